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

Besides the metrics, every record gets

* its **noise floor**: the level noise SD from its steady holds
  (:func:`gatetwin.noise.record_noise_floor`) and the fit % a perfect model would score
  against that noise (:func:`~gatetwin.validate.compare.noise_floor_fit_percent`);
  ``fit_vs_floor`` is the fit minus that floor, in percentage points;
* its place in the FMU's **validity envelope** (:mod:`gatetwin.validate.validity`), read from
  the FMU's own ``resources/provenance.json``: ``inside_validity`` True, False or None
  (unknown).

Each record's run happens in a child process (:mod:`gatetwin.validate.isolation`) under a
wall-clock limit: an FMU that crashes, exits, hangs or outputs NaN or infinity fails that
record, with the cause in ``failure_cause``, whatever the thresholds; the other records and
the report go on. A record whose grid would need more than
:data:`~gatetwin.validate.fmu_runner.MAX_FMU_STEPS` FMU steps is refused before any FMU runs.

Results are findings; whether they fail is decided by the thresholds the caller passes
(and by ``failure_cause``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError, ValidationError
from gatetwin.identify import reconstructed_opening, residual_whiteness
from gatetwin.identify.metrics import Whiteness
from gatetwin.identify.serial import finite_list, finite_or_none
from gatetwin.noise import NoiseFloor, record_noise_floor
from gatetwin.records import Record, read_record
from gatetwin.validate.compare import (
    FreeRunMetrics,
    StepComparison,
    compare_steps,
    free_run_metrics,
    noise_floor_fit_percent,
    worst_step_differences,
)
from gatetwin.validate.fmu_runner import (
    CommunicationGrid,
    FmuInfo,
    communication_grid,
    inspect_fmu,
    output_for_gauge,
    static_findings,
)
from gatetwin.validate.isolation import (
    RunRequest,
    RunResult,
    check_timeout,
    run_in_process,
    run_isolated,
    start_host,
)
from gatetwin.validate.mapping import VariableMap
from gatetwin.validate.thresholds import Check, Threshold
from gatetwin.validate.validity import Envelope, ValidityFinding, read_envelope, record_validity

__all__ = [
    "MATRIX_METRICS",
    "RUN_CHECK",
    "VALIDITY_CHECK",
    "WHITENESS_MAX_LAG",
    "FmuValidation",
    "RecordValidation",
    "Trace",
    "flat_metrics",
    "matrix_cells",
    "matrix_markdown",
    "not_finite_cause",
    "prepare_inputs",
    "validate_fmu",
    "validate_matrix",
    "validity_text",
]

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
        The validity envelope the FMU states (:func:`~gatetwin.validate.validity.read_envelope`).
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


@dataclass(frozen=True)
class _Settings:
    """What applies to every record of one FMU."""

    thresholds: tuple[Threshold, ...]
    envelope: Envelope | None
    fail_outside_validity: bool


@dataclass(frozen=True)
class _Inputs:
    """One record made ready for a run: what the FMU gets and what it is compared with."""

    record: Record
    gauge: str
    measured_mm: np.ndarray
    opening_mm: np.ndarray
    grid: CommunicationGrid


def prepare_inputs(fmu: FmuInfo, output: str, record: Record) -> _Inputs:
    """A record's measured level for ``output`` and the FMU's inputs on its communication
    grid; :class:`ValidationError` for a record the FMU cannot be validated on (no such
    gauge, a grid the FMU cannot step)."""
    gauge = output[len("level_") : -len("_mm")]
    measured = _measured_level(record, gauge, fmu)
    where = record.path or "<arrays>"
    try:
        opening = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    except IdentificationError as exc:
        raise ValidationError(f"{where}: {exc}") from None
    try:
        grid = communication_grid(record.time_s, record.sample_period_s)
    except ValidationError as exc:
        raise ValidationError(f"{where}: {exc}") from None
    return _Inputs(record, gauge, measured, opening, grid)


def not_finite_cause(output: str, simulated_mm: np.ndarray, grid: CommunicationGrid) -> str:
    """``output level_3F_mm not finite (nan) at t = 12 s (record sample 10)``, or ""."""
    bad = np.flatnonzero(~np.isfinite(simulated_mm))
    if bad.size == 0:
        return ""
    k = int(bad[0])
    t = grid.start_time_s + float(grid.index[k]) * grid.step_s
    return (f"output {output} not finite ({simulated_mm[k]}) at t = {t:.6g} s "
            f"(record sample {k})")  # fmt: skip


def _validate_record(
    inputs: _Inputs, output: str, run: RunResult, settings: _Settings
) -> RecordValidation:
    record, gauge, measured = inputs.record, inputs.gauge, inputs.measured_mm
    opening = inputs.opening_mm
    failed = run.result is None
    simulated = np.full(record.n_samples, np.nan) if failed else run.result
    cause = run.failure_cause or not_finite_cause(output, simulated, inputs.grid)
    trace = Trace(record.time_s, opening, record.flow_m3h, measured, simulated, record.hold)
    metrics = free_run_metrics(measured, simulated)
    whiteness, note = _whiteness(trace)
    steps = compare_steps(record, gauge, simulated) if not cause else ()
    noise = record_noise_floor(record, gauge)
    floor, level_sd = noise_floor_fit_percent(noise.sigma_mm, measured)
    flat = flat_metrics(metrics, whiteness, steps, floor)
    validity = record_validity(settings.envelope, opening, record.flow_m3h, measured,
                               noise.sigma_mm)  # fmt: skip
    return RecordValidation(
        record=_record_name(record),
        gauge=gauge,
        test=record.test,
        n_samples=record.n_samples,
        n_fmu_steps=inputs.grid.n_steps,
        step_s=inputs.grid.step_s,
        metrics=metrics,
        whiteness=whiteness,
        steps=steps,
        checks=tuple(t.check(flat) for t in settings.thresholds),
        trace=trace,
        whiteness_note=note,
        record_sha256=record.sha256,
        noise=noise,
        noise_floor_fit_percent=floor,
        level_sd_mm=level_sd,
        validity=validity,
        fail_outside_validity=settings.fail_outside_validity,
        failure_cause=cause,
        run_time_s=run.seconds,
    )


def validate_fmu(
    fmu_path: str | Path,
    records: Sequence[str | Path | Record],
    *,
    gauge: str | None = None,
    thresholds: Sequence[Threshold] = (),
    fail_outside_validity: bool = False,
    timeout_s: float | None = None,
    isolate: bool = True,
    variable_map: VariableMap | None = None,
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
        Applied to every record; none means nothing but the static validation and a failed
        run (crash, exit, timeout, output not finite) can fail.
    fail_outside_validity : bool
        Fail a record that lies outside the validity envelope the FMU states (one whose
        ``inside_validity`` is False; unknown is not a failure).
    timeout_s : float, optional
        Wall-clock limit of each record's run, s; default
        :func:`~gatetwin.validate.isolation.default_timeout_s` (10 s + 1 ms per FMU step).
    isolate : bool
        Run the FMU in a child process (default). False runs it in this process, unguarded:
        an FMU that crashes or exits takes this process with it, one that hangs hangs it.
    variable_map : VariableMap, optional
        For an FMU that is not gatetwin's: its variable and unit behind each record column
        (:mod:`gatetwin.validate.mapping`, ``gatetwin validate --map``).

    Returns
    -------
    FmuValidation
        Metrics, noise floors, validity findings, static findings, checks and failure
        causes; ``passed`` says whether anything failed.

    Raises
    ------
    ValidationError
        The FMU cannot be run (see :func:`~gatetwin.validate.fmu_runner.inspect_fmu` and
        :func:`~gatetwin.validate.isolation.run_isolated`), a record lacks the gauge or
        needs more than :data:`~gatetwin.validate.fmu_runner.MAX_FMU_STEPS` FMU steps, the
        timeout is not a positive number.
    RecordError
        A record breaks the data-format contract.
    """
    if not records:
        raise ValidationError("no records to validate against")
    check_timeout(timeout_s)
    if isolate:
        start_host()  # its imports overlap with the reading and checking below
    info = inspect_fmu(fmu_path, variable_map)
    output = output_for_gauge(info, gauge)
    prepared = [prepare_inputs(info, output, _load(r)) for r in records]
    findings = static_findings(info.path)
    envelope = read_envelope(info.path)
    settings = _Settings(tuple(thresholds), envelope, fail_outside_validity)
    requests = [RunRequest(output, p.grid, p.opening_mm, p.record.flow_m3h) for p in prepared]
    runs = run_isolated(info, requests, timeout_s) if isolate else run_in_process(info, requests)
    results = tuple(_validate_record(p, output, run, settings)
                    for p, run in zip(prepared, runs, strict=True))  # fmt: skip
    return FmuValidation(info, findings, tuple(thresholds), results, envelope)


#: Columns of a matrix cell, in table order (besides ``fmu`` and ``record``).
MATRIX_METRICS = ("fit_percent", "r2", "rmse_mm", "mae_mm", "max_abs_error_mm", "bias_mm")

#: Name of the failed check of a record outside the envelope (with ``fail_outside_validity``).
VALIDITY_CHECK = "inside validity"
#: Prefix of the failed check of a record whose FMU run failed (followed by the cause).
RUN_CHECK = "FMU run failed"


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
                "noise_floor_fit_percent": finite_or_none(rec.noise_floor_fit_percent),
                "fit_vs_floor": finite_or_none(rec.fit_vs_floor),
                "noise_sigma_mm": rec.noise_floor_dict()["sigma_mm"],
                "inside_validity": rec.inside_validity,
                "outside_validity": rec.validity.problems() if rec.validity else [],
                "failure_cause": rec.failure_cause or None,
                "static_passed": result.static_passed,
                "failed_checks": _failed_checks(result, rec),
                "passed": result.static_passed and rec.passed,
            }
        )
    return cells


def _failed_checks(result: FmuValidation, rec: RecordValidation) -> list[str]:
    static = [] if result.static_passed else ["fmpy static validation"]
    run = [f"{RUN_CHECK}: {rec.failure_cause}"] if rec.failure_cause else []
    validity = [VALIDITY_CHECK] if rec.validity_failed else []
    return static + run + [c.threshold.text for c in rec.checks if c.failed] + validity


def validate_matrix(
    fmu_paths: Sequence[str | Path],
    record_paths: Sequence[str | Path | Record],
    *,
    thresholds: Sequence[Threshold] = (),
    gauge: str | None = None,
    fail_outside_validity: bool = False,
    timeout_s: float | None = None,
    isolate: bool = True,
) -> list[dict[str, Any]]:
    """Validate every FMU against every record; one flat cell per pair.

    Records are read once. Each cell holds ``fmu`` and ``record`` (file names), ``gauge``,
    ``test``, ``fit_percent``, ``r2``, ``rmse_mm``, ``mae_mm``, ``max_abs_error_mm``,
    ``bias_mm`` (None where not finite), the noise floor's ``noise_floor_fit_percent``,
    ``fit_vs_floor`` (points) and ``noise_sigma_mm``, ``inside_validity`` (True, False or
    None) with ``outside_validity`` (what lies outside, as phrases), ``failure_cause`` (why
    the FMU run failed, None when it did not), ``static_passed``, ``failed_checks`` (the
    passing conditions that failed) and ``passed``. ``timeout_s`` and ``isolate`` as in
    :func:`validate_fmu`, which this raises as.
    """
    records = [_load(r) for r in record_paths]
    cells: list[dict[str, Any]] = []
    for fmu in fmu_paths:
        result = validate_fmu(fmu, records, gauge=gauge, thresholds=thresholds,
                              fail_outside_validity=fail_outside_validity, timeout_s=timeout_s,
                              isolate=isolate)  # fmt: skip
        cells.extend(matrix_cells(result))
    return cells


def _cell_text(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "pass" if value else "**FAIL**"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value).replace("|", "\\|")


def _fit_and_floor(cell: dict[str, Any]) -> str:
    """``fit / floor`` in %, one decimal (– where unknown)."""
    parts = [cell.get("fit_percent"), cell.get("noise_floor_fit_percent")]
    return " / ".join("–" if v is None else f"{v:.1f}" for v in parts)


def validity_text(cell: dict[str, Any]) -> str:
    """A cell's place in the envelope: ``inside``, ``unknown`` or ``outside: <what>``."""
    inside = cell.get("inside_validity")
    if inside is None:
        return "unknown"
    if inside:
        return "inside"
    return "outside: " + ", ".join(cell.get("outside_validity", []))


def matrix_markdown(cells: Sequence[dict[str, Any]]) -> str:
    """The validation matrix as a Markdown table (one row per FMU × record).

    ``fit / floor %`` is the free-run fit next to the noise floor's fit (the best a perfect
    model can expect on that record); ``validity`` says whether the record lies inside the
    envelope the FMU states (``unknown`` when it states none, or not every range).
    """
    header = ["FMU", "record", "gauge", "fit / floor %", "R²", "RMSE (mm)", "MAE (mm)",
              "max abs error (mm)", "bias (mm)", "validity", "result"]  # fmt: skip
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for cell in cells:
        values = [cell["fmu"], cell["record"], cell["gauge"]]
        row = [_cell_text(v) for v in values] + [_fit_and_floor(cell)]
        row += [_cell_text(cell[m]) for m in MATRIX_METRICS[1:]]
        row += [_cell_text(validity_text(cell)), _cell_text(cell["passed"])]
        if cell.get("failed_checks"):
            row[-1] += " (" + "; ".join(cell["failed_checks"]) + ")"
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"
