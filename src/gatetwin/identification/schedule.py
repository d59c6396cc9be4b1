"""Schedule on discharge: per-condition models → one plant whose parameters follow Q.

FOPDT: each step condition gives K, T, L (least-squares fit, the model dead time) at its
discharge. Each parameter is smoothed across conditions by a least-squares polynomial in Q
(degree ≤ 2, never more than the number of conditions − 2) and tabulated at the conditions'
discharges; the plant interpolates linearly between those knots and clamps outside them —
the schedule's validity range is the span of the conditions.

ARX: the coefficients of each PRBS condition are the knots (linear interpolation between
them; stability is checked on a fine grid of Q).

Operating point: the plant's output is ``level_ref_mm(Q) + x`` with ``x`` driven by
``e − opening_ref_mm``. Each condition was identified around its own opening ``e_i``; its
knot value ``level_ref_mm(Q_i) = H_rating(Q_i, e_i) + K_i·(opening_ref_mm − e_i)`` makes the
steady state equal the rating relation's level at ``(Q_i, e_i)`` and the local slope K_i
(for ARX the DC gain), so one reference opening serves every knot.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.metrics import dc_gain, is_stable
from gatetwin.identification.rating import RatingFit
from gatetwin.plant.model import ArxPlant, FopdtPlant, Schedule

__all__ = [
    "DIGITS",
    "FOPDT_PARAMETERS",
    "ArxCondition",
    "StepCondition",
    "arx_schedule",
    "fopdt_schedule",
    "predict_condition",
    "smooth_in_flow",
]

FOPDT_PARAMETERS = ("gain_mm_per_mm", "time_constant_s", "dead_time_s")
#: Decimals kept in a schedule: far below each parameter's standard error (K ±0.05 mm/mm,
#: T ±0.5 s, L ±0.5 s, levels ±0.1 mm), so model files do not carry optimiser round-off.
DIGITS = {"gain_mm_per_mm": 4, "time_constant_s": 3, "dead_time_s": 3, "level_ref_mm": 3, "arx": 6}


@dataclass(frozen=True)
class StepCondition:
    """One step condition's FOPDT at one gauge (least-squares fit, with standard errors)."""

    name: str
    flow_m3h: float
    opening_mm: float
    delta_e_mm: float
    pre_mean_mm: float
    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    gain_se: float
    time_constant_se_s: float
    dead_time_se_s: float
    record_sha256: str = ""

    def to_dict(self) -> dict[str, Any]:
        """As JSON, floats to 6 decimals (far below the standard errors)."""
        return {k: round(v, 6) + 0.0 if isinstance(v, float) else v
                for k, v in self.__dict__.items()}  # fmt: skip


@dataclass(frozen=True)
class ArxCondition:
    """One PRBS condition's ARX at one gauge."""

    name: str
    flow_m3h: float
    opening_mm: float
    level_mm: float
    a: tuple[float, ...]
    b: tuple[float, ...]
    nk: int
    sample_period_s: float
    record_sha256: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {**self.__dict__, "a": list(self.a), "b": list(self.b)}


def smooth_in_flow(flow_m3h: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, int]:
    """Least-squares polynomial of ``values`` in Q evaluated at ``flow_m3h`` (and its degree)."""
    degree = int(min(2, max(0, flow_m3h.size - 2)))
    if degree == 0:
        return np.full_like(values, np.mean(values)), 0
    coef = np.polyfit(flow_m3h, values, degree)
    return np.polyval(coef, flow_m3h), degree


def _sorted_unique(conditions: Sequence[Any], kind: str) -> list[Any]:
    if not conditions:
        raise IdentificationError(f"{kind} schedule: no conditions to build it from")
    ordered = sorted(conditions, key=lambda c: c.flow_m3h)
    q = np.array([c.flow_m3h for c in ordered])
    if np.any(np.diff(q) <= 0.5):
        raise IdentificationError(
            f"{kind} schedule: two conditions at the same discharge ({q.round(1).tolist()})"
        )
    return ordered


def fopdt_schedule(
    conditions: Sequence[StepCondition], rating: RatingFit, *, gauge: str,
    opening_ref_mm: float | None = None,
) -> tuple[FopdtPlant, dict[str, Any]]:  # fmt: skip
    """Scheduled FOPDT plant and a report of the smoothing (per-condition residuals)."""
    cond = _sorted_unique(conditions, "fopdt")
    q = np.array([c.flow_m3h for c in cond])
    e_op = np.array([c.opening_mm for c in cond])
    e_ref = float(np.median(e_op)) if opening_ref_mm is None else float(opening_ref_mm)
    smoothed, report = {}, {"degree": 0, "residuals": {}}
    for name in FOPDT_PARAMETERS:
        raw = np.array([getattr(c, name) for c in cond])
        smoothed[name], report["degree"] = smooth_in_flow(q, raw)
        report["residuals"][name] = (raw - smoothed[name]).tolist()
    smoothed["dead_time_s"] = np.maximum(smoothed["dead_time_s"], 0.0)
    smoothed["time_constant_s"] = np.maximum(smoothed["time_constant_s"], 1e-3)
    h_rating = rating.level_mm(q, e_op)
    level_ref = h_rating + smoothed["gain_mm_per_mm"] * (e_ref - e_op)
    report["rating_minus_measured_mm"] = (h_rating - [c.pre_mean_mm for c in cond]).tolist()
    values = {k: _rounded(smoothed[k], DIGITS[k]) for k in FOPDT_PARAMETERS}
    values["level_ref_mm"] = _rounded(level_ref, DIGITS["level_ref_mm"])
    plant = FopdtPlant(gauge, e_ref, Schedule(_knots(q), values))
    return plant, report


def arx_schedule(
    conditions: Sequence[ArxCondition], rating: RatingFit, *, gauge: str,
    opening_ref_mm: float | None = None,
) -> tuple[ArxPlant, dict[str, Any]]:  # fmt: skip
    """Scheduled ARX plant (knots = conditions) and a stability report over Q."""
    cond = _sorted_unique(conditions, "arx")
    first = cond[0]
    if any(len(c.a) != len(first.a) or len(c.b) != len(first.b) or c.nk != first.nk
           or c.sample_period_s != first.sample_period_s for c in cond):  # fmt: skip
        raise IdentificationError("arx schedule: conditions have different orders or periods")
    q = np.array([c.flow_m3h for c in cond])
    e_op = np.array([c.opening_mm for c in cond])
    e_ref = float(np.median(e_op)) if opening_ref_mm is None else float(opening_ref_mm)
    gains = np.array([dc_gain(c.a, c.b) for c in cond])
    level_ref = rating.level_mm(q, e_op) + gains * (e_ref - e_op)
    values: dict[str, tuple[float, ...]] = {}
    for i in range(len(first.a)):
        values[f"a{i + 1}"] = _rounded([c.a[i] for c in cond], DIGITS["arx"])
    for j in range(len(first.b)):
        values[f"b{j + 1}"] = _rounded([c.b[j] for c in cond], DIGITS["arx"])
    values["level_ref_mm"] = _rounded(level_ref, DIGITS["level_ref_mm"])
    plant = ArxPlant(gauge, e_ref, first.sample_period_s, len(first.a), len(first.b), first.nk,
                     Schedule(_knots(q), values))  # fmt: skip
    grid = np.linspace(q[0], q[-1], 41)
    unstable = [float(x) for x in grid if not is_stable(plant.coefficients(float(x))[0])]
    if unstable:
        warnings.warn(
            f"arx schedule: interpolated model unstable at Q = {unstable[0]:.1f} m³/h",
            RuntimeWarning, stacklevel=2,
        )  # fmt: skip
    report = {"dc_gain_mm_per_mm": gains.tolist(), "unstable_flow_m3h": unstable,
              "rating_minus_measured_mm": (rating.level_mm(q, e_op)
                                           - [c.level_mm for c in cond]).tolist()}  # fmt: skip
    return plant, report


def _rounded(values: Any, digits: int) -> tuple[float, ...]:
    return tuple(round(float(v), digits) + 0.0 for v in values)


def _knots(flow_m3h: np.ndarray) -> tuple[float, ...]:
    """Knots at the conditions' mean discharges, to the flow meter's 0.1 m³/h."""
    return tuple(round(float(v), 1) for v in flow_m3h)


def predict_condition(plant: FopdtPlant, flow_m3h: float) -> dict[str, float]:
    """K, T, L the schedule gives at ``flow_m3h`` (for the leave-one-out check)."""
    return {name: plant.schedule.at(name, flow_m3h) for name in FOPDT_PARAMETERS}
