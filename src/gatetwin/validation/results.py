"""What validating an FMU finds: per record (:class:`RecordValidation`, with the signals
behind it in :class:`Trace`) and per FMU (:class:`FmuValidation`), each with its JSON form,
and the metrics by threshold name (:func:`flat_metrics`).

Plain data: nothing here runs an FMU or decides a threshold (:mod:`gatetwin.validation.harness`
does both), and the files are rendered elsewhere (:mod:`gatetwin.validation.outputs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gatetwin.identification.metrics import Whiteness
from gatetwin.identification.serial import finite_list, finite_or_none
from gatetwin.noise import NoiseFloor
from gatetwin.validation.compare import FreeRunMetrics, StepComparison, worst_step_differences
from gatetwin.validation.fmu_inspect import FmuInfo
from gatetwin.validation.thresholds import Check, Threshold
from gatetwin.validation.validity import Envelope, ValidityFinding

__all__ = ["FmuValidation", "RecordValidation", "Trace", "flat_metrics"]


@dataclass(frozen=True)
class Trace:
    """The signals behind one record's validation (for plots; not serialised).

    Attributes
    ----------
    time_s : ndarray
        Record time stamps, s.
    opening_mm, flow_m3h : ndarray
        The inputs given to the FMU, mm and m³/h.
    measured_mm, simulated_mm : ndarray
        Measured level (NaN where missing) and FMU output, mm.
    hold : ndarray of bool
        The record's actuator flag.
    """

    time_s: np.ndarray
    opening_mm: np.ndarray
    flow_m3h: np.ndarray
    measured_mm: np.ndarray
    simulated_mm: np.ndarray
    hold: np.ndarray

    @property
    def residual_mm(self) -> np.ndarray:
        """Measured minus simulated level, mm (NaN where not measured)."""
        return self.measured_mm - self.simulated_mm


@dataclass(frozen=True)
class RecordValidation:
    """One FMU run on one record, compared with the measured level.

    Attributes
    ----------
    record : str
        The record's file name.
    record_sha256 : str
        Hash of the record's CSV ("" for in-memory records).
    gauge : str
        The gauge compared (``level_<gauge>_mm``).
    test : str
        The record's test type (``step``, ``prbs``, ``free``).
    n_samples : int
        Samples in the record.
    n_fmu_steps : int
        Communication steps the FMU made (more than ``n_samples - 1`` across gaps).
    step_s : float
        Communication step, s (the record's nominal sample period).
    metrics : FreeRunMetrics
    whiteness : Whiteness or None
        Of the free-run residuals (None, with ``whiteness_note``, if too few samples).
    steps : tuple of StepComparison
        FOPDT comparison per step (step records only).
    checks : tuple of Check
        The thresholds applied to this record.
    trace : Trace
        The signals (not serialised).
    whiteness_note : str
        Why ``whiteness`` is missing ("" otherwise).
    record_sha256 : str
        Hash of the record's CSV ("" for in-memory records).
    noise : NoiseFloor or None
        The level noise at the gauge, from the record's steady holds.
    noise_floor_fit_percent : float
        The fit % a perfect model would score against that noise (NaN if unknown).
    level_sd_mm : float
        SD of the measured level over the compared samples, mm (the floor's ``s``).
    validity : ValidityFinding or None
        The record against the FMU's validity envelope.
    fail_outside_validity : bool
        Whether lying outside the envelope fails the record.
    failure_cause : str
        Why the FMU run failed ("" when it did not): the FMU process died, exited or gave
        no result in time, or the output is not finite. Such a record fails.
    run_time_s : float
        Wall-clock time of the FMU run, s (NaN when unknown).
    unobserved_steps : int
        Opening changes the record's logger missed, inside logging gaps
        (:attr:`gatetwin.records.Record.unobserved_steps`): the FMU holds the last logged
        opening through each gap, so the gap's moves reach it late and the metrics include
        the settling after them.
    """

    record: str
    gauge: str
    test: str
    n_samples: int
    n_fmu_steps: int
    step_s: float
    metrics: FreeRunMetrics
    whiteness: Whiteness | None
    steps: tuple[StepComparison, ...]
    checks: tuple[Check, ...]
    trace: Trace = field(repr=False, compare=False)
    whiteness_note: str = ""
    record_sha256: str = ""
    noise: NoiseFloor | None = None
    noise_floor_fit_percent: float = math.nan
    level_sd_mm: float = math.nan
    validity: ValidityFinding | None = None
    fail_outside_validity: bool = False
    failure_cause: str = ""
    run_time_s: float = math.nan
    unobserved_steps: int = 0

    @property
    def inside_validity(self) -> bool | None:
        """Inside the FMU's validity envelope: True, False, or None when unknown."""
        return self.validity.inside if self.validity is not None else None

    @property
    def fit_vs_floor(self) -> float:
        """Fit % minus the noise floor's fit %, percentage points (NaN when unknown)."""
        return self.metrics.fit_percent - self.noise_floor_fit_percent

    @property
    def validity_failed(self) -> bool:
        """Outside the envelope while that fails the record."""
        return self.fail_outside_validity and self.inside_validity is False

    @property
    def passed(self) -> bool:
        """True when the FMU ran, no threshold failed (nor the envelope, when enforced)."""
        return (not self.failure_cause and not any(c.failed for c in self.checks)
                and not self.validity_failed)  # fmt: skip

    def flat_metrics(self) -> dict[str, float]:
        """Every threshold-able metric of this record by name (see ``thresholds``)."""
        return flat_metrics(self.metrics, self.whiteness, self.steps,
                            self.noise_floor_fit_percent)  # fmt: skip

    def noise_floor_dict(self) -> dict[str, Any]:
        """The ``noise_floor`` object of the JSON."""
        noise = self.noise.to_dict() if self.noise is not None else {}
        return {
            "sigma_mm": finite_or_none(noise.get("sigma_mm", math.nan)),
            "fit_percent": finite_or_none(self.noise_floor_fit_percent),
            "level_sd_mm": finite_or_none(self.level_sd_mm),
            "method": noise.get("method", ""),
            "n_stretches": noise.get("n_stretches", 0),
            "n_samples": noise.get("n_samples", 0),
        }

    def validity_dict(self) -> dict[str, Any]:
        """``inside_validity``, ``validity``, ``outside_by`` and details, for the JSON."""
        found = self.validity.to_dict() if self.validity is not None else {
            "inside_validity": None, "validity": None, "outside_by": None}  # fmt: skip
        return {**found, "fail_outside_validity": self.fail_outside_validity,
                "validity_failed": self.validity_failed}  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        return {
            "record": self.record,
            "record_sha256": self.record_sha256,
            "gauge": self.gauge,
            "test": self.test,
            "n_samples": self.n_samples,
            "n_fmu_steps": self.n_fmu_steps,
            "communication_step_s": self.step_s,
            "unobserved_steps": self.unobserved_steps,
            "metrics": self.metrics.to_dict(),
            "step_comparison": [s.to_dict() for s in self.steps],
            "whiteness": _whiteness_dict(self.whiteness, self.whiteness_note),
            "thresholds": [c.to_dict() for c in self.checks],
            "noise_floor": self.noise_floor_dict(),
            "fit_vs_floor": finite_or_none(self.fit_vs_floor),
            **self.validity_dict(),
            "failure_cause": self.failure_cause or None,
            "run_time_s": finite_or_none(self.run_time_s),
            "passed": self.passed,
        }


def _whiteness_dict(whiteness: Whiteness | None, note: str) -> dict[str, Any]:
    if whiteness is None:
        return {"note": note}
    out = whiteness.to_dict()
    out.pop("cross_correlation")
    out.pop("n_cross_outside")
    for key in ("band_99", "ljung_box_q", "ljung_box_p"):
        out[key] = finite_or_none(out[key])
    out["autocorrelation"] = finite_list(out["autocorrelation"])
    return out


def flat_metrics(
    metrics: FreeRunMetrics,
    whiteness: Whiteness | None,
    steps: tuple[StepComparison, ...],
    floor_fit_percent: float = math.nan,
) -> dict[str, float]:
    """Metrics by threshold name; step metrics only for records with steps.

    ``fit_vs_floor`` is ``fit_percent`` minus the noise floor's fit %, percentage points
    (NaN when the floor is unknown).
    """
    out = {
        "fit_percent": metrics.fit_percent,
        "fit_vs_floor": metrics.fit_percent - floor_fit_percent,
        "r2": metrics.r2,
        "rmse_mm": metrics.rmse_mm,
        "mae_mm": metrics.mae_mm,
        "max_abs_error_mm": metrics.max_abs_error_mm,
        "abs_bias_mm": metrics.abs_bias_mm,
        "ljung_box_p": whiteness.ljung_box_p if whiteness is not None else math.nan,
    }
    if steps:
        out.update(worst_step_differences(steps))
    return out


@dataclass(frozen=True)
class FmuValidation:
    """An FMU validated against records.

    Attributes
    ----------
    fmu : FmuInfo
    static_findings : tuple of str
        Problems found by fmpy's static validator (any one is a failure).
    thresholds : tuple of Threshold
    records : tuple of RecordValidation
    validity : dict or None
        The validity envelope the FMU states (:func:`~gatetwin.validation.validity.read_envelope`).
    """

    fmu: FmuInfo
    static_findings: tuple[str, ...]
    thresholds: tuple[Threshold, ...]
    records: tuple[RecordValidation, ...]
    validity: Envelope | None = None

    @property
    def static_passed(self) -> bool:
        return not self.static_findings

    @property
    def passed(self) -> bool:
        """True when the static validation is clean and every record passed."""
        return self.static_passed and all(r.passed for r in self.records)

    def to_dict(self) -> dict[str, Any]:
        env = self.validity
        return {
            "fmu": {
                **self.fmu.to_dict(),
                "validity": None if env is None else {q: list(env[q]) for q in env},
            },
            "static_validation": {
                "tool": "fmpy.validation.validate_fmu",
                "findings": list(self.static_findings),
                "passed": self.static_passed,
            },
            "thresholds": [t.to_dict() for t in self.thresholds],
            "records": [r.to_dict() for r in self.records],
            "passed": self.passed,
        }
