"""The ``gatetwin run`` pipeline: a list of stages run in order on one context.

Each stage is a plain function ``stage(ctx) -> None`` that reads what earlier stages left
in ``ctx.results`` and adds its own; extend the pipeline by appending a
:class:`PipelineStage` to :data:`STAGES`. Neighbouring stages of one ``group`` need nothing
from each other: on a local pool they run at the same time, their tasks sharing its
processes (the validation, the MPC demo and the diagnosis fill the pool together where one by
one each left a process idle at its end).

Outputs are written into a temporary sibling of the output directory, which is renamed into
place only when every stage has succeeded:
a failed run leaves no partial output, and an existing output directory is replaced only
after success and only if it is still the run's own (:mod:`gatetwin.run.outdir`).

This module orchestrates; checking, identification and so on live in their own modules.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.bundled import bundled_records_dir
from gatetwin.errors import PipelineError
from gatetwin.fleet.execute import shared_pool, stop_shared_pools
from gatetwin.records import detect_table_kind, read_record, read_static_table
from gatetwin.run import stages as _stages
from gatetwin.run.outdir import (
    MARKER,
    RUN_PID_FILE,
    check_replaceable,
    clean_stale_work,
    make_work_dir,
    make_world_readable,
    replace_output,
)

__all__ = [
    "MARKER",
    "STAGES",
    "PipelineContext",
    "PipelineStage",
    "check_records",
    "export_fmus",
    "export_model_fmus",
    "find_records",
    "identify_models",
    "run_pipeline",
    "stage_times_markdown",
    "tables_and_figures",
    "write_record_summary",
    "write_summary",
]


@dataclass
class PipelineContext:
    """What the stages share (deliberately mutable: stages fill ``results``).

    Attributes
    ----------
    out_dir : Path
        Directory to write into (a temporary directory until the run succeeds).
    records_dir : Path
        Where the input records are read from.
    records : list[Path]
        The input files found (records and static tables).
    results : dict
        Stage outputs by name, e.g. ``results["records"]``: summaries of the checked
        records.
    progress : callable
        Takes one line of progress text.
    fleet : FleetSettings or None
        Where the stages' independent pieces run, one per task (each gauge's models, each
        model's FMUs, each FMU's validation, each plant of the MPC demo, each record's
        diagnosis): a local process pool or a dask scheduler; ``None`` for one after another
        here. The outputs do not depend on it.
    stage : int
        Number of the stage running (from 1): where its summary sections go.
    """

    out_dir: Path
    records_dir: Path
    records: list[Path] = field(default_factory=list)
    results: dict[str, Any] = field(default_factory=dict)
    progress: Callable[[str], None] = print
    fleet: Any = None
    stage: int = 0

    def add_section(self, markdown: str) -> None:
        """A section of ``summary.md`` from the running stage: sections follow the stages'
        order, whichever stage of a group finished first."""
        self.results.setdefault("summary_sections", []).append((self.stage, markdown))


@dataclass(frozen=True)
class PipelineStage:
    """One stage: a title for the progress line and the function that runs it; ``group``,
    when not empty, the neighbouring stages it may run at the same time as (they share
    ``results``, and each reads only what stages before the group left there)."""

    title: str
    run: Callable[[PipelineContext], None]
    group: str = ""


# --------------------------------------------------------------------------- stages


def find_records(ctx: PipelineContext) -> None:
    """Collect the ``*.csv`` files of ``ctx.records_dir``."""
    found = sorted(ctx.records_dir.glob("*.csv")) if ctx.records_dir.is_dir() else []
    if not found:
        raise PipelineError(
            f"{ctx.records_dir}: no records found; expected NAME.csv files "
            "(time-series records or static tables)"
        )
    ctx.records = found
    ctx.progress(f"      found {len(found)} file(s) in {ctx.records_dir}")


def check_records(ctx: PipelineContext) -> None:
    """Read and check every input; results["records"] gets their summaries."""
    summaries = []
    for path in ctx.records:
        if detect_table_kind(path) == "static":
            summary = read_static_table(path).summary()
        else:
            summary = read_record(path).summary()
        summary["file"] = path.name
        summaries.append(summary)
        ctx.progress(f"      {path.name}: ok ({summary['kind']})")
    ctx.results["records"] = summaries


def write_record_summary(ctx: PipelineContext) -> None:
    """Write ``records.json`` and ``summary.md`` (a table of the checked records)."""
    from gatetwin._io import write_json_atomic, write_text_atomic

    summaries = ctx.results["records"]
    write_json_atomic(ctx.out_dir / "records.json", summaries)
    write_text_atomic(ctx.out_dir / "summary.md", _summary_markdown(summaries))


def _summary_markdown(summaries: Sequence[dict[str, Any]]) -> str:
    lines = [
        "# gatetwin run",
        "",
        "## Records checked",
        "",
        "| file | kind | test | samples / points | gauges | steps | flow (m³/h) |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in summaries:
        gauges = " ".join(g["name"] for g in s["gauges"])
        flow = s["flow_m3h"]
        if s["kind"] == "static":
            row = (s["file"], "static", "–", s["n_points"], gauges, "–")
        else:
            test = f"{s['test']} ({s['test_source']})"
            row = (s["file"], "record", test, s["n_samples"], gauges, len(s["steps"]))
        cells = [*map(str, row), f"{flow['min']:.4g} … {flow['max']:.4g}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def identify_models(ctx: PipelineContext) -> None:
    """Identify every record; write ``models/*.json`` (and the schema)."""
    from gatetwin.identification.suite import identify_folder
    from gatetwin.modelfile import write_model_files

    ident = identify_folder(ctx.records_dir, ctx.progress, ctx.fleet)
    if ident.not_identified:  # the later stages compare and control every family
        name, why = next(iter(sorted(ident.not_identified.items())))
        raise PipelineError(f"{ctx.records_dir}: {name} not identified ({' '.join(why.split())})"
                            "; gatetwin run needs every model family")  # fmt: skip
    ctx.results["ident"] = ident
    written = write_model_files(ident.models, ctx.out_dir / "models")
    ctx.results["model_paths"] = [p for p in written if p.name != "schema.json"]
    ctx.progress(f"      {len(ident.models)} model(s): {', '.join(sorted(ident.models))}")


#: Where ``gatetwin run`` puts each kind of FMU: (folder under fmus/, backend, FMI version).
FMU_KINDS = (("c", "c", "2.0"), ("python", "python", "2.0"), ("fmi3", "c", "3.0"))


def export_fmus(ctx: PipelineContext) -> None:
    """Export every model with both backends, ``fmus/c/NAME.fmu`` and
    ``fmus/python/NAME.fmu`` (FMI 2.0), and as FMI 3.0, ``fmus/fmi3/NAME.fmu`` (C); the C FMUs
    for every platform when Zig's C compiler is installed (else the host's)."""
    from gatetwin._io import write_bytes_atomic
    from gatetwin.fleet.execute import map_tasks
    from gatetwin.fmu.platforms import platforms_of, zig_available

    if zig_available():
        platforms = "all"
        for version in ("2.0", "3.0"):
            ctx.progress(f"      C FMUs (FMI {version}) carry binaries for "
                         f"{', '.join(platforms_of(version))} (Zig's C compiler)")  # fmt: skip
    else:
        platforms = "host"
        ctx.progress("      C FMUs carry the host's binary only: pip install 'gatetwin[cross]' "
                     "adds Windows, macOS and 64-bit ARM")  # fmt: skip
    paths = ctx.results["model_paths"]
    for path in paths:
        ctx.progress(f"      exporting {path.stem} (C and python, FMI 2.0; C, FMI 3.0)")
    built = map_tasks(export_model_fmus, [(str(p), platforms) for p in paths], ctx.fleet,
                      lambda job: f"{Path(job[0]).stem}: its export")  # fmt: skip
    fmus: dict[str, list[Path]] = {folder: [] for folder, _, _ in FMU_KINDS}
    for path, files in zip(paths, built, strict=True):
        for folder, data in files.items():
            out = ctx.out_dir / "fmus" / folder / f"{path.stem}.fmu"
            write_bytes_atomic(out, data)
            fmus[folder].append(out)
    ctx.results["fmus"] = fmus
    _cross_checks(ctx, fmus["c"])


def export_model_fmus(job: tuple[str, str]) -> dict[str, bytes]:
    """The FMUs of one model file (a task): each of :data:`FMU_KINDS` by its folder, the C
    ones for ``platforms`` (``"all"`` or ``"host"``), built in a private folder."""
    import tempfile

    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.c_build import Builds
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.modelfile import read_model_file

    path, platforms = job
    model = read_model_file(path)
    files = {}
    builds: Builds = {}  # one binary serves both FMI versions
    with tempfile.TemporaryDirectory(prefix="gatetwin-export-") as tmp:
        for folder, backend, version in FMU_KINDS:
            out = Path(tmp) / folder / f"{model.name}.fmu"
            export_fmu(model.plant, out, backend=backend, model_name=model.name,
                       provenance=fmu_provenance(model), fmi_version=version,
                       platforms=platforms if backend == "c" else "host",
                       builds=builds)  # fmt: skip
            files[folder] = out.read_bytes()
    return files


#: The record whose inputs drive the run's cross-check packages (gate moves and inflow steps).
CROSS_CHECK_RECORD = "Eboth.csv"


def _cross_checks(ctx: PipelineContext, c_fmus: list[Path]) -> None:
    """``crosscheck/<model>/``: each C FMU's FMI cross-check package, on the records folder's
    Eboth record when it has one."""
    from gatetwin.fmu.crosscheck import write_cross_check
    from gatetwin.modelfile import read_model_file

    source = ctx.records_dir / CROSS_CHECK_RECORD
    if not source.is_file():
        ctx.progress(f"      no {CROSS_CHECK_RECORD} among the records: no cross-check packages")
        return
    record = read_record(source)
    for path, fmu in zip(ctx.results["model_paths"], c_fmus, strict=True):
        model = read_model_file(path)
        if model.plant.gauge in record.levels_mm:
            write_cross_check(model, fmu, record, ctx.out_dir / "crosscheck" / model.name)
    ctx.progress(f"      cross-check packages in crosscheck/ ({CROSS_CHECK_RECORD}'s inputs)")


def tables_and_figures(ctx: PipelineContext) -> None:
    """Published-vs-ours tables (``tables.md``) and the figures (``figures/*.png``)."""
    from gatetwin._io import write_text_atomic
    from gatetwin.run.figures import write_all
    from gatetwin.run.tables import all_tables

    ident = ctx.results["ident"]
    tables = all_tables(ident)
    ctx.results["tables"] = tables
    write_text_atomic(ctx.out_dir / "tables.md", "\n".join(t.markdown() for t in tables))
    ctx.results["figures"] = write_all(ident, ctx.out_dir / "figures")
    ctx.progress(f"      {len(tables)} table(s), {len(ctx.results['figures'])} figure(s)")


def write_summary(ctx: PipelineContext) -> None:
    """``summary.md``: records, published-vs-ours tables, and what later stages found."""
    from gatetwin._io import write_text_atomic
    from gatetwin.run.tables import worst_deviation

    parts = [_summary_markdown(ctx.results["records"])]
    ident = ctx.results.get("ident")
    if ident is not None and {"A", "B"} <= set(ident.steps):
        worst = worst_deviation(ident)
        parts.append(
            "## Published vs ours\n\nLargest deviation over the five gauges of A and B "
            f"(paper's method): levels {worst['level_mm']} mm, K {worst['K_percent']} %, "
            f"L {worst['L_s']} s, T {worst['T_percent']} %.\n"
        )
    parts += [t.markdown() for t in ctx.results.get("tables", [])]
    sections = sorted(ctx.results.get("summary_sections", []), key=lambda part: part[0])
    parts += [markdown for _, markdown in sections]
    write_text_atomic(ctx.out_dir / "summary.md", "\n".join(parts))


#: The stages of ``gatetwin run``, in order. Append to extend the pipeline.
STAGES: tuple[PipelineStage, ...] = (
    PipelineStage("finding records", find_records),
    PipelineStage("checking records", check_records),
    PipelineStage("writing the record summary", write_record_summary),
    PipelineStage("identifying models", identify_models),
    PipelineStage("exporting FMUs (C and python; FMI 2.0 and 3.0)", export_fmus),
    PipelineStage("tables and figures", tables_and_figures),
    PipelineStage(
        "validating every FMU against every record (fmpy)", _stages.validate_all, "checks"
    ),
    PipelineStage(
        "comparing the model families on every record", _stages.compare_families, "checks"
    ),
    PipelineStage("MPC demo against PI (FMU and flume in the loop)", _stages.mpc_demo, "checks"),
    PipelineStage("diagnosing the bundled records", _stages.diagnose_records, "checks"),
    # after the MPC demo, whose mpc.json it adds its result to; alone, as it runs the SSP in
    # this process beside its tasks
    PipelineStage("controller FMUs and the closed loop as an SSP", _stages.closed_loop_artefacts),
    PipelineStage("writing summary.md", write_summary),
    PipelineStage("writing report.html", _stages.write_report),
)


# --------------------------------------------------------------------------- running


def run_pipeline(
    out_dir: str | os.PathLike[str],
    progress: Callable[[str], None] | None = None,
    *,
    stages: Sequence[PipelineStage] = STAGES,
    records_dir: str | os.PathLike[str] | None = None,
    fleet: Any = None,
) -> Path:
    """Run ``stages`` and move their output to ``out_dir`` only if all succeed.

    Parameters
    ----------
    out_dir : path
        Output directory. An existing one is replaced after success, provided it was
        written by an earlier run (or is empty) -- checked at the start and again at the
        moment it is replaced (see :func:`replace_output`).
    progress : callable, optional
        Receives progress lines such as ``"[2/3] checking records ..."``.
    stages : sequence of PipelineStage, optional
        The stages to run (default :data:`STAGES`).
    records_dir : path, optional
        Input directory (default: the bundled records, :func:`bundled_records_dir`).
    fleet : FleetSettings, optional
        Run the stages' independent pieces as tasks on a local process pool or a dask
        scheduler (:class:`~gatetwin.fleet.execute.FleetSettings`, see
        :class:`PipelineContext`); the outputs are those of the default, one after another
        in this process.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    GatetwinError
        From any stage, or :class:`~gatetwin.errors.PipelineError` if ``out_dir`` cannot
        be written or (re)placed. Nothing is left behind on failure, except this run's
        output kept in a named sibling folder when ``out_dir`` changed hands meanwhile.
    """
    target = Path(out_dir).resolve()
    say = progress or (lambda _line: None)
    owner = check_replaceable(target)
    inputs = Path(records_dir) if records_dir is not None else bundled_records_dir()
    clean_stale_work(target, say)
    work = make_work_dir(target)
    try:
        ctx = PipelineContext(out_dir=work, records_dir=inputs, progress=say, fleet=fleet)
        start = time.perf_counter()
        with shared_pool(fleet):
            times = _run_stages(ctx, stages, say)
        overlapped = any(len(b) > 1 for b in _batches(list(enumerate(stages, 1)),
                                                      _pooled(fleet)))  # fmt: skip
        _write_stage_times(work, times, time.perf_counter() - start if overlapped else None, say)
        (work / MARKER).write_text("written by gatetwin run\n", encoding="utf-8")
        (work / RUN_PID_FILE).unlink()
        make_world_readable(work)
        replace_output(work, target, owner)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return target


def _run_stages(ctx: PipelineContext, stages: Sequence[PipelineStage],
                say: Callable[[str], None]) -> list[tuple[str, float]]:  # fmt: skip
    """Run ``stages`` in order, a group's together where the run has a local pool; each
    one's title and wall-clock time, s."""
    times: list[tuple[str, float]] = []
    for batch in _batches(list(enumerate(stages, 1)), _pooled(ctx.fleet)):
        if len(batch) == 1:
            number, stage = batch[0]
            say(f"[{number}/{len(stages)}] {stage.title} ...")
            ctx.stage = number
            times.append((stage.title, _timed(stage, ctx)))
        else:
            times += _run_together(ctx, batch, len(stages), say)
    return times


def _pooled(fleet: Any) -> bool:
    """Whether the run's tasks go to a local pool of two or more processes (where a group's
    stages run together; serially or on dask they run one after another)."""
    return fleet is not None and not fleet.scheduler and fleet.workers > 1


def _batches(numbered: list[tuple[int, PipelineStage]], together: bool
             ) -> list[list[tuple[int, PipelineStage]]]:  # fmt: skip
    """The stages in runs: neighbours of one group together when ``together``, else one by
    one."""
    batches: list[list[tuple[int, PipelineStage]]] = []
    for number, stage in numbered:
        last = batches[-1][-1][1] if batches else None
        if together and stage.group and last is not None and last.group == stage.group:
            batches[-1].append((number, stage))
        else:
            batches.append([(number, stage)])
    return batches


def _timed(stage: PipelineStage, ctx: PipelineContext) -> float:
    start = time.perf_counter()
    stage.run(ctx)
    return time.perf_counter() - start


def _run_together(ctx: PipelineContext, batch: list[tuple[int, PipelineStage]], total: int,
                  say: Callable[[str], None]) -> list[tuple[str, float]]:  # fmt: skip
    """The stages of ``batch`` at the same time, each in a thread (their tasks share the
    pool) with a context of its own that shares ``results``. Each stage's progress is
    printed once the stages before it have ended (the first one's as it comes): the lines are
    those of a run one after another. The first error in the stages' order is raised once
    every stage of the batch has ended; an interrupt stops the pool's waiting tasks and waits
    for the stages to end before it goes on (so that nothing writes into the output being
    removed)."""
    relays = [_Relay(say, f"[{number}/{total}] {stage.title} ...") for number, stage in batch]
    relays[0].open()
    threads = ThreadPoolExecutor(max_workers=len(batch))
    futures = [threads.submit(_timed, stage, dataclasses.replace(ctx, stage=number,
                                                                progress=relay))
               for (number, stage), relay in zip(batch, relays, strict=True)]  # fmt: skip
    try:
        for future, after in zip(futures, [*relays[1:], None], strict=True):
            wait([future])
            if after is not None:
                after.open()
    except BaseException:
        stop_shared_pools()
        wait(futures)
        raise
    finally:
        threads.shutdown(wait=True)
    for future in futures:
        if (error := future.exception()) is not None:
            raise error
    return [
        (stage.title, future.result()) for (_, stage), future in zip(batch, futures, strict=True)
    ]


class _Relay:
    """A grouped stage's progress lines: held (after its header) until :meth:`open`, then
    printed as they come."""

    def __init__(self, say: Callable[[str], None], header: str) -> None:
        self.say, self.held, self.live = say, [header], False
        self.lock = threading.Lock()

    def __call__(self, line: str) -> None:
        with self.lock:
            if self.live:
                self.say(line)
            else:
                self.held.append(line)

    def open(self) -> None:
        with self.lock:
            for line in self.held:
                self.say(line)
            self.held, self.live = [], True


def stage_times_markdown(times: Sequence[tuple[str, float]], total_s: float | None = None
                         ) -> str:  # fmt: skip
    """The "Stage times" section: one row per stage, wall-clock seconds, and the total: the
    run's own ``total_s`` when stages ran at the same time (their rows overlap), else their
    sum."""
    overlap = (" Stages of a group ran at the same time: their rows overlap, and the total is "
               "the run's own." if total_s is not None else "")  # fmt: skip
    lines = ["## Stage times", "", "Wall-clock seconds of each stage on the machine that ran "
             f"it (they vary from run to run; every other output does not).{overlap}", "",
             "| stage | time (s) |", "|---|---|"]  # fmt: skip
    lines += [f"| {title} | {seconds:.1f} |" for title, seconds in times]
    total = sum(s for _, s in times) if total_s is None else total_s
    lines.append(f"| total | {total:.1f} |")
    return "\n".join(lines) + "\n"


def _write_stage_times(work: Path, times: Sequence[tuple[str, float]], total_s: float | None,
                       say: Callable[[str], None]) -> None:  # fmt: skip
    """Print the stage times and the total (``total_s``, the run's own, where stages ran at
    the same time; else their sum), and append them to ``summary.md`` when a stage wrote
    one."""
    width = max((len(title) for title, _ in times), default=0)
    say("stage times (s):")
    for title, seconds in times:
        say(f"      {title:<{width}}  {seconds:6.1f}")
    total = sum(s for _, s in times) if total_s is None else total_s
    say(f"      {'total':<{width}}  {total:6.1f}")
    summary = work / "summary.md"
    if summary.is_file():
        text = summary.read_text(encoding="utf-8")
        summary.write_text(text + "\n" + stage_times_markdown(times, total_s), encoding="utf-8")
