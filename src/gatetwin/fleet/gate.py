"""One gate's task: identify its model set (and optionally its FMUs) and summarise it.

:func:`identify_gate` is what a pool process or a dask worker runs, one call per gate. It
takes and returns plain picklable data and never raises: a gate whose records are refused
or whose identification fails comes back with ``status: failed`` and the one-line reason,
so that one bad gate never stops the fleet. It writes nothing: the model documents (and
FMU bytes) travel back to the caller, which writes them, so workers need to read the
records but never to share an output folder.
"""

from __future__ import annotations

import json
import tempfile
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gatetwin.errors import GatetwinError
from gatetwin.fleet.execute import FleetSettings, Progress, run_tasks

__all__ = [
    "FAMILIES",
    "GateJob",
    "failed_summary",
    "gate_summary",
    "identify_gate",
    "identify_histories",
    "identify_history",
    "is_routine_history",
    "routine_summary",
    "run_gates",
]

#: Model-file families, by the prefix of the model name.
FAMILIES = ("fopdt", "physical", "arx")


@dataclass(frozen=True)
class GateJob:
    """What one task does.

    Attributes
    ----------
    gate : str
        Gate name.
    paths : tuple[str, ...]
        The gate's records (CSV and Parquet files, history folders of day files) and its
        static table, as the worker sees them.
    fmu_backend : str | None
        ``"c"`` or ``"python"`` to also build one FMU per model; ``None`` for none.
    max_memory_mib : float | None
        Memory budget of a routine history read chunk by chunk (Parquet files and history
        folders), MiB; ``None`` for the default chunk of
        :data:`~gatetwin.identification.routine_chunks.DEFAULT_CHUNK_ROWS` rows.
    """

    gate: str
    paths: tuple[str, ...]
    fmu_backend: str | None = None
    max_memory_mib: float | None = None


def identify_gate(job: GateJob) -> dict[str, Any]:
    """Identify one gate; a plain dict with ``gate``, ``status``, ``models``, ``fmus``,
    ``routine``, ``summary`` and ``seconds`` (never raises for a bad gate).

    Records whose sidecar says ``test: "routine"`` are routine operation histories: each
    gives its FOPDT from :func:`~gatetwin.identification.routine.identify_routine` (``routine``:
    the identification documents by record name; see :func:`identify_history`). A gate of
    histories only, none with an informative window, has ``status`` ``no_window``; the
    other records build the model set as designed tests do.
    """
    start = time.perf_counter()
    models: dict[str, dict[str, Any]] = {}
    fmus: dict[str, bytes] = {}
    routine: dict[str, dict[str, Any]] = {}
    histories = tuple(p for p in job.paths if is_routine_history(p))
    tests = [Path(p) for p in job.paths if p not in histories]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            routine = identify_histories(histories, job.max_memory_mib)
            if tests:
                ident = _identify_tests(tests, job.gate)
                models = ident.models
                if job.fmu_backend:
                    fmus = _export_fmus(models, job.fmu_backend)
                summary = gate_summary(job.gate, ident, _messages(caught))
            else:
                summary = routine_summary(job.gate, routine, _messages(caught))
            summary["routine"] = {name: _routine_entry(doc) for name, doc in routine.items()}
            summary["samples"] += sum(int(d["n_samples"]) for d in routine.values())
        except GatetwinError as exc:
            summary = failed_summary(job.gate, str(exc), len(job.paths))
        except Exception as exc:  # one gate's crash is reported, not fatal
            summary = failed_summary(job.gate, f"{type(exc).__name__}: {exc}", len(job.paths))
    ok = summary["status"] == "ok"
    return {"gate": job.gate, "status": summary["status"], "models": models if ok else {},
            "fmus": fmus if ok else {}, "routine": routine if ok else {}, "summary": summary,
            "seconds": time.perf_counter() - start}  # fmt: skip


def _identify_tests(paths: list[Path], gate: str) -> Any:
    from gatetwin.identification.suite import identify_records

    return identify_records(paths, f"gate {gate}")


def is_routine_history(path: str) -> bool:
    """Whether the record's sidecar says ``test: "routine"`` (read from the sidecar alone)."""
    try:
        data = json.loads(Path(path).with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(data, dict) and data.get("test") == "routine"


def identify_histories(
    paths: tuple[str, ...], max_memory_mib: float | None = None
) -> dict[str, dict[str, Any]]:
    """Each routine history's identification document by record name (the file or
    folder name without its suffix), see :func:`identify_history`.

    Raises
    ------
    GatetwinError
        A history that cannot be read, or two histories of the gate with the same name (the
        gate fails: bad input, not a lack of moves).
    """
    out: dict[str, dict[str, Any]] = {}
    seen: dict[str, str] = {}
    for path in paths:
        name = Path(path).stem
        if name in seen:
            raise GatetwinError(f"{path}: a second routine history named {name!r} (the first: "
                                f"{seen[name]}); keep one of them")  # fmt: skip
        seen[name] = path
        out[name] = identify_history(path, max_memory_mib)
    return out


def identify_history(path: str, max_memory_mib: float | None = None) -> dict[str, Any]:
    """One routine history's identification document, with the history's ``n_samples``; a
    history without an informative window gives ``{"test": "routine", "record": PATH,
    "no_window": REASON}``.

    A Parquet file or a folder of day files is read chunk by chunk, as ``gatetwin routine
    --max-memory`` reads it (:mod:`gatetwin.identification.routine_chunks`; the same result as
    the whole history), with chunks sized for ``max_memory_mib`` MiB when given; a CSV
    file is read whole (a single CSV cannot be read in parts).

    Raises
    ------
    GatetwinError
        The history cannot be read.
    """
    from gatetwin.errors import NoWindowError
    from gatetwin.identification.routine import identify_routine
    from gatetwin.identification.routine_chunks import (
        DEFAULT_CHUNK_ROWS,
        chunk_rows_for,
        scan_routine_history,
    )
    from gatetwin.records import read_record
    from gatetwin.records.parquet import PARQUET_SUFFIXES

    where = Path(path)
    if where.is_dir() or where.suffix.lower() in PARQUET_SUFFIXES:
        rows = DEFAULT_CHUNK_ROWS if max_memory_mib is None else chunk_rows_for(max_memory_mib)
        scan = scan_routine_history(path, chunk_rows=rows)
        if scan.identification is None:
            return _no_window(path, scan.no_window, scan.n_rows)
        return {**scan.identification.to_dict(), "n_samples": scan.n_rows}
    record = read_record(path, test="routine")
    try:
        doc = identify_routine(record).to_dict()
    except NoWindowError as exc:
        return _no_window(path, str(exc), record.n_samples)
    return {**doc, "n_samples": record.n_samples}


def _no_window(path: str, reason: str, n_samples: int) -> dict[str, Any]:
    return {"test": "routine", "record": path, "no_window": " ".join(reason.split()),
            "n_samples": n_samples}  # fmt: skip


def _routine_entry(doc: dict[str, Any]) -> dict[str, Any]:
    """A history's line in the fleet summary: its FOPDT (overall medians) or why none."""
    if "no_window" in doc:
        return {"n_windows": 0, "no_window": doc["no_window"]}
    o = doc["overall"]
    return {"n_moves": doc["n_moves"], "n_windows": doc["n_windows"],
            "n_closed_loop_windows": doc["n_closed_loop_windows"],
            "gain_mm_per_mm": o["gain_mm_per_mm"], "time_constant_s": o["time_constant_s"],
            "dead_time_s": o["dead_time_s"],
            "flow_m3h": [o["flow_min_m3h"], o["flow_max_m3h"]]}  # fmt: skip


def routine_summary(gate: str, routine: dict[str, dict[str, Any]],
                    messages: list[str]) -> dict[str, Any]:  # fmt: skip
    """The summary entry of a gate of routine histories only: ``ok`` with its FOPDT from the
    histories' windows, else ``no_window`` with every history's reason."""
    found = [d for d in routine.values() if "no_window" not in d]
    status = "ok" if found else "no_window"
    error = "" if found else "; ".join(d["no_window"] for d in routine.values())
    warns = list(messages) + [w for d in found for w in d["warnings"]]
    return {
        "gate": gate, "status": status, "error": error, "files": len(routine),
        "records": sorted(routine), "samples": 0,
        "families": ["fopdt"] if found else [], "models": [],
        "fopdt_source": "routine" if found else "", "validity": {}, "held_out": {},
        "warnings": warns,
    }  # fmt: skip


def _messages(caught: list[warnings.WarningMessage]) -> list[str]:
    seen: dict[str, None] = {}
    for w in caught:
        seen[f"{w.category.__name__}: {' '.join(str(w.message).split())}"] = None
    return list(seen)


def failed_summary(gate: str, error: str, n_files: int) -> dict[str, Any]:
    """The summary entry of a gate that produced no model set."""
    return {"gate": gate, "status": "failed", "error": " ".join(error.split()),
            "files": n_files, "records": [], "samples": 0, "families": [], "models": [],
            "validity": {}, "held_out": {}, "warnings": [], "routine": {}}  # fmt: skip


def _held_out(name: str, doc: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Free-run fit of ``doc`` on each held-out record: fit %, RMSE mm."""
    held = doc.get("provenance", {}).get("metrics", {}).get("held_out", {})
    out = {}
    for rec, entry in sorted(held.items()):
        free = entry.get("free_run", entry) if name.startswith("fopdt") else entry
        if "fit_percent" in free:
            out[rec] = {"fit_percent": round(float(free["fit_percent"]), 2),
                        "rmse_mm": round(float(free["rmse_mm"]), 3)}  # fmt: skip
    return out


def _validity(doc: dict[str, Any]) -> dict[str, list[float]]:
    v = doc.get("validity", {})
    keys = {"flow_m3h": "flow_m3h", "opening_range_mm": "opening_mm",
            "level_range_mm": "level_mm"}  # fmt: skip
    return {short: [float(x) for x in v[k]] for k, short in keys.items() if k in v}


def gate_summary(gate: str, ident: Any, messages: list[str]) -> dict[str, Any]:
    """The summary entry of an identified gate (see :func:`~gatetwin.fleet.summary`)."""
    models = ident.models
    samples = sum(int(r.n_samples) for r in ident.records.values())
    samples += int(ident.static.n_points) if ident.static is not None else 0
    held = {name: _held_out(name, doc) for name, doc in sorted(models.items())}
    warns = list(messages)
    warns += [f"{name} not identified ({' '.join(why.split())}); the others are written"
              for name, why in sorted(ident.not_identified.items())]  # fmt: skip
    if not any(held.values()):
        warns.append("no held-out record: the model set is not checked on unseen data")
    return {
        "gate": gate, "status": "ok", "error": "",
        "files": len(ident.records) + (1 if ident.static is not None else 0),
        "records": sorted(ident.records), "samples": samples,
        "families": [f for f in FAMILIES if any(n.startswith(f + "_") for n in models)],
        "fopdt_source": "step tests" if any(n.startswith("fopdt_") for n in models) else "",
        "models": sorted(models),
        "validity": {n: _validity(d) for n, d in sorted(models.items())},
        "held_out": held,
        "warnings": warns,
    }  # fmt: skip


def _export_fmus(models: dict[str, dict[str, Any]], backend: str) -> dict[str, bytes]:
    """One FMU per model document, built in a private temporary folder, as bytes."""
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.modelfile import read_model_file
    from gatetwin.modelfile import write_model_files as write_models

    out: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory(prefix="gatetwin-fleet-") as tmp:
        folder = Path(tmp)
        write_models(models, folder)
        for name in sorted(models):
            model = read_model_file(folder / f"{name}.json")
            path = export_fmu(
                model.plant,
                folder / f"{name}.fmu",
                backend=backend,
                model_name=model.name,
                provenance=fmu_provenance(model),
            )
            out[name] = path.read_bytes()
    return out


def _crashed(job: GateJob, exc: BaseException) -> dict[str, Any]:
    """The result of a task whose process died or could not run it."""
    reason = f"task failed ({type(exc).__name__}: {exc})"
    return {
        "gate": job.gate,
        "status": "failed",
        "models": {},
        "fmus": {},
        "routine": {},
        "summary": failed_summary(job.gate, reason, len(job.paths)),
        "seconds": 0.0,
    }


def run_gates(jobs: Iterable[GateJob], settings: FleetSettings,
              progress: Progress | None = None,
              finished: Callable[[dict[str, Any]], dict[str, Any]] | None = None,
              ) -> list[dict[str, Any]]:  # fmt: skip
    """Run every job; the results (see :func:`identify_gate`) sorted by gate name.
    ``finished`` sees each result as its gate finishes (to write it then) and returns the
    result kept."""
    kept: dict[str, dict[str, Any]] = {}

    def report(k: int, n: int, res: dict[str, Any]) -> None:
        res = kept[res["gate"]] = finished(res) if finished else res
        if progress:
            progress(_progress_line(k, n, res))

    results = run_tasks(identify_gate, jobs, settings, _crashed, report)
    return sorted((kept.get(r["gate"], r) for r in results), key=lambda r: r["gate"])


def _progress_line(k: int, n: int, res: dict[str, Any]) -> str:
    head = f"fleet: [{k}/{n}] {res['gate']}"
    if res["status"] == "no_window":
        return f"{head} no informative window: {res['summary']['error']}"
    if res["status"] != "ok":
        return f"{head} FAILED: {res['summary']['error']}"
    histories = f", routine histories: {len(res['routine'])}" if res.get("routine") else ""
    return f"{head} ok, {len(res['models'])} models{histories} in {res['seconds']:.1f} s"
