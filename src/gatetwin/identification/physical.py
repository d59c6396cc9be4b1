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
5. **Tail pool** (``physical_hydraulics._fit_tail``): a submerged gate discharges into a
   pool of its own, whose depth lowers the head and answers on its own, slower time scale —
   an upstream gauge alone shows it as a second mode. Its four parameters are fitted
   jointly with the core law and the storage, from a pool half as deep as the water above
   the gate with an orifice below (the next check) and the core law refitted against that
   tailwater; the pool replaces
   the free gate when it is physical and fits the weighted residuals better with no more
   parameters, or an F-test of its extra parameters rejects the free gate.
6. **Seiche** (period, decay time, amplitude per mm of gate move: the pool's oscillation that
   gate moves excite; periods the sampling and the pool can show, :func:`seiche_periods_s`)
   from the simulation error left by stages 4–5, the hydraulics held; kept as
   the plant's ``seiche`` effect block only when an F-test rejects "no seiche" at
   :data:`SEICHE_SIGNIFICANCE`.

This module runs the stages in order, fixes what the data fix before them and fits the
actuator (stage 2); each other stage lives in a module of its own: the gate law in
:mod:`gatetwin.identification.physical_law`, the storage, the joint fit, the tail pool and the
gauge's floor in :mod:`gatetwin.identification.physical_hydraulics`, the seiche in
:mod:`gatetwin.identification.physical_seiche`, and the residuals and least squares they share in
:mod:`gatetwin.identification.physical_residuals`. Their public names are importable from here too.

The simulator of the fits is the kernel compiled by numba
(:func:`gatetwin.identification.physical_residuals.kernel_simulator`): the same
arithmetic as every other rendering, stepping as :class:`gatetwin.plant.physical.
PhysicalSimulator` does (tests hold the two equal).

Fixed before the fit, from the data (:func:`fixed_parameters`; the model file's report
states each value and where it came from):

* ``width_m``: the sidecar's ``gate_width_m``; without one, the width at which the static
  points at the smallest opening ratios pass their discharge with the textbook free-flow
  coefficient :data:`~gatetwin.identification.physical_start.TEXTBOOK_CD` (width and Cd are not
  separable in free underflow);
* ``resolution_mm``: the sidecar's ``actuator_resolution_mm``, else the opening's quantum in
  the records (the largest power of ten dividing every recorded opening);
* ``flow_centre_m3h`` / ``flow_scale_m3h``: the static table's mid-range discharge (two
  significant figures) and the power of ten at or above its span;
* ``depth_max_m``: the power of two at or above four times the highest level (a quarter of the
  smallest opening ratio the data reach, at the largest discharge, still lies in the bracket);
* ``max_substep_s``: half the sample period, or a tenth of the shortest small-signal time
  constant of the starting model at the steady points, whichever is shorter.

The storage area starts from the scan of ``physical_hydraulics._storage_start`` (time
constants from one sample period to the longest record), the actuator from its moves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from gatetwin.errors import IdentificationError
from gatetwin.identification import physical_start as start
from gatetwin.identification.physical_hydraulics import (
    AREA_SCAN,
    FLOOR,
    STORAGE,
    TAIL,
    TAIL_DEPTH_START,
    TAIL_EXPONENT_RANGE,
    TAIL_EXPONENT_START,
    _fit_hydraulics,
)
from gatetwin.identification.physical_law import (
    LAW,
    LAW_CORE,
    LAW_EVALUATIONS,
    LAWS,
    ZERO_START,
    _fit_law,
    law_start,
)
from gatetwin.identification.physical_residuals import (
    NO_SEICHE,
    SEICHE,
    SEICHE_SIGNIFICANCE,
    STEADY_HOLD_SAMPLES,
    STEADY_SAMPLES,
    SteadyPoints,
    _drives,
    _dynamic_residuals,
    _rms,
    _standard_errors,
    _steady_residuals,
    _vector,
    kernel_simulator,
    steady_points,
)
from gatetwin.identification.physical_seiche import (
    SEICHE_AMPLITUDE_MAX,
    SEICHE_AMPLITUDE_START,
    _fit_seiche,
    seiche_periods_s,
)
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.effects import effect_dict
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

#: Parameters fixed from the data before the fit (see the module docstring).
FIXED = ("width_m", "resolution_mm", "max_substep_s", "flow_centre_m3h", "flow_scale_m3h",
         "depth_max_m")  # fmt: skip
ACTUATOR = ["speed_mm_s", "stall_depth_m"]


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
