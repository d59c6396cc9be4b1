"""Identify the ``physical`` family of one gauge from every record at once.

Stages, each on the data that determines its parameters, with joint refinements:

1. **Gate law and gauge offset** (3, 6 or 11 parameters, grown along :data:`LAWS` while the
   data ask for more and the discharge coefficient stays physical) from every steady point:
   the static table's rows and the settled end of every long hold in the dynamic records
   (the last :data:`STEADY_SAMPLES` valid samples of a hold lasting at least
   :data:`STEADY_HOLD_SAMPLES` sample periods).
   Residuals are levels (mm) against the kernel's steady level.
2. **Actuator** (no-load speed, stall depth) from the gate's moves: each move's opening change
   over the time between the last hold sample before it and the first after, against the
   depth at the gate (rating level plus offset) at the start of the move.
3. **Storage** (A0, A1) by simulation error: the kernel run freely on every dynamic record,
   driven by the reconstructed opening and the measured inflow.
4. **Joint**: the law's and the storage's parameters on the stacked residuals of 1 and 3,
   each source weighted by the inverse of its residual RMS after stage 3 (its noise level),
   with standard errors from the Jacobian.
5. **Tail pool** (:func:`_fit_tail`): a submerged gate discharges into a pool of its own,
   whose depth lowers the head and answers on its own, slower time scale — an upstream gauge
   alone shows it as a second mode. Its four parameters are fitted jointly with the core law
   and the storage, from a pool half as deep as the water above the gate with an orifice
   below (the next check) and the core law refitted against that tailwater; the pool replaces
   the free gate when it is physical and fits the weighted residuals better with no more
   parameters, or an F-test of its extra parameters rejects the free gate.
6. **Seiche** (period, decay time, amplitude per mm of gate move: the pool's oscillation that
   gate moves excite; periods the sampling and the pool can show, :func:`seiche_periods_s`)
   from the simulation error left by stages 4–5, the hydraulics held; kept as
   the plant's ``seiche`` effect block only when an F-test rejects "no seiche" at
   :data:`SEICHE_SIGNIFICANCE`.

The simulator here is the kernel compiled by numba (:func:`kernel_simulator`): the same
arithmetic as every other rendering, stepping as :class:`gatetwin.plant.physical.
PhysicalSimulator` does (tests hold the two equal).

Fixed before the fit, from the data (:func:`fixed_parameters`; the model file's report
states each value and where it came from):

* ``width_m``: the sidecar's ``gate_width_m``; without one, the width at which the static
  points at the smallest opening ratios pass their discharge with the textbook free-flow
  coefficient :data:`~gatetwin.identify.physical_start.TEXTBOOK_CD` (width and Cd are not
  separable in free underflow);
* ``resolution_mm``: the sidecar's ``actuator_resolution_mm``, else the opening's quantum in
  the records (the largest power of ten dividing every recorded opening);
* ``flow_centre_m3h`` / ``flow_scale_m3h``: the static table's mid-range discharge (two
  significant figures) and the power of ten at or above its span;
* ``depth_max_m``: the power of two at or above four times the highest level (a quarter of the
  smallest opening ratio the data reach, at the largest discharge, still lies in the bracket);
* ``max_substep_s``: half the sample period, or a tenth of the shortest small-signal time
  constant of the starting model at the steady points, whichever is shorter.

The storage area starts from the scan of :func:`_area_start` (time constants from one sample
period to the longest record), the actuator from its moves.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import f as f_dist

from gatetwin.errors import IdentificationError
from gatetwin.identify import physical_start as start
from gatetwin.identify.preprocess import reconstructed_opening
from gatetwin.plant import blocks
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.effects import effect_dict
from gatetwin.plant.kernel_render import numba_kernel
from gatetwin.plant.model import (
    FORMAT_DEFAULTS,
    PhysicalPlant,
    Schedule,
    lowest_operating_room,
)
from gatetwin.records import Record

__all__ = [
    "ACTUATOR",
    "AREA_SCAN",
    "FIXED",
    "FLOOR",
    "LAW",
    "LAWS",
    "LAW_CORE",
    "LAW_EVALUATIONS",
    "NO_SEICHE",
    "SEICHE",
    "SEICHE_AMPLITUDE_MAX",
    "SEICHE_AMPLITUDE_START",
    "SEICHE_SIGNIFICANCE",
    "STEADY_HOLD_SAMPLES",
    "STEADY_SAMPLES",
    "STORAGE",
    "TAIL",
    "TAIL_DEPTH_START",
    "TAIL_EXPONENT_RANGE",
    "TAIL_EXPONENT_START",
    "ZERO_START",
    "PhysicalFit",
    "SteadyPoints",
    "actuator_moves",
    "data_ranges",
    "fit_physical",
    "fixed_parameters",
    "kernel_simulator",
    "law_start",
    "seiche_periods_s",
    "steady_points",
    "values_depth",
]

#: A hold this many sample periods long counts as settled.
STEADY_HOLD_SAMPLES = 300
#: Samples averaged at the end of a settled hold.
STEADY_SAMPLES = 40
#: Parameters fixed from the data before the fit (see the module docstring).
FIXED = ("width_m", "resolution_mm", "max_substep_s", "flow_centre_m3h", "flow_scale_m3h",
         "depth_max_m")  # fmt: skip
#: Storage-area starts scanned (log-spaced time constants, one sample period to a record).
AREA_SCAN = 25
LAW = [n for n, _, _ in kernel.PARAMETERS[:9]] + ["offset_mm", "offset_per_flow2_mm"]
STORAGE = ["area_m2", "area_per_depth_m"]
#: The seiche's parameters (period, decay time, amplitude), fitted last; "no seiche".
SEICHE = ["period_s", "decay_time_s", "amplitude_mm_per_mm"]
NO_SEICHE = np.array([1.0, 1.0, 0.0])
#: Amplitude start of the seiche fit, mm of level per mm of gate move.
SEICHE_AMPLITUDE_START = 0.3
#: Largest |amplitude| of the seiche, mm per mm of gate move.
SEICHE_AMPLITUDE_MAX = 5.0
#: The seiche is kept when the F-test of its three parameters against none rejects "no
#: seiche" at this level (residuals treated as independent: an optimistic test, so the level
#: is strict).
SEICHE_SIGNIFICANCE = 1e-3
ACTUATOR = ["speed_mm_s", "stall_depth_m"]
#: The pool below the gate (storage, steady depth at the discharge centre, datum, outlet
#: exponent): fitted with the core law and the storage, kept by the rule of
#: :func:`_fit_tail`.
TAIL = ["tail_area_m2", "tail_depth_m", "tail_datum_m", "tail_exponent"]
#: The tail pool's start: the outlet of an orifice (the next check gate) and a pool as deep
#: as this fraction of the steady depths above the gate.
TAIL_EXPONENT_START = 0.5
TAIL_DEPTH_START = 0.5
#: The outlet exponents a tail pool may have: an orifice's 1/2 to a wide channel's 5/3, with a
#: margin of a factor of two each way.
TAIL_EXPONENT_RANGE = (0.25, 10.0 / 3.0)
#: The gate law's parameters that every gate has: a discharge coefficient that may differ
#: between small and large openings, and the gauge's offset.
LAW_CORE = ["cd_small", "cd_large", "offset_mm"]
#: Evaluations per parameter allowed to a gate-law fit (five times least_squares' default: a
#: law's evaluation is one steady solve per point, milliseconds, and the transition's
#: parameters are weakly determined when the data see one side of it).
LAW_EVALUATIONS = 500
#: The gate law in nested steps, each kept only when the data ask for it (an F-test against
#: the last law kept at ``SEICHE_SIGNIFICANCE``; a step they do not ask for is passed over)
#: and its discharge coefficient stays physical (in (0, 1] at every opening,
#: :func:`_physical_law`): the core; the
#: coefficients' and the offset's drift with discharge (a submerged or far gauge, a pool whose
#: friction loss grows with Q); the whole transition (its place, width and shape).
LAWS = (
    LAW_CORE,
    [*LAW_CORE, "cd_small_per_q", "cd_large_per_q", "offset_per_flow2_mm"],
    LAW,
)
#: The floor of a far gauge (its level, the level's drift with discharge, the smoothness of
#: the passage), tried last with the law, storage and tail pool kept (:func:`_fit_floor`):
#: the gate's pool drawn down at a low inflow stops reaching the gauge, whose water runs at
#: its channel's own depth for the inflow.
FLOOR = ["floor_mm", "floor_per_q_mm", "floor_smooth_mm"]
#: Law parameters that start at zero (no drift with discharge, no offset, no shape).
ZERO_START = ("cd_small_per_q", "cd_large_per_q", "cd_mid_per_q", "cd_log_width_per_q",
              "cd_log_shape", "offset_mm", "offset_per_flow2_mm", "area_per_depth_m")  # fmt: skip


@dataclass(frozen=True)
class SteadyPoints:
    """Steady operating points of one gauge: discharge, opening, level and where from."""

    flow_m3h: np.ndarray
    opening_mm: np.ndarray
    level_mm: np.ndarray
    source: tuple[str, ...]


@dataclass(frozen=True)
class PhysicalFit:
    """The identified plant with its standard errors and per-source residuals."""

    plant: PhysicalPlant
    standard_errors: dict[str, float]
    steady_rmse_mm: float
    n_steady: int
    dynamic_rmse_mm: dict[str, float]
    actuator_moves: int
    seiche: dict[str, Any]
    fixed_sources: dict[str, str]

    def report(self) -> dict[str, Any]:
        return {
            "seiche": self.seiche,
            "standard_errors": self.standard_errors,
            "steady_points": self.n_steady,
            "steady_rmse_mm": self.steady_rmse_mm,
            "dynamic_rmse_mm": self.dynamic_rmse_mm,
            "actuator_moves": self.actuator_moves,
            "fixed": {n: self.plant.parameters[n] for n in FIXED},
            "fixed_from": dict(self.fixed_sources),
        }


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

    @njit(cache=False)
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

    @njit(cache=False)
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
    index = [kernel.INDEX[n] for n in names]
    base = _vector(values)
    box = [(bounds or {}).get(n, (-np.inf, np.inf)) for n in names]
    lower, upper = np.array([b[0] for b in box]), np.array([b[1] for b in box])

    def fun(x: np.ndarray) -> np.ndarray:
        p = base.copy()
        p[index] = x
        return residual(p)

    x0 = np.clip(base[index], lower, upper)
    result = least_squares(fun, x0, x_scale="jac", diff_step=1e-6, max_nfev=max_nfev,
                           bounds=(lower, upper))  # fmt: skip
    if not result.success or not np.all(np.isfinite(result.fun)):
        raise IdentificationError(f"physical fit did not converge ({result.message})")
    return {**values, **dict(zip(names, (float(v) for v in result.x), strict=True))}, result


def actuator_moves(records: dict[str, Record], gauge: str, values: dict[str, float]
                   ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Observed speed of each gate move (mm/s) and the depth at the gate when it began (m).

    The move lies between the last hold sample before it and the first after; on average it
    begins and ends half a sample period inside that interval, so its duration is the
    interval less one sample period. The depth is the gauge's level at the start plus the
    gauge offset at the measured discharge.
    """
    speeds, depths = [], []
    for rec in records.values():
        level = rec.levels_mm.get(gauge)
        if level is None:
            continue
        for step in rec.steps:
            i0, i1 = step.before.stop - 1, step.after.start
            duration = rec.time_s[i1] - rec.time_s[i0] - rec.sample_period_s
            if not (duration > 0 and np.isfinite(level[i0])):
                continue
            qs = rec.flow_m3h[i0] / values["flow_scale_m3h"]
            offset = values["offset_mm"] + values["offset_per_flow2_mm"] * qs * qs
            speeds.append(abs(step.after.opening_mm - step.before.opening_mm) / duration)
            depths.append((level[i0] + offset) / 1000.0)
    return np.asarray(speeds), np.asarray(depths)


def _fit_actuator(speeds: np.ndarray, depths: np.ndarray, values: dict[str, float]
                  ) -> dict[str, float]:  # fmt: skip
    if speeds.size < 3:
        raise IdentificationError(
            f"physical: {speeds.size} gate move(s) in the records; the actuator needs 3 or more"
        )

    def residual(x: np.ndarray) -> np.ndarray:
        load = depths / x[1]
        return x[0] * np.maximum(kernel.SPEED_FLOOR, 1.0 - load * load) - speeds

    # start: the fastest move unloaded, stalling at half again the deepest start; bounds: a
    # micrometre a second to a metre a second, stalling above the deepest to ten times it
    deepest = float(np.max(depths))
    x0 = [float(np.max(speeds)), 1.5 * deepest]
    result = least_squares(residual, x0, bounds=([1e-3, 1.05 * deepest],
                                                 [1e3, 10.0 * deepest]))  # fmt: skip
    return {**values, "speed_mm_s": float(result.x[0]), "stall_depth_m": float(result.x[1])}


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


def fit_physical(static: Any, records: dict[str, Record], gauge: str,
                 flow_range_m3h: tuple[float, float]) -> PhysicalFit:  # fmt: skip
    """Identify the physical plant of ``gauge`` from the static table and ``records``.

    The storage area is linear in depth. When the fitted area falls to its floor at a level
    and discharge the data span (the records cover too little depth to carry its slope
    there), the hydraulics are fitted again with a constant area.
    """
    points = steady_points(static, records, gauge)
    if points.flow_m3h.size < len(LAW) + 2:
        raise IdentificationError(
            f"physical {gauge}: {points.flow_m3h.size} steady points; need {len(LAW) + 2}"
        )
    drives = _drives(records, gauge)
    if not drives:
        raise IdentificationError(f"physical {gauge}: no dynamic record has this gauge")
    fixed, sources = fixed_parameters(static, records, gauge, points)
    laws = _fit_law(points, fixed, sources)
    speeds, depths = actuator_moves(records, gauge, laws[-1][1])
    actuated = _fit_actuator(speeds, depths, laws[-1][1])
    ranges = data_ranges(static, records, gauge)

    def lowest_room(values: dict[str, float]) -> tuple[float, float, float]:
        return lowest_operating_room(list(_vector(values)), ranges["level_mm"],
                                     ranges["flow_m3h"])  # fmt: skip

    staged = sources  # each hydraulics fit starts from the sources of the stages before
    fitted, values, result, rms_dyn, sources = _fit_hydraulics(points, drives, laws, actuated,
                                                               staged, STORAGE)  # fmt: skip
    room, level, flow = lowest_room(values)
    if not room > 0.0:
        slope = values["area_per_depth_m"]
        fitted, values, result, rms_dyn, sources = _fit_hydraulics(
            points, drives, laws, {**actuated, "area_per_depth_m": 0.0}, staged, ["area_m2"]
        )
        sources["area_per_depth_m"] = (
            f"0: with its slope ({slope:.4g} m) the fitted area fell to its floor at level "
            f"{level:g} mm and {flow:g} m3/h, inside the data's ranges"
        )
        if not lowest_room(values)[0] > 0.0:
            raise IdentificationError(
                f"physical {gauge}: the fitted storage area ({values['area_m2']:.4g} m2) is "
                f"not above its floor ({kernel.AREA_MIN_M2:g} m2) where the data run"
            )
    p = _vector(values)
    seiche, seiche_report = _fit_seiche(drives, p, rms_dyn,
                                        seiche_periods_s(records, p, points))  # fmt: skip
    effects = (effect_dict("seiche", **dict(zip(SEICHE, seiche, strict=True))),) \
        if seiche_report["kept"] else ()  # fmt: skip
    plant = PhysicalPlant(gauge, values, Schedule(tuple(flow_range_m3h),
                                                  {"level_ref_mm": (0.0, 0.0)}),
                          effects=effects)  # fmt: skip
    s = seiche if seiche_report["kept"] else NO_SEICHE
    return PhysicalFit(
        plant=plant,
        standard_errors=_standard_errors(result, fitted),
        steady_rmse_mm=_rms(_steady_residuals(points, p)),
        n_steady=int(points.flow_m3h.size),
        dynamic_rmse_mm={
            d.name: _rms(r) for d, r in zip(drives, _dynamic_residuals(drives, p, s), strict=True)
        },
        actuator_moves=int(speeds.size),
        seiche=seiche_report,
        fixed_sources=sources,
    )


def _fit_hydraulics(
    points: SteadyPoints,
    drives: Sequence[_Drive],
    laws: list[tuple[list[str], dict[str, float]]],
    actuated: dict[str, float],
    sources: dict[str, str],
    storage: list[str],
) -> tuple[list[str], dict[str, float], Any, list[float], dict[str, str]]:
    """From the law and the actuator on: the storage by simulation error, then the law and
    the storage jointly (each source weighted by its residual RMS after the stages), the tail
    pool and the floor. ``storage``: the area's parameters fitted (the rest held). Returns
    the parameters fitted, the values, the last least-squares result, the dynamic records'
    residual RMS of the stages and the sources (``laws`` and ``sources`` are not changed)."""
    laws, sources = list(laws), dict(sources)
    law = laws[-1][0]
    values = _storage_start(actuated, points, drives, sources)
    values, _ = _fit(storage, values, lambda p: np.concatenate(_dynamic_residuals(drives, p)))
    rms_static = _rms(_steady_residuals(points, _vector(values)))
    rms_dyn = [_rms(r) for r in _dynamic_residuals(drives, _vector(values))]

    def joint(p: np.ndarray) -> np.ndarray:
        dyn = _dynamic_residuals(drives, p)
        return np.concatenate(
            [
                _steady_residuals(points, p) / rms_static,
                *(r / s for r, s in zip(dyn, rms_dyn, strict=True)),
            ]
        )

    staged = values
    while True:
        try:
            values, result = _fit(law + storage, values, joint)
            break
        except IdentificationError:
            if len(laws) == 1:
                raise
            # this law's parameters and the storage are not identifiable together: one step down
            laws.pop()
            law = laws[-1][0]
            sources["gate_law"] = (f"{len(law)} of {len(LAW)} law parameters: the larger law "
                                   "did not converge jointly with the storage")  # fmt: skip
            values = {**staged, **{n: laws[-1][1][n] for n in LAW}}
    law, values, result = _fit_tail(
        law, values, result, joint, points, laws[0][1], sources, storage
    )
    tail = TAIL if values["tail_area_m2"] > 0.0 else []
    law, values, result = _fit_floor(law, tail, values, result, joint, points, sources, storage)
    return law + storage + tail, values, result, rms_dyn, sources


def _fit_tail(law: list[str], values: dict[str, float], free: Any,
              joint: Callable[[np.ndarray], np.ndarray], points: SteadyPoints,
              core: dict[str, float], sources: dict[str, str], storage: list[str]
              ) -> tuple[list[str], dict[str, float], Any]:  # fmt: skip
    """The gate discharging into a pool of its own (a submerged check).

    The pool's four parameters are fitted with the core law (``core``: its values on the
    steady points) and the storage, on the same weighted residuals as the free gate with its
    kept ``law`` (``free``: that fit's least-squares result): a submerged gate's discharge
    falls with the tailwater, which the free law can only mimic by drifting with discharge.
    The pool is kept when it is physical (:func:`_physical_tail`, :func:`_physical_law`) and
    either fits better with no more parameters than the free gate, or an F-test of its extra
    parameters rejects the free gate at ``SEICHE_SIGNIFICANCE``. Returns the law, values and
    least-squares result kept."""
    names = LAW_CORE + storage + TAIL
    k_free, k_tail, n = len(law) + len(storage), len(names), free.fun.size
    if n <= k_tail:
        return law, values, free
    # start: the pool as deep as a fraction of the depths above the gate, then the core law
    # refitted on the steady points against that tailwater (the free law's coefficient
    # absorbed the submergence), then everything jointly
    depth_m = (points.level_mm + core["offset_mm"]) / 1000.0
    start_values = {**values, **{k: core[k] for k in LAW},
                    "tail_area_m2": values["area_m2"],
                    "tail_depth_m": TAIL_DEPTH_START * float(np.median(depth_m)),
                    "tail_datum_m": 0.0, "tail_exponent": TAIL_EXPONENT_START}  # fmt: skip
    try:
        start_values, _ = _fit(LAW_CORE, start_values,
                               lambda p: _steady_residuals(points, p))  # fmt: skip
        trial, fit = _fit(names, start_values, joint)
    except (IdentificationError, ValueError):  # ValueError: least_squares met a non-finite start
        sources["tail"] = "none: a pool below the gate did not converge"
        return law, values, free
    rss0, rss1 = 2.0 * float(free.cost), 2.0 * float(fit.cost)
    if not (rss1 > 0.0 and _physical_tail(trial) and _physical_law(points, trial)):
        sources["tail"] = "none: the fitted pool below the gate is not physical"
        return law, values, free
    if k_tail <= k_free:
        keep, why = rss1 < rss0, f"{k_tail} parameters against the free gate's {k_free}"
    else:
        extra = k_tail - k_free
        p_value = _f_test_p(rss0, rss1, extra, n - k_tail)
        keep, why = p_value < SEICHE_SIGNIFICANCE, f"F-test p = {p_value:.2g}"
    rms = f"RMS of the weighted residuals {math.sqrt(rss0 / n):.3g} free, " \
          f"{math.sqrt(rss1 / n):.3g} with the pool"  # fmt: skip
    if not keep:
        sources["tail"] = f"none: the free gate holds ({why}; {rms})"
        return law, values, free
    sources["tail"] = f"a pool below the gate with the core law ({why}; {rms})"
    sources["gate_law"] = "core (Cd for small and large openings, offset) with the tail pool"
    return list(LAW_CORE), trial, fit


def _fit_floor(law: list[str], tail: list[str], values: dict[str, float], without: Any,
               joint: Callable[[np.ndarray], np.ndarray], points: SteadyPoints,
               sources: dict[str, str], storage: list[str]
               ) -> tuple[list[str], dict[str, float], Any]:  # fmt: skip
    """A floor at the gauge (:data:`FLOOR`), fitted with the kept ``law``, the storage and the
    ``tail`` pool's parameters on the joint weighted residuals (``without``: that fit without
    the floor), from :func:`_floor_start`. Kept when the law stays physical and F-tests of
    its three parameters on those residuals and on the steady points alone both reject the
    gauge without a floor at ``SEICHE_SIGNIFICANCE``; then the law grows on along ``LAWS``
    with the floor, by the F-test of :func:`_fit_law` on the joint residuals (a free gate's
    only). Returns the law, values and least-squares result kept."""
    names = [*law, *FLOOR]
    n = without.fun.size
    if n <= len(names) + len(storage) + len(tail):
        return law, values, without
    start_values, box = _floor_start(points, values)
    try:
        trial, fit = _fit(names + storage + tail, start_values, joint, None, box)
    except (IdentificationError, ValueError):  # ValueError: least_squares met a non-finite start
        sources["floor"] = "none: a floor did not converge"
        return law, values, without
    rss0, rss1 = 2.0 * float(without.cost), 2.0 * float(fit.cost)
    dof = n - len(names) - len(storage) - len(tail)
    p_joint = _f_test_p(rss0, rss1, len(FLOOR), dof) if rss1 > 0.0 else 1.0
    # a floor is a steady effect: the steady points alone must ask for it too (else the
    # dynamic records use its parameters as free knobs for a misfit of another kind)
    steady0, steady1 = (float(np.sum(_steady_residuals(points, _vector(v)) ** 2))
                        for v in (values, trial))  # fmt: skip
    dof_steady = points.flow_m3h.size - len(names)
    p_steady = _f_test_p(steady0, steady1, len(FLOOR), dof_steady) \
        if steady1 > 0.0 and dof_steady > 0 else 1.0  # fmt: skip
    tests = f"F-test p = {p_joint:.2g} on all residuals, {p_steady:.2g} on the steady points"
    if not (_physical_law(points, trial) and max(p_joint, p_steady) < SEICHE_SIGNIFICANCE):
        sources["floor"] = f"none: the gauge follows the gate's pool ({tests})"
        return law, values, without
    sources["floor"] = (f"{trial['floor_mm']:.4g} mm at Q_c, "
                        f"{trial['floor_per_q_mm']:+.3g} mm per Q_s, met over "
                        f"{trial['floor_smooth_mm']:.3g} mm ({tests})")  # fmt: skip
    # the law was grown without the floor, whose points it bent to fit: grow it on with it
    for larger in (w for w in LAWS if len(w) > len(law) and not tail):
        grown = [*larger, *FLOOR]
        try:
            trial2, fit2 = _fit(grown + storage, trial, joint, None, box)
        except (IdentificationError, ValueError):
            continue
        rss2 = 2.0 * float(fit2.cost)
        dof = n - len(grown) - len(storage)
        if not (
            rss2 > 0.0
            and _physical_law(points, trial2)
            and dof > 0
            and _f_test_p(2.0 * float(fit.cost), rss2, len(grown) - len(names), dof)
            < SEICHE_SIGNIFICANCE
        ):
            continue
        names, trial, fit = grown, trial2, fit2
        sources["gate_law"] = (f"{len(larger)} of {len(LAW)} law parameters with the floor: an "
                               "F-test rejects the smaller law")  # fmt: skip
    return names, trial, fit


def _physical_tail(values: dict[str, float]) -> bool:
    """Whether a fitted tail pool is physical: it stores water, its steady depth lies above
    its datum, and its outlet's exponent lies in :data:`TAIL_EXPONENT_RANGE`."""
    lo, hi = TAIL_EXPONENT_RANGE
    return bool(values["tail_area_m2"] > 0.0 and values["tail_depth_m"] > values["tail_datum_m"]
                and lo <= values["tail_exponent"] <= hi)  # fmt: skip


def law_start(points: SteadyPoints, width_m: float) -> dict[str, float]:
    """The gate law's start from the steady points: every point's discharge coefficient
    Q / (b e sqrt(2 g h)) (level as head), their median for small and large openings alike,
    the transition at the points' median opening ratio e/h and as wide as their spread."""
    head_m = np.maximum(points.level_mm / 1000.0, kernel.DEPTH_MIN_M)
    opening_m = np.maximum(points.opening_mm / 1000.0, 1e-9)
    cd = points.flow_m3h / 3600.0 / (width_m * opening_m * np.sqrt(2.0 * kernel.G * head_m))
    log_ratio = np.log(opening_m / head_m)
    cd0 = float(np.median(cd[np.isfinite(cd)]))
    spread = float(np.std(log_ratio)) if log_ratio.size > 1 else 0.0
    return {**dict.fromkeys(ZERO_START, 0.0), "cd_small": cd0, "cd_large": cd0,
            "cd_mid_log_ratio": float(np.median(log_ratio)),
            "cd_log_width": math.log(max(spread, 0.1))}  # fmt: skip


def _fit_law(points: SteadyPoints, fixed: dict[str, float], sources: dict[str, str]
             ) -> list[tuple[list[str], dict[str, float]]]:  # fmt: skip
    """The gate law on the steady points, grown along ``LAWS``: each step fitted from the last
    one kept, and kept when it converges, its coefficient stays physical over the points
    (:func:`_physical_law`) and an F-test rejects the last law kept at ``SEICHE_SIGNIFICANCE``.
    A step the data do not ask for is passed over, not the end: a field gate's transition
    sits elsewhere than the start puts it while its coefficients do not drift with discharge
    (the drift step misses the points as the core does, the whole law meets their noise).
    The laws kept, simplest first, each with its values (``sources`` says which one is last)."""
    values = {**law_start(points, fixed["width_m"]), **fixed}

    def residual(p: np.ndarray) -> np.ndarray:
        return _steady_residuals(points, p)

    values, last = _fit(LAW_CORE, values, residual)
    kept = [(list(LAW_CORE), values)]
    sources["gate_law"] = "core (Cd for small and large openings, offset): the data show no more"
    n = points.flow_m3h.size
    for law in LAWS[1:]:
        if n <= len(law):
            break
        try:
            trial, fit = _fit(law, kept[-1][1], residual, LAW_EVALUATIONS * len(law))
        except IdentificationError:
            continue
        rss0, rss1 = 2.0 * float(last.cost), 2.0 * float(fit.cost)
        extra = len(law) - len(kept[-1][0])
        if rss1 <= 0.0 or not _physical_law(points, trial):
            continue
        if _f_test_p(rss0, rss1, extra, n - len(law)) >= SEICHE_SIGNIFICANCE:
            continue
        kept.append((list(law), trial))
        last = fit
        sources["gate_law"] = (f"{len(law)} of {len(LAW)} law parameters: an F-test rejects "
                               f"the {len(kept[-2][0])}-parameter law")  # fmt: skip
    return kept


def _floor_start(points: SteadyPoints, values: dict[str, float]
                 ) -> tuple[dict[str, float], dict[str, tuple[float, float]]]:  # fmt: skip
    """A floor's start and bounds from the steady points. Start: through the lowest level the
    gauge read at each discharge (a straight line in the discharge when there are two or
    more), as smooth as its lower bound. Bounds: the floor within the points' level range R
    below their lowest level and up to their highest; its passage no sharper than the law
    without the floor misses the points by (their residuals' RMS: a sharper corner is not
    resolved by them, and a channel's flow depth is met gradually) and no wider than R / 4
    (a wider passage is no floor but a curvature the law lacks)."""
    flows = np.unique(points.flow_m3h)
    lowest = np.array([points.level_mm[points.flow_m3h == q].min() for q in flows])
    qq = (flows - values["flow_centre_m3h"]) / values["flow_scale_m3h"]
    slope, level = np.polyfit(qq, lowest, 1) if flows.size > 1 else (0.0, float(lowest[0]))
    lo, hi = float(points.level_mm.min()), float(points.level_mm.max())
    span = max(hi - lo, 1e-3)
    sharpest = min(max(_rms(_steady_residuals(points, _vector(values))), 1e-6 * span),
                   0.125 * span)  # fmt: skip
    start = {**values, "floor_mm": float(level), "floor_per_q_mm": float(slope),
             "floor_smooth_mm": sharpest}  # fmt: skip
    return start, {"floor_mm": (lo - span, hi), "floor_smooth_mm": (sharpest, 0.25 * span)}


def _physical_law(points: SteadyPoints, values: dict[str, float]) -> bool:
    """Whether the discharge coefficient is physical at every opening ratio: in (0, 1] (the
    jet is no wider than the opening nor faster than the head allows) over the steady points'
    discharges, and still positive over them widened by half their span each way (a
    controller and an inflow step go past the table). The coefficient moves monotonically
    from its small-opening to its large-opening value as the ratio grows, so those two ends,
    linear in discharge, decide."""
    q_lo, q_hi = float(points.flow_m3h.min()), float(points.flow_m3h.max())
    margin = 0.5 * (q_hi - q_lo)

    def ends(q: float) -> list[float]:
        qq = (q - values["flow_centre_m3h"]) / values["flow_scale_m3h"]
        return [values["cd_small"] + values["cd_small_per_q"] * qq,
                values["cd_large"] + values["cd_large_per_q"] * qq]  # fmt: skip

    inside = ends(q_lo) + ends(q_hi)
    wide = ends(max(q_lo - margin, 0.0)) + ends(q_hi + margin)
    return bool(np.all(np.isfinite(wide)) and min(inside) > 0.0 and max(inside) <= 1.0
                and min(wide) > 0.0)  # fmt: skip


def fixed_parameters(static: Any, records: dict[str, Record], gauge: str, points: SteadyPoints
                     ) -> tuple[dict[str, float], dict[str, str]]:  # fmt: skip
    """The parameters fixed before the fit and where each came from (``max_substep_s``
    provisional: half the sample period until :func:`_storage_start` knows the storage)."""
    width, width_from = start.gate_width_m(static, records, gauge)
    resolution, resolution_from = start.opening_quantum_mm(records)
    centre, scale, flow_from = start.flow_normalisation(static)
    values = {
        "width_m": width, "resolution_mm": resolution,
        "max_substep_s": 0.5 * start.sample_period_s(records),
        "flow_centre_m3h": centre, "flow_scale_m3h": scale,
        "depth_max_m": start.depth_bracket_m(points.level_mm, records, gauge),
        "area_m2": 1.0, "speed_mm_s": 1.0, "stall_depth_m": values_depth(points),
        **{n: FORMAT_DEFAULTS[n] for n in TAIL + FLOOR},
    }  # fmt: skip
    sources = {
        "width_m": width_from, "resolution_mm": resolution_from, "flow_centre_m3h": flow_from,
        "flow_scale_m3h": flow_from,
        "depth_max_m": f"power of two at or above {start.DEPTH_MARGIN:g} x the highest level",
    }  # fmt: skip
    return values, sources


def values_depth(points: SteadyPoints) -> float:
    """A placeholder stall depth above every steady level (the actuator fit replaces it), m."""
    return max(1e-3, 10.0 * float(np.max(points.level_mm)) / 1000.0)


def _conductance_m2s(points: SteadyPoints, values: dict[str, float]) -> np.ndarray:
    """∂Q_g/∂h at every steady point (:func:`~gatetwin.plant.physical_kernel.gate_flow_slopes`),
    m²/s."""
    p = list(_vector(values))
    out = []
    for e, q in zip(points.opening_mm, points.flow_m3h, strict=True):
        gate = kernel.actuator_target_mm(float(e), p)
        h, tail = kernel.steady_depth_m(gate, float(q), p), kernel.tail_steady_m(float(q), p)
        out.append(kernel.gate_flow_slopes(h, tail, gate, float(q), p)[0])
    return np.asarray(out)


def _storage_start(values: dict[str, float], points: SteadyPoints, drives: Sequence[_Drive],
                   sources: dict[str, str]) -> dict[str, float]:  # fmt: skip
    """Start the storage area from the scan of time constants that best fits the records, and
    fix the sub-step from the shortest time constant it gives (``sources`` updated)."""
    conductance = _conductance_m2s(points, values)
    positive = conductance[np.isfinite(conductance) & (conductance > 0)]
    if positive.size == 0:
        raise IdentificationError("physical: the gate law passes no flow at any steady point")
    period = 2.0 * values["max_substep_s"]
    longest = max(float(d.time_s[-1] - d.time_s[0]) for d in drives)
    best, best_rms = values["area_m2"], math.inf
    for area in start.area_scan_m2(period, longest, float(np.median(positive)), AREA_SCAN):
        trial = _vector({**values, "area_m2": float(area)})
        rms = _rms(np.concatenate(_dynamic_residuals(drives, trial)))
        if rms < best_rms:
            best, best_rms = float(area), rms
    substep, substep_from = start.max_substep_s(period, best / positive)
    sources["max_substep_s"] = substep_from
    sources["area_m2"] = "start: the best of a scan of time constants (fitted after)"
    return {**values, "area_m2": best, "max_substep_s": substep}


def seiche_periods_s(records: dict[str, Record], p: np.ndarray, points: SteadyPoints
                     ) -> tuple[float, float]:  # fmt: skip
    """The seiche periods the data can show, s: from two sample periods (a faster oscillation
    aliases) to the quarter-wave period of the longest pool the storage allows, 4 L / sqrt(g h)
    with L = area / gate width (the channel is at least as wide as the gate) at the steady
    points' median depth."""
    depth_m = max(float(np.median(points.level_mm + p[kernel.INDEX["offset_mm"]])) / 1000.0,
                  kernel.DEPTH_MIN_M)  # fmt: skip
    length_m = kernel.storage_area_m2(depth_m, list(p)) / p[kernel.INDEX["width_m"]]
    return 2.0 * start.sample_period_s(records), 4.0 * length_m / math.sqrt(kernel.G * depth_m)


def _seiche_start(
    residuals: Sequence[np.ndarray], drives: Sequence[_Drive], periods_s: tuple[float, float]
) -> float:
    """The period of the strongest oscillation left in the simulation error within
    ``periods_s`` (the records' power spectra summed on one grid of periods), s."""
    grid = np.geomspace(periods_s[0], periods_s[1], 64)
    power = np.zeros(grid.size)
    for r, d in zip(residuals, drives, strict=True):
        dt = float(np.median(np.diff(d.time_s)))
        freq = np.fft.rfftfreq(r.size, dt)
        spectrum = np.abs(np.fft.rfft(r - r.mean())) ** 2
        power += np.interp(1.0 / grid, freq, spectrum)
    return float(grid[int(np.argmax(power))])


def _fit_seiche(drives: Sequence[_Drive], p: np.ndarray, weights: list[float],
                periods_s: tuple[float, float]) -> tuple[np.ndarray, dict[str, Any]]:  # fmt: skip
    """The pool's seiche from the simulation error left by the hydraulics (held fixed): its
    period (within ``periods_s``, started at the residuals' spectral peak), decay time (one
    sample period to ten of the longest periods) and amplitude per mm of gate move, with an
    F-test against none; not kept when the period or the decay time ends on its bound
    (``at_bound`` in the report)."""

    def weighted(res: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([r / w for r, w in zip(res, weights, strict=True)])

    def residual(x: np.ndarray) -> np.ndarray:
        return weighted(_dynamic_residuals(drives, p, np.asarray(x, float)))

    plain = _dynamic_residuals(drives, p)
    without = weighted(plain)
    if periods_s[1] <= periods_s[0]:
        reason = (
            f"no seiche the sampling can show: the longest pool's quarter-wave period "
            f"{periods_s[1]:.3g} s is under two sample periods ({periods_s[0]:.3g} s)"
        )
        return NO_SEICHE.copy(), {"kept": False, "reason": reason}
    period = _seiche_start(plain, drives, periods_s)
    lower = (periods_s[0], periods_s[0] / 2.0, -SEICHE_AMPLITUDE_MAX)
    upper = (periods_s[1], 10.0 * periods_s[1], SEICHE_AMPLITUDE_MAX)
    result = least_squares(residual, (period, period, SEICHE_AMPLITUDE_START),
                           bounds=(lower, upper), x_scale="jac")  # fmt: skip
    n, k = without.size, len(SEICHE)
    rss0, rss1 = float(without @ without), 2.0 * float(result.cost)
    p_value = _f_test_p(rss0, rss1, k, max(1, n - k))
    # a period or decay time at its bound is not an oscillation the sampling resolves (a
    # decay of one sample period is a transient the hydraulics miss), and the F-test's
    # reference distribution does not hold on a bound
    bounded = [name for name, active in zip(SEICHE[:2], result.active_mask[:2], strict=True)
               if active != 0]  # fmt: skip
    report = {
        "kept": bool(result.success and p_value < SEICHE_SIGNIFICANCE and result.x[2] != 0.0
                     and not bounded),  # fmt: skip
        "at_bound": bounded,
        "parameters": dict(zip(SEICHE, (float(v) for v in result.x), strict=True)),
        "standard_errors": _standard_errors(result, SEICHE),
        "f_test_p_value": p_value,
        "weighted_rss_without": rss0, "weighted_rss_with": rss1,
        "period_bounds_s": [float(v) for v in periods_s], "period_start_s": period,
    }  # fmt: skip
    return np.asarray(result.x, float), report


def _f_test_p(rss0: float, rss1: float, extra: int, residual_dof: int) -> float:
    """p-value of the F-test of ``extra`` added parameters that take the residual sum of
    squares from ``rss0`` to ``rss1`` with ``residual_dof`` degrees of freedom left (0 for a
    perfect fit)."""
    f_stat = ((rss0 - rss1) / extra) / (rss1 / residual_dof) if rss1 > 0 else math.inf
    return float(f_dist.sf(f_stat, extra, residual_dof))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def data_ranges(static: Any, records: dict[str, Record], gauge: str) -> dict[str, list[float]]:
    """Discharge, opening and level ranges the data span (the model's validity envelope)."""
    q = [np.asarray(static.flow_m3h, float)]
    e = [np.asarray(static.opening_mm, float)]
    h = [np.asarray(static.levels_mm[gauge], float)]
    for rec in records.values():
        q.append(rec.flow_m3h[rec.hold])
        e.append(rec.opening_mm[rec.hold])
        if gauge in rec.levels_mm:
            h.append(rec.levels_mm[gauge])

    def span(parts: list[np.ndarray], digits: int) -> list[float]:
        x = np.concatenate(parts)
        x = x[np.isfinite(x)]
        return [round(float(x.min()), digits), round(float(x.max()), digits)]

    return {"flow_m3h": span(q, 1), "opening_mm": span(e, 1), "level_mm": span(h, 0)}
