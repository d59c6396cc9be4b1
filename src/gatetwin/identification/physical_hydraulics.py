"""The hydraulics of the ``physical`` family (stages 3 to 5 of
:mod:`gatetwin.identification.physical`): the storage by simulation error, the law and the storage
jointly, the pool below the gate and a floor at the gauge.

Each runs from the gate law (:mod:`gatetwin.identification.physical_law`) and the actuator already
fitted, on the residuals of :mod:`gatetwin.identification.physical_residuals`. The seiche, fitted
after with the hydraulics held, is not here (:mod:`gatetwin.identification.physical_seiche`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification import physical_start as start
from gatetwin.identification.physical_law import LAW, LAW_CORE, LAWS, _physical_law
from gatetwin.identification.physical_residuals import (
    SEICHE_SIGNIFICANCE,
    SteadyPoints,
    _Drive,
    _dynamic_residuals,
    _f_test_p,
    _fit,
    _rms,
    _steady_residuals,
    _vector,
)
from gatetwin.plant import physical_kernel as kernel

__all__ = [
    "AREA_SCAN",
    "FLOOR",
    "STORAGE",
    "TAIL",
    "TAIL_DEPTH_START",
    "TAIL_EXPONENT_RANGE",
    "TAIL_EXPONENT_START",
]

#: Storage-area starts scanned (log-spaced time constants, one sample period to a record).
AREA_SCAN = 25
STORAGE = ["area_m2", "area_per_depth_m"]
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
#: The floor of a far gauge (its level, the level's drift with discharge, the smoothness of
#: the passage), tried last with the law, storage and tail pool kept (:func:`_fit_floor`):
#: the gate's pool drawn down at a low inflow stops reaching the gauge, whose water runs at
#: its channel's own depth for the inflow.
FLOOR = ["floor_mm", "floor_per_q_mm", "floor_smooth_mm"]


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


def _physical_tail(values: dict[str, float]) -> bool:
    """Whether a fitted tail pool is physical: it stores water, its steady depth lies above
    its datum, and its outlet's exponent lies in :data:`TAIL_EXPONENT_RANGE`."""
    lo, hi = TAIL_EXPONENT_RANGE
    return bool(values["tail_area_m2"] > 0.0 and values["tail_depth_m"] > values["tail_datum_m"]
                and lo <= values["tail_exponent"] <= hi)  # fmt: skip


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
