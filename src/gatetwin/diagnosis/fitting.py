"""Output-error fits of a plant (and one effect block) to a record, run free on the grid.

A fit adjusts the baseline plant jointly with the block: for an FOPDT the gain and the time
constant by factors, the dead time by a shift and the level by an offset; for an ARX every
coefficient by a shift and the level by an offset (an output-error refit: the least-squares
ARX of the paper predicts one step ahead, and run free its poles can be far off). Every
schedule knot is adjusted alike, so a scheduled model keeps its shape. The effect block adds
its own parameters (natural units). Residuals are measured minus free-run simulated level on
the fitted part only; the fit is :func:`scipy.optimize.least_squares` from several starts, the
best kept.

Standard errors: ``sqrt(diag(s^2 (J^T J)^-1) * n / n_eff)`` with ``s^2 = RSS / (n - p)`` and
``n_eff = n (1 - r1) / (1 + r1)`` from the residuals' lag-1 autocorrelation ``r1``: the
free-run residuals of a real record are rarely white, and treating them as independent would
overstate the precision.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import linalg, optimize

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.diagnosis.grid_sim import simulate_grid
from gatetwin.errors import GatetwinError
from gatetwin.plant.model import FopdtPlant, Plant, Schedule

__all__ = [
    "ARX_COEFFICIENT_SHIFT",
    "FOPDT_ADJUST",
    "GRID_DEAD_TIMES_S",
    "GRID_TIME_CONSTANTS_S",
    "PENALTY_MM",
    "Fit",
    "Parametrization",
    "adjusted",
    "baseline_bounds",
    "effective_n",
    "fit_plant",
    "grid_start",
    "plant_parametrization",
    "rmse",
]

#: Residual of a parameter vector the plant cannot be built or run with, mm.
PENALTY_MM = 1e4
#: Baseline adjustments, FOPDT then ARX: (name, lower, upper, neutral).
#: The factors' bounds are wide on purpose: a large missing effect (an inflow response of
#: 100 mm, say) can bend the baseline far from the plant, and a candidate must be able to
#: bring it back.
FOPDT_ADJUST = (
    ("gain_factor", 1e-3, 1e3, 1.0),
    ("time_constant_factor", 1e-4, 1e4, 1.0),
    ("dead_time_shift_s", None, 60.0, 0.0),
    ("level_offset_mm", -1e3, 1e3, 0.0),
)
ARX_COEFFICIENT_SHIFT = 1.0


@dataclass(frozen=True)
class Parametrization:
    """Free parameters of a fit and how they make a plant.

    Attributes
    ----------
    names : tuple of str
        Parameter names (baseline adjustments first, then the block's).
    lower, upper : ndarray
        Bounds.
    build : callable
        ``theta -> Plant``.
    n_baseline : int
        How many leading parameters adjust the baseline.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    build: Callable[[np.ndarray], Plant]
    n_baseline: int


@dataclass(frozen=True)
class Fit:
    """A fitted plant.

    Attributes
    ----------
    plant : Plant
        The fitted plant.
    theta, se : ndarray
        Parameters and standard errors (NaN when not estimable), in ``names`` order.
    names : tuple of str
        Parameter names.
    simulated_mm : ndarray
        Free-run level at every record sample, mm.
    rss_mm2 : float
        Residual sum of squares on the fitted part, mm².
    n_fit : int
        Samples fitted.
    n_effective : float
        Effective sample size of the fitted residuals.
    converged : bool
        Whether the best start reported convergence.
    """

    plant: Plant
    theta: np.ndarray
    se: np.ndarray
    names: tuple[str, ...]
    simulated_mm: np.ndarray
    rss_mm2: float
    n_fit: int
    n_effective: float
    converged: bool

    def value(self, name: str) -> float:
        return float(self.theta[self.names.index(name)])

    def parameters(self) -> dict[str, dict[str, float | None]]:
        """``{name: {"value", "se", "ci95"}}`` for JSON."""
        out: dict[str, dict[str, Any]] = {}
        for name, v, s in zip(self.names, self.theta, self.se, strict=True):
            ok = bool(np.isfinite(s))
            ci = [float(v - 1.96 * s), float(v + 1.96 * s)] if ok else None
            out[name] = {"value": float(v), "se": float(s) if ok else None, "ci95": ci}
        return out


def _flat(values: Sequence[float]) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def adjusted(base: Plant, theta: np.ndarray) -> Plant:
    """``base`` with the baseline adjustments ``theta`` applied to every schedule knot."""
    v = dict(base.schedule.values)
    if isinstance(base, FopdtPlant):
        gain, tau, shift, offset = theta[:4]
        v["gain_mm_per_mm"] = _flat(np.asarray(v["gain_mm_per_mm"]) * gain)
        v["time_constant_s"] = _flat(np.asarray(v["time_constant_s"]) * tau)
        v["dead_time_s"] = _flat(np.maximum(np.asarray(v["dead_time_s"]) + shift, 0.0))
    else:
        names = [f"a{i}" for i in range(1, base.na + 1)] + [f"b{j}" for j in range(1, base.nb + 1)]
        for name, shift in zip(names, theta, strict=False):
            v[name] = _flat(np.asarray(v[name]) + shift)
        offset = theta[len(names)]
    v["level_ref_mm"] = _flat(np.asarray(v["level_ref_mm"]) + offset)
    return replace(base, schedule=Schedule(base.schedule.flow_m3h, v))


def baseline_bounds(base: Plant, max_time_constant_s: float = math.inf
                    ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Names, bounds and neutral values of the baseline adjustments (an FOPDT's time constant
    at most ``max_time_constant_s``: one longer than the record is not identifiable)."""
    if isinstance(base, FopdtPlant):
        longest = max(base.schedule.values["time_constant_s"])
        cap = min(FOPDT_ADJUST[1][2], max(max_time_constant_s / longest, 1.0))
        rows = (FOPDT_ADJUST[0], (*FOPDT_ADJUST[1][:2], cap, 1.0), *FOPDT_ADJUST[2:])
    else:
        coef = [f"a{i}" for i in range(1, base.na + 1)] + [f"b{j}" for j in range(1, base.nb + 1)]
        scale = [ARX_COEFFICIENT_SHIFT if c[0] == "a" else
                 ARX_COEFFICIENT_SHIFT * (1.0 + 5.0 * max(abs(x) for x in base.schedule.values[c]))
                 for c in coef]  # fmt: skip
        rows = (*((f"{c}_shift", -s, s, 0.0) for c, s in zip(coef, scale, strict=True)),
                ("level_offset_mm", -1e3, 1e3, 0.0))  # fmt: skip
    names = tuple(r[0] for r in rows)
    lo = [(-min(base.schedule.values["dead_time_s"]) if r[1] is None else r[1]) for r in rows]
    return (names, np.array(lo, float), np.array([r[2] for r in rows], float),
            np.array([r[3] for r in rows], float))  # fmt: skip


def plant_parametrization(
    base: Plant,
    effect_names: tuple[str, ...] = (),
    effect_lower: Sequence[float] = (),
    effect_upper: Sequence[float] = (),
    make: Callable[[Plant, np.ndarray], Plant] | None = None,
    *,
    max_time_constant_s: float = math.inf,
) -> Parametrization:
    """Baseline adjustments followed by a block's parameters (``make(plant, block_theta)``)."""
    names, lo, hi, _ = baseline_bounds(base, max_time_constant_s)
    k = len(names)

    def build(theta: np.ndarray) -> Plant:
        plant = adjusted(base, theta)
        return make(plant, theta[k:]) if make is not None else plant

    return Parametrization(
        (*names, *effect_names), np.concatenate([lo, np.asarray(effect_lower, float)]),
        np.concatenate([hi, np.asarray(effect_upper, float)]), build, k,
    )  # fmt: skip


def effective_n(residual: np.ndarray) -> float:
    """``n (1 - r1) / (1 + r1)``, ``r1`` the lag-1 autocorrelation (clipped to [0, 0.95])."""
    r = residual[np.isfinite(residual)]
    r = r - r.mean()
    denom = float(r @ r)
    r1 = float(r[1:] @ r[:-1]) / denom if denom > 0 and r.size > 2 else 0.0
    r1 = min(max(r1, 0.0), 0.95)
    return r.size * (1.0 - r1) / (1.0 + r1)


def _simulate(param: Parametrization, theta: np.ndarray, data: DiagnosisData) -> np.ndarray | None:
    try:
        out = simulate_grid(param.build(theta), data.grid)
    except (GatetwinError, FloatingPointError, ValueError, ZeroDivisionError, OverflowError):
        return None
    return out if np.all(np.isfinite(out)) else None


def _standard_errors(jac: np.ndarray, rss: float, n: int, n_eff: float) -> np.ndarray:
    p = jac.shape[1]
    if n <= p:
        return np.full(p, np.nan)
    try:
        cov = linalg.pinvh(jac.T @ jac)
    except (linalg.LinAlgError, ValueError):
        return np.full(p, np.nan)
    var = np.diag(cov) * rss / (n - p) * (n / max(n_eff, 1.0))
    return np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)


def fit_plant(
    param: Parametrization, starts: Sequence[np.ndarray], data: DiagnosisData,
    *, max_nfev: int = 400, max_starts: int = 3,
) -> Fit:  # fmt: skip
    """Fit ``param`` from the ``max_starts`` best of ``starts`` (by their residual sum of
    squares); return the best fit.

    Raises
    ------
    GatetwinError
        When no start gives a plant that can be simulated.
    """
    mask = data.fit_mask
    y = data.level_mm[mask]

    def residual(theta: np.ndarray) -> np.ndarray:
        sim = _simulate(param, theta, data)
        return np.full(y.size, PENALTY_MM) if sim is None else sim[mask] - y

    ranked = []
    for start in starts:
        x0 = np.clip(np.asarray(start, float), param.lower, param.upper)
        sim = _simulate(param, x0, data)
        if sim is not None:
            ranked.append((float(np.sum((sim[mask] - y) ** 2)), len(ranked), x0))
    best = None
    for _, _, x0 in sorted(ranked)[:max_starts]:
        res = optimize.least_squares(residual, x0, bounds=(param.lower, param.upper),
                                     x_scale="jac", max_nfev=max_nfev, method="trf")  # fmt: skip
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise GatetwinError("no start value gives a plant that can be simulated")
    sim = _simulate(param, best.x, data)
    if sim is None:
        raise GatetwinError("the fitted plant cannot be simulated")
    resid = sim - data.level_mm
    rss = float(np.nansum(resid[mask] ** 2))
    n = int(np.count_nonzero(mask))
    n_eff = effective_n(resid[mask])
    return Fit(param.build(best.x), best.x, _standard_errors(best.jac, rss, n, n_eff),
               param.names, sim, rss, n, n_eff, bool(best.success))  # fmt: skip


#: Grid of the starts of every fit (FOPDT baselines): time constants and dead times, s.
GRID_TIME_CONSTANTS_S = (5.0, 12.0, 25.0, 50.0, 100.0, 250.0)
GRID_DEAD_TIMES_S = (0.0, 3.0, 8.0)


def grid_start(param: Parametrization, d: DiagnosisData, base: Plant,
               block: Sequence[float] = (), amp: int | None = None
               ) -> np.ndarray | None:  # fmt: skip
    """Best start over a grid of absolute (T, L) for an FOPDT ``base`` (None for ARX), the
    block at ``block``; at every node the gain factor, the level offset and the block's
    amplitude parameter (index ``amp`` in ``block``) are solved linearly (the level is linear
    in them). Guards against a baseline bent out of shape by a large missing effect, and
    gives the baseline and every candidate the same starts."""
    if not isinstance(base, FopdtPlant):
        return None
    mask, y = d.fit_mask, d.level_mm[d.fit_mask]
    k = param.n_baseline
    q = float(np.median(d.flow_m3h))
    tau0 = base.schedule.at("time_constant_s", q)
    delay0 = base.schedule.at("dead_time_s", q)
    best: tuple[float, np.ndarray | None] = (math.inf, None)
    for tau in GRID_TIME_CONSTANTS_S:
        for delay in GRID_DEAD_TIMES_S:
            adjust = [1.0, tau / tau0, max(delay - delay0, param.lower[2]), 0.0]
            theta = np.concatenate([adjust, block])
            zero = theta.copy()
            zero[0] = 0.0
            try:
                with_gain = simulate_grid(param.build(theta), d.grid)[mask]
                no_gain = simulate_grid(param.build(zero), d.grid)[mask]
            except (GatetwinError, ValueError, FloatingPointError):
                continue
            columns = [np.ones_like(y), with_gain - no_gain]
            if amp is not None:
                columns.append(no_gain - no_gain[0])
            coef, *_ = np.linalg.lstsq(np.column_stack(columns), y - no_gain, rcond=None)
            rss = float(np.sum((np.column_stack(columns) @ coef - (y - no_gain)) ** 2))
            if rss < best[0] and np.all(np.isfinite(coef)):
                theta[0], theta[3] = coef[1], coef[0]
                if amp is not None:
                    theta[k + amp] *= 1.0 + coef[2]
                best = (rss, theta)
    return best[1]


def rmse(measured: np.ndarray, simulated: np.ndarray, mask: np.ndarray) -> float:
    """RMS of ``measured - simulated`` over ``mask`` (finite samples), mm."""
    d = (measured - simulated)[mask]
    d = d[np.isfinite(d)]
    return float(math.sqrt(float(d @ d) / d.size)) if d.size else math.nan
