"""The data the ``physical`` fit works on and the least squares every stage of it runs.

The steady points of a gauge and its dynamic records as the kernel's simulator is driven
(:func:`kernel_simulator`, compiled by numba), the residuals of each against a parameter
vector, and the tools the stages share: a least-squares fit over named parameters, standard
errors from its Jacobian and the F-test that decides what is kept. What each stage fits is
elsewhere (:mod:`gatetwin.identification.physical` and the modules it names); nothing here decides
a parameter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import f as f_dist

from gatetwin.errors import IdentificationError
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.plant import blocks
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.kernel_render import numba_kernel
from gatetwin.records import Record

__all__ = [
    "NO_SEICHE",
    "SEICHE",
    "SEICHE_SIGNIFICANCE",
    "STEADY_HOLD_SAMPLES",
    "STEADY_SAMPLES",
    "SteadyPoints",
    "kernel_simulator",
    "steady_points",
]

#: A hold this many sample periods long counts as settled.
STEADY_HOLD_SAMPLES = 300
#: Samples averaged at the end of a settled hold.
STEADY_SAMPLES = 40
#: The seiche's parameters (period, decay time, amplitude), fitted last; "no seiche".
SEICHE = ["period_s", "decay_time_s", "amplitude_mm_per_mm"]
NO_SEICHE = np.array([1.0, 1.0, 0.0])
#: The seiche is kept when the F-test of its three parameters against none rejects "no
#: seiche" at this level (residuals treated as independent: an optimistic test, so the level
#: is strict).
SEICHE_SIGNIFICANCE = 1e-3


@dataclass(frozen=True)
class SteadyPoints:
    """Steady operating points of one gauge: discharge, opening, level and where from."""

    flow_m3h: np.ndarray
    opening_mm: np.ndarray
    level_mm: np.ndarray
    source: tuple[str, ...]


def steady_points(static: Any, records: dict[str, Record], gauge: str) -> SteadyPoints:
    """The static table's points and the settled end of every long hold of ``records``."""
    q, e, h = [list(static.flow_m3h)], [list(static.opening_mm)], [list(static.levels_mm[gauge])]
    source = ["static"] * len(static.flow_m3h)
    for name, rec in records.items():
        if gauge not in rec.levels_mm:
            continue
        for seg in rec.holds:
            held = rec.time_s[seg.stop - 1] - rec.time_s[seg.start]
            if held < STEADY_HOLD_SAMPLES * rec.sample_period_s:
                continue
            idx = np.arange(seg.start, seg.stop)
            level = rec.levels_mm[gauge][idx]
            valid = idx[np.isfinite(level)][-STEADY_SAMPLES:]
            q.append([float(np.mean(rec.flow_m3h[valid]))])
            e.append([seg.opening_mm])
            h.append([float(np.mean(rec.levels_mm[gauge][valid]))])
            source.append(name)
    arrays = [np.concatenate([np.asarray(v, float) for v in x]) for x in (q, e, h)]
    ok = np.all([np.isfinite(a) for a in arrays], axis=0)
    return SteadyPoints(*(a[ok] for a in arrays), tuple(np.asarray(source)[ok]))


@cache
def kernel_simulator() -> tuple[Callable[..., Any], Callable[..., Any]]:
    """Numba renderings: ``run(t, e, q, p, s, out)`` (a free run, as PhysicalSimulator steps,
    with the seiche ``s = (period, decay time, amplitude)``; amplitude 0 for none) and
    ``steady(e, q, p, out)`` (the steady level at each point)."""
    from numba import njit

    k = numba_kernel(kernel.__name__)
    substep, depth0, level = k.substep, k.steady_depth_m, k.level_mm
    target_of, count_of, tail0 = k.actuator_target_mm, k.substep_count, k.tail_steady_m

    advance = njit(cache=True)(blocks.seiche_advance)
    at_rest = njit(cache=True)(blocks.seiche_equilibrium)
    seiche_out = njit(cache=True)(blocks.seiche_output)

    # nogil (both): the columns of a finite-difference Jacobian run in threads at once (_fit)
    @njit(cache=False, nogil=True)
    def run(t: np.ndarray, e: np.ndarray, q: np.ndarray, p: np.ndarray, s: np.ndarray,
            out: np.ndarray) -> None:  # fmt: skip
        # s: the seiche's period, decay time and amplitude (amplitude 0: no seiche)
        has_seiche = s[2] != 0.0
        gate = target_of(e[0], p)
        depth = depth0(gate, q[0], p)
        tail = tail0(q[0], p)
        x1 = at_rest(e[0], s[0], s[1]) if has_seiche else 0.0
        x2 = 0.0
        out[0] = level(depth, gate, q[0], p)
        for i in range(1, t.size):
            h = t[i] - t[i - 1]
            n = count_of(h, p)
            target = target_of(e[i - 1], p)
            dt = h / n
            for _ in range(int(n)):
                start = gate
                depth, tail, gate = substep(depth, tail, gate, target, q[i - 1], dt, p)
                if has_seiche:
                    x1, x2 = advance(x1, x2, start, dt, s[0], s[1])
            out[i] = level(depth, gate, q[i - 1], p)
            if has_seiche:
                out[i] += seiche_out(x2, s[0], s[2])

    @njit(cache=False, nogil=True)
    def steady(e: np.ndarray, q: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
        for i in range(e.size):
            gate = target_of(e[i], p)
            out[i] = level(depth0(gate, q[i], p), gate, q[i], p)

    return run, steady


def _vector(values: dict[str, float]) -> np.ndarray:
    return np.array([values[n] for n, _, _ in kernel.PARAMETERS], dtype=float)


def _steady_residuals(points: SteadyPoints, p: np.ndarray) -> np.ndarray:
    out = np.empty(points.flow_m3h.size)
    kernel_simulator()[1](points.opening_mm, points.flow_m3h, p, out)
    return out - points.level_mm


@dataclass(frozen=True)
class _Drive:
    """One dynamic record as the simulator is driven: time, opening, inflow, level."""

    name: str
    time_s: np.ndarray
    opening_mm: np.ndarray
    flow_m3h: np.ndarray
    level_mm: np.ndarray


def _drives(records: dict[str, Record], gauge: str) -> list[_Drive]:
    out = []
    for name, rec in records.items():
        if gauge in rec.levels_mm:
            e = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
            out.append(_Drive(name, rec.time_s, e, rec.flow_m3h, rec.levels_mm[gauge]))
    return out


def _dynamic_residuals(drives: Sequence[_Drive], p: np.ndarray,
                       seiche: np.ndarray = NO_SEICHE) -> list[np.ndarray]:  # fmt: skip
    run = kernel_simulator()[0]
    res = []
    for d in drives:
        out = np.empty(d.time_s.size)
        run(d.time_s, d.opening_mm, d.flow_m3h, p, seiche, out)
        ok = np.isfinite(d.level_mm)
        res.append(out[ok] - d.level_mm[ok])
    return res


def _fit(names: list[str], values: dict[str, float], residual: Callable[[np.ndarray], np.ndarray],
         max_nfev: int | None = None, bounds: dict[str, tuple[float, float]] | None = None
         ) -> tuple[dict[str, float], Any]:  # fmt: skip
    """Least squares over ``names`` (the rest of ``values`` held); ``max_nfev`` as in
    :func:`scipy.optimize.least_squares` (its default when None); ``bounds`` by name (none
    where not given)."""
    from gatetwin.fleet.execute import default_workers

    index = [kernel.INDEX[n] for n in names]
    base = _vector(values)
    box = [(bounds or {}).get(n, (-np.inf, np.inf)) for n in names]
    lower, upper = np.array([b[0] for b in box]), np.array([b[1] for b in box])

    def fun(x: np.ndarray) -> np.ndarray:
        p = base.copy()
        p[index] = x
        return residual(p)

    x0 = np.clip(base[index], lower, upper)
    # the Jacobian's columns (one free run each) on the CPUs at once; the same evaluations
    # as one after another, so the same result
    with ThreadPoolExecutor(max_workers=default_workers()) as pool:
        result = least_squares(fun, x0, x_scale="jac", diff_step=1e-6, max_nfev=max_nfev,
                               bounds=(lower, upper), workers=pool.map)  # fmt: skip
    if not result.success or not np.all(np.isfinite(result.fun)):
        raise IdentificationError(f"physical fit did not converge ({result.message})")
    return {**values, **dict(zip(names, (float(v) for v in result.x), strict=True))}, result


def _standard_errors(result: Any, names: list[str]) -> dict[str, float]:
    """One-sigma errors from the Jacobian of a (weighted) least-squares fit."""
    jac = result.jac
    dof = max(1, jac.shape[0] - jac.shape[1])
    s2 = 2.0 * result.cost / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
    except np.linalg.LinAlgError:
        return {n: float("nan") for n in names}
    return {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}


def _f_test_p(rss0: float, rss1: float, extra: int, residual_dof: int) -> float:
    """p-value of the F-test of ``extra`` added parameters that take the residual sum of
    squares from ``rss0`` to ``rss1`` with ``residual_dof`` degrees of freedom left (0 for a
    perfect fit)."""
    f_stat = ((rss0 - rss1) / extra) / (rss1 / residual_dof) if rss1 > 0 else math.inf
    return float(f_dist.sf(f_stat, extra, residual_dof))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))
