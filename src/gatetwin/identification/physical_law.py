"""The gate law of the ``physical`` family, fitted on the steady points alone (stage 1 of
:mod:`gatetwin.identification.physical`).

Where the law starts from the data (:func:`law_start`), how it grows along :data:`LAWS` while
the data ask for more, and when its discharge coefficient is physical. The law's joint
refinement with the storage, the tail pool and the floor is not here
(:mod:`gatetwin.identification.physical_hydraulics`).
"""

from __future__ import annotations

import math

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.physical_residuals import (
    SEICHE_SIGNIFICANCE,
    SteadyPoints,
    _f_test_p,
    _fit,
    _steady_residuals,
)
from gatetwin.plant import physical_kernel as kernel

__all__ = ["LAW", "LAWS", "LAW_CORE", "LAW_EVALUATIONS", "ZERO_START", "law_start"]

LAW = [n for n, _, _ in kernel.PARAMETERS[:9]] + ["offset_mm", "offset_per_flow2_mm"]
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
#: Law parameters that start at zero (no drift with discharge, no offset, no shape).
ZERO_START = ("cd_small_per_q", "cd_large_per_q", "cd_mid_per_q", "cd_log_width_per_q",
              "cd_log_shape", "offset_mm", "offset_per_flow2_mm", "area_per_depth_m")  # fmt: skip


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
