"""Validate an FMU against measured records: simulate freely, compare, apply thresholds.

:func:`validate_fmu` drives one FMU (through fmpy) with the measured inputs of each record
and compares its output with the measured level; :func:`validate_matrix` does it for every
FMU × record pair and returns flat cells; :func:`matrix_markdown` renders them.

Inputs given to the FMU, per sample of the record:

* the gate opening as logged on ``hold`` samples; while the actuator moves (``open``
  samples, opening empty or untrusted) the opening is interpolated linearly *in time*
  between the last hold opening and the next
  (:func:`gatetwin.identification.reconstructed_opening`):
  the actuator is taken to move at a roughly constant speed;
* the measured discharge.

Both are held over the communication step to the next sample (zero-order hold); across a
logging gap the FMU makes several steps with the last logged inputs (see
:func:`~gatetwin.validation.fmu_runner.communication_grid`). The FMU's output is never
corrected by a measurement: it is a free-run (simulation) test, much harder than the
one-step-ahead R² of the reference study.

Besides the metrics, every record gets

* its **noise floor**: the level noise SD from its steady holds
  (:func:`gatetwin.noise.record_noise_floor`) and the fit % a perfect model would score
  against that noise (:func:`~gatetwin.validation.compare.noise_floor_fit_percent`);
  ``fit_vs_floor`` is the fit minus that floor, in percentage points;
* its place in the FMU's **validity envelope** (:mod:`gatetwin.validation.validity`), read from
  the FMU's own ``resources/provenance.json``: ``inside_validity`` True, False or None
  (unknown).

Each record's run happens in a child process (:mod:`gatetwin.validation.isolation`) under a
wall-clock limit: an FMU that crashes, exits, hangs or outputs NaN or infinity fails that
record, with the cause in ``failure_cause``, whatever the thresholds; the other records and
the report go on. A record whose grid would need more than
:data:`~gatetwin.validation.fmu_runner.MAX_FMU_STEPS` FMU steps is refused before any FMU runs.

Results are findings; whether they fail is decided by the thresholds the caller passes
(and by ``failure_cause``). Their types live in :mod:`gatetwin.validation.results`, the matrix's
cells and table in :mod:`gatetwin.validation.matrix`; the public names of both are importable
from here too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError, ValidationError
from gatetwin.identification import reconstructed_opening, residual_whiteness
from gatetwin.identification.metrics import Whiteness
from gatetwin.noise import record_noise_floor
from gatetwin.records import Record, read_record
from gatetwin.validation.compare import compare_steps, free_run_metrics, noise_floor_fit_percent
from gatetwin.validation.fmu_runner import (
    CommunicationGrid,
    FmuInfo,
    communication_grid,
    inspect_fmu,
    output_for_gauge,
    static_findings,
)
from gatetwin.validation.isolation import (
    RunRequest,
    RunResult,
    check_timeout,
    run_in_process,
    run_isolated,
    start_host,
)
from gatetwin.validation.mapping import VariableMap
from gatetwin.validation.matrix import (
    MATRIX_METRICS,
    RUN_CHECK,
    VALIDITY_CHECK,
    matrix_cells,
    matrix_markdown,
    validity_text,
)
from gatetwin.validation.results import FmuValidation, RecordValidation, Trace, flat_metrics
from gatetwin.validation.thresholds import Threshold
from gatetwin.validation.validity import Envelope, read_envelope, record_validity

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
        unobserved_steps=int(record.unobserved_steps),
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
        :func:`~gatetwin.validation.isolation.default_timeout_s` (10 s + 1 ms per FMU step).
    isolate : bool
        Run the FMU in a child process (default). False runs it in this process, unguarded:
        an FMU that crashes or exits takes this process with it, one that hangs hangs it.
    variable_map : VariableMap, optional
        For an FMU that is not gatetwin's: its variable and unit behind each record column
        (:mod:`gatetwin.validation.mapping`, ``gatetwin validate --map``).

    Returns
    -------
    FmuValidation
        Metrics, noise floors, validity findings, static findings, checks and failure
        causes; ``passed`` says whether anything failed.

    Raises
    ------
    ValidationError
        The FMU cannot be run (see :func:`~gatetwin.validation.fmu_runner.inspect_fmu` and
        :func:`~gatetwin.validation.isolation.run_isolated`), a record lacks the gauge or
        needs more than :data:`~gatetwin.validation.fmu_runner.MAX_FMU_STEPS` FMU steps, the
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
