"""``gatetwin models`` over many gates: discover, run one task per gate, write the results.

Output layout under ``out``: one folder per identified gate holding its model files and
``schema.json`` (exactly what ``gatetwin models`` writes for one records folder), its FMUs
under ``<gate>/fmus/`` when asked for, and the fleet summary ``fleet.json``, ``fleet.md``,
``fleet.html`` and ``fleet.png``. Bad input (a source that does not exist, no records) is
refused before anything is written; a gate that fails, or whose folder cannot be written
(read-only, disk full), is reported in the summary and gets no folder (the one an earlier
run into the same ``out`` wrote for it is removed).
"""

from __future__ import annotations

import contextlib
import json
import shutil
from pathlib import Path
from typing import Any

from gatetwin._io import write_bytes_atomic, write_json_atomic, write_text_atomic
from gatetwin.errors import OutputError
from gatetwin.fleet.execute import FleetSettings, Progress
from gatetwin.fleet.gate import GateJob, failed_summary, run_gates
from gatetwin.fleet.sources import discover_gates
from gatetwin.fleet.summary import (
    fleet_document,
    fleet_figure_png,
    fleet_html,
    fleet_markdown,
    summary_paths,
)

__all__ = ["run_fleet", "write_gate_outputs"]


def write_gate_outputs(result: dict[str, Any], out: Path) -> list[Path]:
    """Write one identified gate's model files (and FMUs) into ``out/<gate>/``, and each
    routine history's identification as ``routine_<record>.json``."""
    from gatetwin.modelfile import write_model_files as write_models

    folder = out / result["gate"]
    paths = write_models(result["models"], folder) if result["models"] else []
    for name, doc in sorted(result.get("routine", {}).items()):
        paths.append(write_json_atomic(folder / f"routine_{name}.json", doc))
    for name, data in sorted(result["fmus"].items()):
        paths.append(write_bytes_atomic(folder / "fmus" / f"{name}.fmu", data))
    return paths


def _write_or_fail(result: dict[str, Any], out: Path) -> dict[str, Any]:
    """Write one gate's outputs; a gate whose folder cannot be written (read-only, disk full)
    becomes a failed gate with the reason, and what was written of it is removed (its folder
    too when this run created it), so the summary's other gates still get written."""
    folder = out / result["gate"]
    existed = folder.exists()
    try:
        write_gate_outputs(result, out)
    except OutputError as exc:
        if not existed:
            shutil.rmtree(folder, ignore_errors=True)
        elif folder.is_dir():
            for path in _output_paths(result, folder):
                with contextlib.suppress(OSError):
                    path.unlink(missing_ok=True)
        reason = f"its outputs cannot be written: {' '.join(str(exc).split())}"
        summary = failed_summary(result["gate"], reason, result["summary"]["files"])
        return {**result, "status": "failed", "models": {}, "fmus": {}, "routine": {},
                "summary": summary}  # fmt: skip
    return result


def _output_paths(result: dict[str, Any], folder: Path) -> list[Path]:
    """The files :func:`write_gate_outputs` writes for ``result``."""
    return ([folder / "schema.json", *(folder / f"{n}.json" for n in result["models"])]
            + [folder / f"routine_{n}.json" for n in result.get("routine", {})]
            + [folder / "fmus" / f"{n}.fmu" for n in result["fmus"]])  # fmt: skip


def _gates_written_before(out: Path) -> dict[str, list[str]]:
    """Gates whose folders an earlier fleet run wrote into ``out`` (its ``fleet.json``), with
    the models it wrote for each."""
    try:
        doc = json.loads(summary_paths(out)["json"].read_text(encoding="utf-8"))
        return {g["gate"]: [str(m) for m in g.get("models", [])]
                for g in doc["gates"] if g["status"] == "ok"}  # fmt: skip
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _remove_earlier_outputs(folder: Path, models: list[str]) -> None:
    """Remove what an earlier run wrote into a gate's folder (its models, FMUs, routine
    reports), and the folder when nothing else is left: a file the user put there stays."""
    paths = [folder / "schema.json", *sorted(folder.glob("routine_*.json"))]
    paths += [p for n in models for p in (folder / f"{n}.json", folder / "fmus" / f"{n}.fmu")
              if Path(n).name == n]  # fmt: skip
    for path in paths:
        with contextlib.suppress(OSError, ValueError):  # ValueError: a NUL in a name
            path.unlink(missing_ok=True)
    for empty in (folder / "fmus", folder):
        with contextlib.suppress(OSError):
            empty.rmdir()


def run_fleet(sources: list[str], out: str | Path, settings: FleetSettings, *,
              fmu_backend: str | None = None, max_memory_mib: float | None = None,
              progress: Progress | None = None) -> dict[str, Any]:  # fmt: skip
    """Identify every gate of ``sources`` and write the model sets and the summary.

    Parameters
    ----------
    sources : list of str
        Folders (of records, or of gate folders), glob patterns, record files or manifests
        (see :mod:`gatetwin.fleet.sources`).
    out : str or Path
        Output folder.
    settings : FleetSettings
        Serial, local pool or dask scheduler.
    fmu_backend : str, optional
        ``"c"`` or ``"python"`` to build every model's FMU as well.
    max_memory_mib : float, optional
        Memory budget of a worker reading a routine history chunk by chunk (Parquet files
        and history folders), MiB (see :func:`~gatetwin.fleet.gate.identify_history`).
    progress : callable, optional
        Receives one line per finished gate.

    Returns
    -------
    dict
        The fleet summary (the content of ``fleet.json``).

    Raises
    ------
    GatetwinError
        Sources that name no records (see :func:`~gatetwin.fleet.sources.discover_gates`),
        or a memory budget too small to hold the interpreter; nothing is written then.
    """
    if max_memory_mib is not None:
        from gatetwin.identification.routine_chunks import chunk_rows_for

        chunk_rows_for(max_memory_mib)  # refuses a budget below the libraries' own
    gates = discover_gates(sources)
    out_dir = Path(out)
    if progress:
        progress(f"fleet: {len(gates)} gates, {settings.describe()}")
    jobs = [GateJob(g.gate, g.paths, fmu_backend, max_memory_mib) for g in gates]
    ours = _gates_written_before(out_dir)

    def finished(res: dict[str, Any]) -> dict[str, Any]:
        """Each gate written as it finishes: a run that stops early keeps the gates done."""
        if res["status"] == "ok":
            return _write_or_fail(res, out_dir)
        if res["summary"]["gate"] in ours:
            # what an earlier run into this --out wrote for the gate would stand beside a
            # summary that says the gate failed
            gate = res["summary"]["gate"]
            _remove_earlier_outputs(out_dir / gate, ours[gate])
        return res

    results = run_gates(jobs, settings, progress, finished)
    doc = fleet_document(results, settings.describe())
    paths = summary_paths(out_dir)
    png = fleet_figure_png(doc)
    write_bytes_atomic(paths["figure"], png)
    write_text_atomic(paths["markdown"], fleet_markdown(doc))
    write_text_atomic(paths["html"], fleet_html(doc, png))
    write_json_atomic(paths["json"], doc)
    return doc
