"""One FMU against many records, one record per task: on a local process pool or on a
``dask.distributed`` cluster (:mod:`gatetwin.fleet.execute`).

Each task carries the FMU's bytes and one read record, so the workers need no shared
folder; it runs :func:`~gatetwin.validate.harness.validate_fmu` on its record, exactly as the
serial run does record by record (each record's run, metrics and checks depend on that
record alone), so the findings are the serial run's. The FMU is inspected, and every record
read, here first: what cannot be validated fails in one line before any work is sent out.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gatetwin.errors import GatetwinError
from gatetwin.records import Record, read_record
from gatetwin.validate.errors import ValidationError
from gatetwin.validate.fmu_runner import inspect_fmu, output_for_gauge, static_findings
from gatetwin.validate.harness import (
    FmuValidation,
    RecordValidation,
    prepare_inputs,
    validate_fmu,
)
from gatetwin.validate.mapping import VariableMap
from gatetwin.validate.thresholds import Threshold
from gatetwin.validate.validity import read_envelope

if TYPE_CHECKING:
    from gatetwin.fleet.execute import FleetSettings


@dataclass(frozen=True)
class RecordTask:
    """What a worker needs to validate one record: the FMU itself, the record, the settings."""

    fmu_name: str
    fmu_bytes: bytes
    record: Record
    gauge: str | None
    thresholds: tuple[Threshold, ...]
    fail_outside_validity: bool
    timeout_s: float | None
    variable_map: VariableMap | None = None


def validate_record_task(task: RecordTask) -> RecordValidation:
    """Validate ``task.record`` against the FMU (written to a private folder first)."""
    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        fmu = Path(tmp) / task.fmu_name
        fmu.write_bytes(task.fmu_bytes)
        result = validate_fmu(fmu, [task.record], gauge=task.gauge, thresholds=task.thresholds,
                              fail_outside_validity=task.fail_outside_validity,
                              timeout_s=task.timeout_s,
                              variable_map=task.variable_map)  # fmt: skip
    return result.records[0]


def _lost(task: RecordTask, exc: BaseException) -> BaseException:
    """A task that raised or did not come back: kept as the exception, raised once all are
    in."""
    del task
    return exc


def validate_fmu_spread(
    fmu_path: str | Path,
    records: Sequence[str | Path | Record],
    settings: FleetSettings,
    *,
    gauge: str | None = None,
    thresholds: Sequence[Threshold] = (),
    fail_outside_validity: bool = False,
    timeout_s: float | None = None,
    progress: Callable[[str], None] | None = None,
    variable_map: VariableMap | None = None,
) -> FmuValidation:
    """:func:`~gatetwin.validate.harness.validate_fmu`, one record per task where
    ``settings`` says (:class:`~gatetwin.fleet.execute.FleetSettings`).

    Raises
    ------
    ValidationError
        As :func:`~gatetwin.validate.harness.validate_fmu`; also a task whose worker was
        lost (the record named).
    RecordError
        A record breaks the data-format contract.
    """
    from gatetwin.fleet.execute import run_tasks

    if not records:
        raise ValidationError("no records to validate against")
    info = inspect_fmu(fmu_path, variable_map)
    output = output_for_gauge(info, gauge)
    loaded = [r if isinstance(r, Record) else read_record(r) for r in records]
    for rec in loaded:  # each record's gauge and grid, as validate_fmu checks them, first
        prepare_inputs(info, output, rec)
    data = Path(fmu_path).read_bytes()
    tasks = [RecordTask(Path(fmu_path).name, data, rec, gauge, tuple(thresholds),
                        fail_outside_validity, timeout_s, variable_map)
             for rec in loaded]  # fmt: skip

    def report(done: int, total: int, result: Any) -> None:
        if progress and isinstance(result, RecordValidation):
            progress(f"validate: [{done}/{total}] {result.record}")

    results = run_tasks(validate_record_task, tasks, settings, _lost, report)
    for task, result in zip(tasks, results, strict=True):
        if isinstance(result, GatetwinError):  # the record's own one-line refusal
            raise result
        if isinstance(result, BaseException):
            text = " ".join(str(result).split()) or type(result).__name__
            raise ValidationError(f"{task.record.path or 'a record'}: its validation did not "
                                  f"come back from the worker ({text})")  # fmt: skip
    return FmuValidation(info, static_findings(info.path), tuple(thresholds), tuple(results),
                         read_envelope(info.path))  # fmt: skip
