"""One FMU against many records, one record per task: on a local process pool or on a
``dask.distributed`` cluster (:mod:`gatetwin.fleet.execute`).

Each task carries the FMU's bytes and one read record, so the workers need no shared
folder; it runs :func:`~gatetwin.validation.harness.validate_fmu` on its record, exactly as the
serial run does record by record (each record's run, metrics and checks depend on that
record alone), so the findings are the serial run's. The FMU is inspected, and every record
read, here first: what cannot be validated fails in one line before any work is sent out.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gatetwin.errors import ValidationError
from gatetwin.records import Record, read_record
from gatetwin.validation.fmu_runner import inspect_fmu, output_for_gauge, static_findings
from gatetwin.validation.harness import (
    FmuValidation,
    RecordValidation,
    prepare_inputs,
    validate_fmu,
)
from gatetwin.validation.mapping import VariableMap
from gatetwin.validation.thresholds import Threshold
from gatetwin.validation.validity import read_envelope

if TYPE_CHECKING:
    from gatetwin.fleet.execute import FleetSettings

__all__ = [
    "MatrixTask",
    "RecordTask",
    "validate_fmu_spread",
    "validate_matrices",
    "validate_matrix_task",
    "validate_record_task",
]


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


@contextlib.contextmanager
def _private_fmu(name: str, data: bytes) -> Iterator[Path]:
    """The FMU ``data`` as the file ``name`` in a private folder, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        fmu = Path(tmp) / name
        fmu.write_bytes(data)
        yield fmu


def validate_record_task(task: RecordTask) -> RecordValidation:
    """Validate ``task.record`` against the FMU (written to a private folder first)."""
    with _private_fmu(task.fmu_name, task.fmu_bytes) as fmu:
        result = validate_fmu(fmu, [task.record], gauge=task.gauge, thresholds=task.thresholds,
                              fail_outside_validity=task.fail_outside_validity,
                              timeout_s=task.timeout_s,
                              variable_map=task.variable_map)  # fmt: skip
    return result.records[0]


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
    """:func:`~gatetwin.validation.harness.validate_fmu`, one record per task where
    ``settings`` says (:class:`~gatetwin.fleet.execute.FleetSettings`).

    Raises
    ------
    ValidationError
        As :func:`~gatetwin.validation.harness.validate_fmu`; also a task whose worker was
        lost (the record named).
    RecordError
        A record breaks the data-format contract.
    """
    from gatetwin.fleet.execute import map_tasks

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

    results = map_tasks(validate_record_task, tasks, settings,
                        lambda task: f"{task.record.path or 'a record'}: its validation",
                        report, ValidationError)  # fmt: skip
    return FmuValidation(info, static_findings(info.path), tuple(thresholds), tuple(results),
                         read_envelope(info.path))  # fmt: skip


@dataclass(frozen=True)
class MatrixTask:
    """What a worker needs to validate one FMU against its records: the FMU itself, the
    records' paths (read by the same paths there), the thresholds."""

    fmu_name: str
    fmu_bytes: bytes
    records: tuple[str, ...]
    thresholds: tuple[Threshold, ...]


def validate_matrix_task(task: MatrixTask) -> list[dict[str, Any]]:
    """:func:`~gatetwin.validation.harness.validate_matrix` of the task's FMU (written to a
    private folder first) against its records."""
    from gatetwin.validation.harness import validate_matrix

    with _private_fmu(task.fmu_name, task.fmu_bytes) as fmu:
        return validate_matrix([fmu], list(task.records), thresholds=task.thresholds)


def validate_matrices(
    pairs: Sequence[tuple[str | Path, Sequence[str | Path]]],
    settings: FleetSettings | None,
    *,
    thresholds: Sequence[Threshold] = (),
) -> list[list[dict[str, Any]]]:
    """The matrix cells of every (FMU, records) pair, one FMU per task where ``settings``
    says (``None``: one after another here); in the pairs' order. Each FMU's static
    validation runs once, with its records, as in the serial matrix.

    Raises
    ------
    ValidationError
        As :func:`~gatetwin.validation.harness.validate_matrix`, for the first FMU (in order)
        that failed so, or whose worker was lost.
    """
    from gatetwin.fleet.execute import map_tasks

    tasks = [MatrixTask(Path(fmu).name, Path(fmu).read_bytes(), tuple(map(str, records)),
                        tuple(thresholds)) for fmu, records in pairs]  # fmt: skip
    return map_tasks(validate_matrix_task, tasks, settings,
                     lambda task: f"{task.fmu_name}: its validation",
                     error=ValidationError)  # fmt: skip
