"""Step-test identification of a :class:`~gatetwin.records.Record`, every gauge at once.

A thin wrapper: it picks the step (an opening change between two hold segments found by
the record reader), runs :func:`~gatetwin.identification.fopdt.paper_step_method` and
:func:`~gatetwin.identification.fopdt.fit_fopdt` on each gauge, and shapes the result for the
command line's JSON. The methods themselves live in :mod:`gatetwin.identification.fopdt`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.fopdt import FopdtFit, PaperStepResult, fit_fopdt, paper_step_method
from gatetwin.identification.serial import finite_or_none, none_to_nan
from gatetwin.records import Record

__all__ = ["GaugeStep", "StepIdentification", "hold_mean_flow", "identify_step"]


@dataclass(frozen=True)
class GaugeStep:
    """Both step analyses of one gauge.

    Attributes
    ----------
    gauge : str
        Gauge name (``"3F"``).
    paper : PaperStepResult
        The reference study's method.
    fit : FopdtFit
        Least-squares FOPDT fit on the whole transient.
    """

    gauge: str
    paper: PaperStepResult
    fit: FopdtFit

    def to_dict(self) -> dict[str, Any]:
        p = self.paper
        return {
            "pre_mean_mm": p.pre_mean_mm,
            "pre_sd_mm": p.pre_sd_mm,
            "post_mean_mm": p.post_mean_mm,
            "post_sd_mm": p.post_sd_mm,
            "dH_mm": p.delta_level_mm,
            "paper": {
                "K": p.gain_mm_per_mm,
                "L_s": p.dead_time_s,
                "T_s": p.time_constant_s,
                **p.to_dict(),
            },
            "fit": self.fit.to_dict(),
        }


@dataclass(frozen=True)
class StepIdentification:
    """FOPDT identification of one step of a record.

    Attributes
    ----------
    delta_e_mm : float
        Opening step, mm.
    flow_m3h : float
        Mean discharge over the record's hold samples, m³/h (NaN if never logged).
    onset_time_s : float
        Step onset, s.
    step_index : int
        Which step of the record (0 = first).
    opening_before_mm, opening_after_mm : float
        Hold openings on either side of the step, mm.
    gauges : dict[str, GaugeStep]
        Results per gauge, in the record's gauge order.
    """

    delta_e_mm: float
    flow_m3h: float
    onset_time_s: float
    step_index: int
    opening_before_mm: float
    opening_after_mm: float
    gauges: dict[str, GaugeStep]

    def to_dict(self) -> dict[str, Any]:
        return {
            "test": "step",
            "delta_e_mm": self.delta_e_mm,
            "flow_m3h": finite_or_none(self.flow_m3h),
            "onset_time_s": self.onset_time_s,
            "step_index": self.step_index,
            "opening_before_mm": self.opening_before_mm,
            "opening_after_mm": self.opening_after_mm,
            "gauges": {name: g.to_dict() for name, g in self.gauges.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StepIdentification:
        try:
            gauges = {
                name: GaugeStep(
                    name, PaperStepResult.from_dict(g["paper"]), FopdtFit.from_dict(g["fit"])
                )
                for name, g in data["gauges"].items()
            }
            return cls(
                delta_e_mm=float(data["delta_e_mm"]),
                flow_m3h=none_to_nan(data["flow_m3h"]),
                onset_time_s=float(data["onset_time_s"]),
                step_index=int(data["step_index"]),
                opening_before_mm=float(data["opening_before_mm"]),
                opening_after_mm=float(data["opening_after_mm"]),
                gauges=gauges,
            )
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise IdentificationError(f"step identification: malformed ({exc})") from None


def _gauge_names(record: Record, gauge: str | Sequence[str] | None) -> tuple[str, ...]:
    names = record.gauges if gauge is None else (gauge,) if isinstance(gauge, str) else gauge
    unknown = [g for g in names if g not in record.levels_mm]
    if unknown or not names:
        raise IdentificationError(
            f"{record.path or 'record'}: no gauge {', '.join(unknown) or '(none given)'}; "
            f"it has {', '.join(record.gauges) or 'none'}"
        )
    return tuple(names)


def hold_mean_flow(record: Record) -> float:
    """Mean discharge over the hold samples where it was logged, m³/h (NaN if none)."""
    q = np.asarray(record.flow_m3h, dtype=float)[np.asarray(record.hold, dtype=bool)]
    q = q[np.isfinite(q)]
    return float(np.mean(q)) if q.size else float("nan")


def identify_step(
    record: Record,
    gauge: str | Sequence[str] | None = None,
    step_index: int = 0,
) -> StepIdentification:
    """Identify FOPDT models from one step of a record, for one or every gauge.

    For each gauge: :func:`~gatetwin.identification.fopdt.paper_step_method` (pre window not
    reaching back before the previous step's hold; post window the last 40 valid samples
    of the hold after the step), then :func:`~gatetwin.identification.fopdt.fit_fopdt` on every
    valid sample from the first pre-window sample to the end of the hold after the step
    (valid: finite level, and hold or opening logged), started from ``pre_mean``. The hold
    after the step goes on to where the gate next moved or the inflow changed, across
    logging gaps (:attr:`~gatetwin.records.StepOnset.held_after`).

    Parameters
    ----------
    record : Record
        A read record with at least one step.
    gauge : str or sequence of str, optional
        Gauge name(s); default every gauge.
    step_index : int, optional
        Which step (default the first).

    Returns
    -------
    StepIdentification

    Raises
    ------
    IdentificationError
        No such step or gauge, or a gauge's response cannot support the methods.
    """
    where = record.path or "record"
    if not record.steps:
        raise IdentificationError(
            f"{where}: no step found (no opening change between two hold segments)"
        )
    if not 0 <= step_index < len(record.steps):
        raise IdentificationError(
            f"{where}: step {step_index} requested, the record has {len(record.steps)}"
        )
    step = record.steps[step_index]
    pre_start = record.steps[step_index - 1].after.start if step_index > 0 else 0
    stop = step.held_after.stop
    t, hold, opening = record.time_s, record.hold, record.opening_mm
    results = {}
    for name in _gauge_names(record, gauge):
        level = record.levels_mm[name]
        try:
            paper = paper_step_method(
                t,
                level,
                hold,
                step.time_s,
                stop,
                step.delta_e_mm,
                opening_mm=opening,
                pre_start_index=pre_start,
            )
            mask = (hold | np.isfinite(opening)) & np.isfinite(level)
            mask[: paper.pre_start_index] = False
            mask[stop:] = False
            fit = fit_fopdt(t, level, mask, step.time_s, step.delta_e_mm, paper.pre_mean_mm)
        except IdentificationError as exc:
            raise IdentificationError(f"{where}, gauge {name}: {exc}") from None
        results[name] = GaugeStep(name, paper, fit)
    return StepIdentification(
        delta_e_mm=float(step.delta_e_mm),
        flow_m3h=hold_mean_flow(record),
        onset_time_s=float(step.time_s),
        step_index=int(step_index),
        opening_before_mm=float(step.before.opening_mm),
        opening_after_mm=float(step.after.opening_mm),
        gauges=results,
    )
