"""Validate an FMU against measured records: simulate freely, compare, apply thresholds.

:func:`validate_fmu` drives one FMU (through fmpy) with the measured inputs of each record
and compares its output with the measured level; :func:`validate_matrix` does it for every
FMU × record pair and returns flat cells; :func:`matrix_markdown` renders them.

Inputs given to the FMU, per sample of the record:

* the gate opening as logged on ``hold`` samples; while the actuator moves (``open``
  samples, opening empty or untrusted) the opening is interpolated linearly *in time*
  between the last hold opening and the next (:func:`gatetwin.identify.reconstructed_opening`):
  the actuator is taken to move at a roughly constant speed;
* the measured discharge.

Both are held over the communication step to the next sample (zero-order hold); across a
logging gap the FMU makes several steps with the last logged inputs (see
:func:`~gatetwin.validate.fmu_runner.communication_grid`). The FMU's output is never
corrected by a measurement: it is a free-run (simulation) test, much harder than the
one-step-ahead R² of the reference study.

Results are findings; whether they fail is decided by the thresholds the caller passes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identify import reconstructed_opening, residual_whiteness
from gatetwin.identify.metrics import Whiteness
from gatetwin.identify.serial import finite_list, finite_or_none
from gatetwin.records import Record, read_record
from gatetwin.validate.compare import (
    FreeRunMetrics,
    StepComparison,
    compare_steps,
    free_run_metrics,
    worst_step_differences,
)
from gatetwin.validate.errors import ValidationError
from gatetwin.validate.fmu_runner import (
    FmuInfo,
    communication_grid,
    inspect_fmu,
    output_for_gauge,
    run_fmu,
    static_findings,
)
from gatetwin.validate.thresholds import Check, Threshold

#: Largest lag of the residual whiteness test, samples.
WHITENESS_MAX_LAG = 25


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

    @property
    def passed(self) -> bool:
        """True when no threshold failed."""
        return not any(c.failed for c in self.checks)

    def flat_metrics(self) -> dict[str, float]:
        """Every threshold-able metric of this record by name (see ``thresholds``)."""
        return flat_metrics(self.metrics, self.whiteness, self.steps)

    def to_dict(self) -> dict[str, Any]:
        return {
            "record": self.record,
            "record_sha256": self.record_sha256,
            "gauge": self.gauge,
            "test": self.test,
            "n_samples": self.n_samples,
            "n_fmu_steps": self.n_fmu_steps,
            "communication_step_s": self.step_s,
            "metrics": self.metrics.to_dict(),
            "step_comparison": [s.to_dict() for s in self.steps],
            "whiteness": _whiteness_dict(self.whiteness, self.whiteness_note),
            "thresholds": [c.to_dict() for c in self.checks],
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
    metrics: FreeRunMetrics, whiteness: Whiteness | None, steps: tuple[StepComparison, ...]
) -> dict[str, float]:
    """Metrics by threshold name; step metrics only for records with steps."""
    out = {
        "fit_percent": metrics.fit_percent,
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
    """

    fmu: FmuInfo
    static_findings: tuple[str, ...]
    thresholds: tuple[Threshold, ...]
    records: tuple[RecordValidation, ...]

    @property
    def static_passed(self) -> bool:
        return not self.static_findings

    @property
    def passed(self) -> bool:
        """True when the static validation is clean and every record passed."""
        return self.static_passed and all(r.passed for r in self.records)

    def to_dict(self) -> dict[str, Any]:
        return {
            "fmu": self.fmu.to_dict(),
            "static_validation": {
                "tool": "fmpy.validation.validate_fmu",
                "findings": list(self.static_findings),
                "passed": self.static_passed,
            },
            "thresholds": [t.to_dict() for t in self.thresholds],
            "records": [r.to_dict() for r in self.records],
            "passed": self.passed,
        }


def _load(record: str | Path | Record) -> Record:
    return record if isinstance(record, Record) else read_record(record)


def _record_name(record: Record) -> str:
    return Path(record.path).name if record.path else "<arrays>"


def _measured_level(record: Record, gauge: str, fmu: FmuInfo) -> np.ndarray:
    if gauge not in record.levels_mm:
        raise ValidationError(
            f"{record.path or '<arrays>'}: no column level_{gauge}_mm for the output of "
            f"{fmu.name} (the record has gauges {', '.join(record.gauges)})"
        )
    level = np.asarray(record.levels_mm[gauge], dtype=float)
    if np.count_nonzero(np.isfinite(level)) < 2:
        raise ValidationError(
            f"{record.path or '<arrays>'}: column level_{gauge}_mm has fewer than 2 values"
        )
    return level


def _whiteness(trace: Trace) -> tuple[Whiteness | None, str]:
    if not np.all(np.isfinite(trace.simulated_mm)):
        return None, "the FMU output is not finite"
    try:
        return residual_whiteness(trace.residual_mm, max_lag=WHITENESS_MAX_LAG), ""
    except IdentificationError as exc:
        return None, str(exc)


def _validate_record(
    fmu: FmuInfo, output: str, record: Record, thresholds: Sequence[Threshold]
) -> RecordValidation:
    gauge = output[len("level_") : -len("_mm")]
    measured = _measured_level(record, gauge, fmu)
    try:
        opening = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    except IdentificationError as exc:
        raise ValidationError(f"{record.path or '<arrays>'}: {exc}") from None
    grid = communication_grid(record.time_s, record.sample_period_s)
    simulated = run_fmu(fmu, output, grid, opening, record.flow_m3h)
    trace = Trace(record.time_s, opening, record.flow_m3h, measured, simulated, record.hold)
    metrics = free_run_metrics(measured, simulated)
    whiteness, note = _whiteness(trace)
    finite = bool(np.all(np.isfinite(simulated)))
    steps = compare_steps(record, gauge, simulated) if finite else ()
    flat = flat_metrics(metrics, whiteness, steps)
    return RecordValidation(
        record=_record_name(record),
        gauge=gauge,
        test=record.test,
        n_samples=record.n_samples,
        n_fmu_steps=grid.n_steps,
        step_s=grid.step_s,
        metrics=metrics,
        whiteness=whiteness,
        steps=steps,
        checks=tuple(t.check(flat) for t in thresholds),
        trace=trace,
        whiteness_note=note,
        record_sha256=record.sha256,
    )


def validate_fmu(
    fmu_path: str | Path,
    records: Sequence[str | Path | Record],
    *,
    gauge: str | None = None,
    thresholds: Sequence[Threshold] = (),
) -> FmuValidation:
    """Validate one FMU against measured records.

    Parameters
    ----------
    fmu_path : str or Path
        An FMI 2.0 co-simulation FMU with Real inputs ``opening_mm`` (mm) and ``flow_m3h``
        (m³/h) and an output ``level_<G>_mm`` (mm).
    records : sequence of path or Record
        Records (paths are read with :func:`gatetwin.records.read_record`).
    gauge : str, optional
        Gauge to compare (output ``level_<gauge>_mm``); default the FMU's only level output.
    thresholds : sequence of Threshold
        Applied to every record; none means nothing but the static validation can fail.

    Returns
    -------
    FmuValidation
        Metrics, static findings and checks; ``passed`` says whether anything failed.

    Raises
    ------
    ValidationError
        The FMU cannot be run (see :func:`~gatetwin.validate.fmu_runner.inspect_fmu` and
        :func:`~gatetwin.validate.fmu_runner.run_fmu`), a record lacks the gauge.
    RecordError
        A record breaks the data-format contract.
    """
    if not records:
        raise ValidationError("no records to validate against")
    info = inspect_fmu(fmu_path)
    output = output_for_gauge(info, gauge)
    loaded = [_load(r) for r in records]
    findings = static_findings(info.path)
    results = tuple(_validate_record(info, output, r, thresholds) for r in loaded)
    return FmuValidation(info, findings, tuple(thresholds), results)


#: Columns of a matrix cell, in table order (besides ``fmu`` and ``record``).
MATRIX_METRICS = ("fit_percent", "r2", "rmse_mm", "mae_mm", "max_abs_error_mm", "bias_mm")


def matrix_cells(result: FmuValidation) -> list[dict[str, Any]]:
    """Flat, JSON-ready cells (one per record) of one FMU's validation."""
    cells = []
    for rec in result.records:
        metrics = rec.metrics.to_dict()
        cells.append(
            {
                "fmu": result.fmu.name,
                "record": rec.record,
                "gauge": rec.gauge,
                "test": rec.test,
                **{name: metrics[name] for name in MATRIX_METRICS},
                "static_passed": result.static_passed,
                "failed_checks": _failed_checks(result, rec),
                "passed": result.static_passed and rec.passed,
            }
        )
    return cells


def _failed_checks(result: FmuValidation, rec: RecordValidation) -> list[str]:
    static = [] if result.static_passed else ["fmpy static validation"]
    return static + [c.threshold.text for c in rec.checks if c.failed]


def validate_matrix(
    fmu_paths: Sequence[str | Path],
    record_paths: Sequence[str | Path | Record],
    *,
    thresholds: Sequence[Threshold] = (),
    gauge: str | None = None,
) -> list[dict[str, Any]]:
    """Validate every FMU against every record; one flat cell per pair.

    Records are read once. Each cell holds ``fmu`` and ``record`` (file names), ``gauge``,
    ``test``, ``fit_percent``, ``r2``, ``rmse_mm``, ``mae_mm``, ``max_abs_error_mm``,
    ``bias_mm`` (None where not finite), ``static_passed``, ``failed_checks`` (the
    passing conditions that failed) and ``passed``. Raises as :func:`validate_fmu`.
    """
    records = [_load(r) for r in record_paths]
    cells: list[dict[str, Any]] = []
    for fmu in fmu_paths:
        cells.extend(matrix_cells(validate_fmu(fmu, records, gauge=gauge, thresholds=thresholds)))
    return cells


def _cell_text(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "pass" if value else "**FAIL**"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value).replace("|", "\\|")


def matrix_markdown(cells: Sequence[dict[str, Any]]) -> str:
    """The validation matrix as a Markdown table (one row per FMU × record)."""
    header = ["FMU", "record", "gauge", "fit %", "R²", "RMSE (mm)", "MAE (mm)",
              "max abs error (mm)", "bias (mm)", "result"]  # fmt: skip
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for cell in cells:
        values = [cell["fmu"], cell["record"], cell["gauge"],
                  *(cell[m] for m in MATRIX_METRICS), cell["passed"]]  # fmt: skip
        row = [_cell_text(v) for v in values]
        if cell.get("failed_checks"):
            row[-1] += " (" + "; ".join(cell["failed_checks"]) + ")"
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"
