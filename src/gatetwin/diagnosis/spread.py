"""Many records diagnosed one record per task: on a local process pool or a dask cluster
(:mod:`gatetwin.fleet.execute`).

Each task runs :func:`~gatetwin.diagnosis.workflow.diagnose_record` on its record exactly as
the serial run does (each diagnosis depends on its record and model file alone), writing
its figure, augmented model file and FMUs into a private temporary folder; their bytes come
back with the findings and are written here, under the names the serial run gives them,
so the workers read the records and model files but never share an output folder.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gatetwin._io import write_bytes_atomic
from gatetwin.diagnosis.workflow import DiagnosisSettings, diagnose_record

if TYPE_CHECKING:
    from gatetwin.fleet.execute import FleetSettings

__all__ = ["DiagnoseTask", "diagnose_records", "diagnose_task"]

#: Sub-folders of a task's private folder: the figure, the FMUs and augmented model file.
_PLOTS, _FMUS = "plots", "fmus"


@dataclass(frozen=True)
class DiagnoseTask:
    """One record to diagnose: where it is, its baseline, where its outputs go here."""

    record: str
    model: str | None
    plots_dir: str | None
    fmu_dir: str | None
    settings: DiagnosisSettings


def diagnose_task(task: DiagnoseTask) -> tuple[dict[str, Any], dict[str, bytes]]:
    """Diagnose ``task.record``; the findings (paths as they will be written here) and the
    bytes of every file written, by those paths."""
    with tempfile.TemporaryDirectory(prefix="gatetwin-diagnose-") as tmp:
        places = {_PLOTS: task.plots_dir, _FMUS: task.fmu_dir}
        private = {k: Path(tmp) / k if v is not None else None for k, v in places.items()}
        result = diagnose_record(task.record, task.model, plots_dir=private[_PLOTS],
                                 fmu_dir=private[_FMUS], settings=task.settings)  # fmt: skip
        files: dict[str, bytes] = {}
        for key, folder in private.items():
            if folder is None or not folder.is_dir():
                continue
            for path in sorted(folder.rglob("*")):
                if path.is_file():
                    target = Path(str(places[key])) / path.relative_to(folder)
                    files[str(target)] = path.read_bytes()
        return _moved(result, tmp, places), files


def _moved(value: Any, tmp: str, places: dict[str, str | None]) -> Any:
    """``value`` with every path under the private folder ``tmp`` renamed to its place."""
    if isinstance(value, dict):
        return {k: _moved(v, tmp, places) for k, v in value.items()}
    if isinstance(value, list):
        return [_moved(v, tmp, places) for v in value]
    if isinstance(value, str) and value.startswith(tmp + "/"):
        key, _, rest = value[len(tmp) + 1 :].partition("/")
        return str(Path(str(places[key])) / rest)
    return value


def diagnose_records(
    tasks: Sequence[DiagnoseTask],
    settings: FleetSettings | None,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """:func:`~gatetwin.diagnosis.workflow.diagnose_record` of every task, one record per task
    where ``settings`` says (``None``: one after another here); the findings in the tasks'
    order, the files written.

    Raises
    ------
    GatetwinError
        The first task (in order) that was refused (its own one-line message) or that did
        not come back from its worker; nothing is written then.
    """
    from gatetwin.fleet.execute import map_tasks

    def report(done: int, total: int, result: Any) -> None:
        if progress and isinstance(result, tuple):
            progress(f"diagnose: [{done}/{total}] {result[0]['record']}")

    results = map_tasks(diagnose_task, tasks, settings,
                        lambda task: f"{task.record}: its diagnosis", report)  # fmt: skip
    for _, files in results:
        for path, data in files.items():
            write_bytes_atomic(Path(path), data)
    return [findings for findings, _ in results]
