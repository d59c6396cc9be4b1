"""Later stages of ``gatetwin run``: validation matrix and the HTML report.

Each stage is a plain ``stage(ctx)`` on the pipeline's context (see
:mod:`gatetwin.run.pipeline`); the work itself lives in the stage's own package.
"""

from __future__ import annotations

import os
from typing import Any

__all__ = [
    "CONTROLLER_KINDS",
    "DIAGNOSE",
    "DIAGNOSE_HEADER",
    "FAMILY_GAUGE",
    "FAMILY_NAMES",
    "FLOOR_NOTE",
    "FLOW_MEDIAN_SAMPLES",
    "MATRIX_FAIL_UNDER",
    "MATRIX_TITLES",
    "MPC_COLUMNS",
    "MPC_CONTROLLERS",
    "MPC_HEADER",
    "MPC_MINUTES",
    "MPC_PLANTS",
    "ONE_FLOW_SPREAD_M3H",
    "applicable_pairs",
    "closed_loop_artefacts",
    "closed_loop_fmu_task",
    "compare_families",
    "diagnose_records",
    "mpc_demo",
    "mpc_demo_task",
    "mpc_table",
    "not_diagnosed",
    "operating_points",
    "validate_all",
    "write_report",
]

#: The run's pass criterion for the validation matrix: a free-running linear model of a
#: nonlinear gate on noisy data. Gauge noise (SD up to ~2.4 mm after a step) caps a perfect
#: model near 94 % on a step record; 70 % leaves room for the linearisation over a 5–10 mm
#: opening change and the rating relation's ~3 mm level error, and still fails a model
#: with a wrong gain sign, a doubled time constant or a mis-scheduled operating point.
MATRIX_FAIL_UNDER = ("fit_percent=70",)


def validate_all(ctx: Any) -> None:
    """Validate every exported FMU against every bundled record; ``validation.json``."""
    from gatetwin._io import write_json_atomic
    from gatetwin.validation import matrix_markdown, parse_thresholds
    from gatetwin.validation.spread import validate_matrices

    thresholds = parse_thresholds(MATRIX_FAIL_UNDER)
    pairs, outside = applicable_pairs(ctx)
    n_pairs = sum(len(v) for v in pairs.values())
    jobs = [(backend, fmu) for backend, fmus in ctx.results["fmus"].items() for fmu in fmus]
    for backend in ctx.results["fmus"]:
        ctx.progress(f"      {backend}: {n_pairs} applicable FMU × record pair(s)")
    found = validate_matrices(
        [(fmu, [ctx.records_dir / f"{r}.csv" for r in pairs[fmu.stem]]) for _, fmu in jobs],
        ctx.fleet, thresholds=thresholds)  # fmt: skip
    cells: list[dict[str, Any]] = []
    for (backend, _), fmu_cells in zip(jobs, found, strict=True):
        for cell in fmu_cells:
            cells.append({"backend": backend, **cell})
            if cell["failure_cause"]:
                ctx.progress(f"      {backend} {cell['fmu']} on {cell['record']}: FMU run "
                             f"failed: {cell['failure_cause']}")  # fmt: skip
    ctx.results["validation"] = cells
    write_json_atomic(ctx.out_dir / "validation.json", {
        "thresholds": list(MATRIX_FAIL_UNDER), "matrix": cells, "outside_validity": outside,
    })  # fmt: skip
    n_pass = sum(bool(c["passed"]) for c in cells)
    n_out = sum(c["inside_validity"] is False for c in cells)
    ctx.progress(f"      {n_pass} of {len(cells)} cells pass {', '.join(MATRIX_FAIL_UNDER)}; "
                 f"{n_out} outside the FMU's stated validity")  # fmt: skip
    c_cells = [c for c in cells if c["backend"] == "c"]
    skipped = "\n".join(f"- {o['model']} × {o['record']}: {o['reason']}" for o in outside)
    ctx.add_section(
        "## Validation matrix (C FMUs; the python and FMI 3.0 FMUs give the same numbers)\n\n"
        f"Criterion: {', '.join(MATRIX_FAIL_UNDER)}; {n_pass} of {len(cells)} cells pass "
        f"over the {len(ctx.results['fmus'])} FMU sets ({', '.join(ctx.results['fmus'])}). "
        f"{FLOOR_NOTE}\n\n"
        + matrix_markdown(c_cells)
        + "\nOutside a model's validity (not validated):\n\n"
        + skipped
        + "\n"
    )


#: What the fit / floor pair and the validity column of the matrix mean.
FLOOR_NOTE = (
    "Fit / floor: the free-run fit next to the fit a perfect model would score against the "
    "record's own level noise (its noise floor, estimated from the steady holds). Validity: "
    "whether the record lies inside the opening, flow and level ranges the FMU states; "
    "unknown when the FMU does not state all three."
)


#: Column titles of the report's validation matrix that differ from the cells' keys.
MATRIX_TITLES = {"noise_floor_fit_percent": "noise floor fit %",
                 "fit_vs_floor": "fit − floor (points)"}  # fmt: skip


#: Gauge of the per-record comparison of the model families in ``gatetwin run``.
FAMILY_GAUGE = "3F"
FAMILY_NAMES = ["local FOPDT", "envelope FOPDT", "physical"]


def compare_families(ctx: Any) -> None:
    """``families.json``: per record, the local FOPDT against the envelope FOPDT and the
    physical model of gauge 3F (fit, RMSE, bias, noise floor); a summary and report table."""
    from gatetwin._io import write_json_atomic
    from gatetwin.modelfile import read_model_file
    from gatetwin.validation.families import families_markdown, family_row, local_form

    models = [read_model_file(p) for p in ctx.results["model_paths"]]
    by_name = {m.name: m.plant for m in models}
    envelope = by_name[f"fopdt_{FAMILY_GAUGE}"]
    physical = by_name[f"physical_{FAMILY_GAUGE}"]
    plants = dict(zip(FAMILY_NAMES, (local_form(envelope), envelope, physical), strict=True))
    ident = ctx.results["ident"]
    rows = [family_row(rec, plants, FAMILY_GAUGE) for _, rec in sorted(ident.records.items())
            if FAMILY_GAUGE in rec.levels_mm]  # fmt: skip
    ctx.results["families"] = rows
    write_json_atomic(ctx.out_dir / "families.json", {"gauge": FAMILY_GAUGE, "rows": rows})
    ctx.progress(f"      {len(rows)} records × {len(plants)} families at gauge {FAMILY_GAUGE}")
    ctx.add_section(
        f"## Model families per record (gauge {FAMILY_GAUGE}, free run)\n\n"
        + families_markdown(rows, FAMILY_NAMES)
    )


def applicable_pairs(ctx: Any) -> tuple[dict[str, list[str]], list[dict[str, str]]]:
    """Records each model applies to (validity range and opening band), and the others.

    A record is checked at each of its :func:`operating_points`; the reason of the first
    one outside the model's validity goes to ``outside_validity``.
    """
    from gatetwin.modelfile import read_model_file

    ident = ctx.results["ident"]
    pairs: dict[str, list[str]] = {}
    outside: list[dict[str, str]] = []
    points = {name: operating_points(rec) for name, rec in ident.records.items()}
    for path in ctx.results["model_paths"]:
        model = read_model_file(path)
        pairs[model.name] = []
        for name in sorted(ident.records):
            ok, why = _applies(model.content, points[name])
            if ok:
                pairs[model.name].append(name)
            else:
                outside.append({"model": model.name, "record": name, "reason": why})
    return pairs, outside


def _applies(content: dict[str, Any], points: list[tuple[float, Any]]) -> tuple[bool, str]:
    """The first operating point outside the model's validity (with its Q if several)."""
    from gatetwin.modelfile import applies_to

    for flow_m3h, openings_mm in points:
        ok, why = applies_to(content, flow_m3h, openings_mm)
        if not ok:
            return False, why if len(points) == 1 else f"at Q {flow_m3h:.1f} m³/h: {why}"
    return True, "within validity"


#: Samples of the running median that takes the flow meter's noise (0.16 % of reading) out
#: of the discharge before a record's held discharges are read (30 s at 1.2 s).
FLOW_MEDIAN_SAMPLES = 25
#: Spread of the held discharge below which a record is at one discharge, m³/h (the flow
#: meter's accuracy, as in :func:`gatetwin.modelfile.applies_to`).
ONE_FLOW_SPREAD_M3H = 1.0


def operating_points(rec: Any) -> list[tuple[float, Any]]:
    """(discharge m³/h, hold openings mm) pairs at which a model must hold for ``rec``.

    A record held at one discharge (spread of the running median of
    :data:`FLOW_MEDIAN_SAMPLES` samples within :data:`ONE_FLOW_SPREAD_M3H`) gives one
    point: its mean hold discharge and all its hold openings. Otherwise each hold segment
    gives its openings at the lowest and at the highest discharge held during it, so a
    record whose discharge changes is checked over every discharge it visits, not at its
    mean (the operating opening of a model rises with Q, so the farthest an opening gets
    from it over a segment is at one of the two).
    """
    import numpy as np
    from scipy.ndimage import median_filter

    flow = np.asarray(rec.flow_m3h, dtype=float)
    ok = np.isfinite(flow)
    smooth = median_filter(np.interp(rec.time_s, rec.time_s[ok], flow[ok]),
                           size=FLOW_MEDIAN_SAMPLES, mode="nearest")  # fmt: skip
    held = smooth[rec.hold]
    if held.size == 0 or np.ptp(held) <= ONE_FLOW_SPREAD_M3H:
        return [(float(np.nanmean(flow[rec.hold])), rec.opening_mm[rec.hold])]
    points = []
    for seg in rec.holds:
        q = smooth[seg.slice]
        points += [(float(np.min(q)), rec.opening_mm[seg.slice]),
                   (float(np.max(q)), rec.opening_mm[seg.slice])]  # fmt: skip
    return points


#: Plants the MPC demo closes the loop on in ``gatetwin run`` (both, 30 minutes each).
MPC_PLANTS = ("fmu", "flume")
MPC_MINUTES = 30.0


def mpc_demo(ctx: Any) -> None:
    """MPC against PI on the exported FOPDT (3F) and on the flume: ``mpc.json``."""
    from gatetwin._io import write_bytes_atomic, write_json_atomic
    from gatetwin.fleet.execute import map_tasks
    from gatetwin.modelfile import read_model_file

    model_path = ctx.out_dir / "models" / "fopdt_3F.json"
    model = read_model_file(model_path)
    scenarios: dict[str, Any] = {}
    runs: dict[str, Any] = {}
    envelope: dict[str, Any] = {}
    for kind in MPC_PLANTS:
        ctx.progress(f"      {kind}: {MPC_MINUTES:g} simulated minutes per scenario")
    # the exported C FMU of the model is the fmu plant (not exported again, when there is one)
    fmu = next((str(p) for p in ctx.results.get("fmus", {}).get("c", [])
                if p.stem == model.name), None)  # fmt: skip
    jobs = [(str(model_path), kind, fmu if kind == "fmu" else None) for kind in MPC_PLANTS]
    found = map_tasks(mpc_demo_task, jobs, ctx.fleet,
                      lambda job: f"the MPC demo on the {job[1]}")  # fmt: skip
    for kind, (result, plots) in zip(MPC_PLANTS, found, strict=True):
        for name, data in plots.items():
            write_bytes_atomic(ctx.out_dir / "figures" / f"mpc_{kind}" / name, data)
        runs[kind] = {k: v for k, v in result.items() if k != "scenarios"}
        for name, pair in result["scenarios"].items():
            scenarios[f"{kind}_{name}"] = {**pair, "plant": kind}
        for name, row in result["envelope_vs_single_point"].items():
            envelope[f"{kind}_{name}"] = row
    doc = {"model": model.name, "minutes": MPC_MINUTES, "runs": runs, "scenarios": scenarios,
           "envelope_vs_single_point": envelope}  # fmt: skip
    write_json_atomic(ctx.out_dir / "mpc.json", doc)
    ctx.results["mpc"] = doc
    ctx.add_section(_mpc_markdown(doc))


def mpc_demo_task(job: tuple[str, str, str | None]
                  ) -> tuple[dict[str, Any], dict[str, bytes]]:  # fmt: skip
    """The MPC demo of a model file on one kind of plant (a task), with the model's C FMU as
    the fmu plant when one is given: its result and its plots (file name: bytes), drawn in
    a private folder."""
    import tempfile
    from pathlib import Path

    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc import run_mpc_demo

    path, kind, fmu = job
    with tempfile.TemporaryDirectory(prefix="gatetwin-mpc-") as tmp:
        result = run_mpc_demo(read_model_file(path).plant, plant_kind=kind,
                              minutes=MPC_MINUTES, out_plots_dir=tmp, plant_fmu=fmu)  # fmt: skip
        return result, {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir())}


#: Controller FMUs ``gatetwin run`` builds for the MPC demo's model (``controllers/``).
CONTROLLER_KINDS = ("pi", "mpc")


def closed_loop_artefacts(ctx: Any) -> None:
    """``controllers/<model>_<kind>.fmu`` and ``observers/<model>_observer.fmu`` for the MPC
    demo's model (the MPC and the observer on its FOPDT without the effect blocks they do not
    cover), ``observers/physical_<G>_observer.fmu`` (the envelope observer of the same gauge's
    physical model, its blocks dropped) and ``observers/physical_<G>_observer_gauges.fmu``
    (the same with the run's other gauges as references of the gauge-drift rule), and
    ``loop.ssp`` (plant FMU + PI FMU, the demo's
    set-point scenario), run by gatetwin's SSP master next to the Python loop it packs; both
    IAEs go into ``mpc.json`` (``closed_loop_ssp``)."""
    from pathlib import Path

    from gatetwin._io import write_bytes_atomic, write_json_atomic
    from gatetwin.fleet.execute import map_tasks
    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc.demo import DemoSettings, demo_scenarios
    from gatetwin.mpc.loop import loop_metrics
    from gatetwin.ssp import simulate_ssp, write_ssp
    from gatetwin.ssp.reference import python_loop

    models = ctx.out_dir / "models"
    fopdt, physical = (models / f"{k}_{FAMILY_GAUGE}.json" for k in ("fopdt", "physical"))
    model = read_model_file(fopdt)
    references = sorted(path.stem.removeprefix("physical_")
                        for path in models.glob("physical_*.json")
                        if path != physical)  # fmt: skip
    jobs = [(str(fopdt), f"controllers/{fopdt.stem}_{kind}.fmu",
             {"controller": kind, "without_effects": kind == "mpc"})
            for kind in CONTROLLER_KINDS]  # fmt: skip
    jobs += [(str(fopdt), f"observers/{fopdt.stem}_observer.fmu", {"without_effects": True}),
             (str(physical), f"observers/{physical.stem}_observer.fmu", {"without_effects": True}),
             (str(physical), f"observers/{physical.stem}_observer_gauges.fmu",
              {"without_effects": True, "reference_gauges": references})]  # fmt: skip
    built = map_tasks(closed_loop_fmu_task, jobs, ctx.fleet, lambda job: f"{job[1]}: its export")
    for (_, name, _), data in zip(jobs, built, strict=True):
        write_bytes_atomic(ctx.out_dir / name, data)
    ctx.progress(f"      controllers/, observers/: {', '.join(Path(j[1]).name for j in jobs)}")
    settings = DemoSettings()
    scenario = demo_scenarios(MPC_MINUTES, settings)[0]
    package = write_ssp(model, ctx.out_dir / "loop.ssp", controller="pi", scenario=scenario,
                        settings=settings)  # fmt: skip
    run = simulate_ssp(package, out_csv=ctx.out_dir / "loop.csv")
    level = f"controller.level_{model.plant.gauge}_mm"
    iae_ssp = run.iae(level, "controller.setpoint_mm")
    reference = python_loop(package, model.plant, scenario, settings)
    iae_python = loop_metrics(reference)["iae"]
    doc = ctx.results["mpc"]
    doc["closed_loop_ssp"] = {
        "package": "loop.ssp", "result": "loop.csv", "model": model.name, "controller": "pi",
        "scenario": scenario.name, "minutes": MPC_MINUTES, "noise": False,
        "iae_ssp": iae_ssp, "iae_python_loop": iae_python,
        "max_abs_level_difference_mm": float(abs(run.columns[level] - reference.level_mm).max()),
    }  # fmt: skip
    write_json_atomic(ctx.out_dir / "mpc.json", doc)
    ctx.progress(f"      loop.ssp ({scenario.name}, PI, noise-free): IAE {iae_ssp:.1f} mm·s by "
                 f"the SSP master, {iae_python:.1f} mm·s by the Python loop")  # fmt: skip


def closed_loop_fmu_task(job: tuple[str, str, dict[str, Any]]) -> bytes:
    """One controller or observer FMU of a model file (a task), built in a private folder:
    ``(model file, name, options)``, a controller where the options name its kind, else
    the observer with those options; the FMU's bytes."""
    import tempfile
    from pathlib import Path

    from gatetwin.fmu.controller import export_controller
    from gatetwin.fmu.observer_fmu import export_observer
    from gatetwin.modelfile import read_model_file

    path, name, options = job
    model = read_model_file(path)
    with tempfile.TemporaryDirectory(prefix="gatetwin-export-") as tmp:
        out = Path(tmp) / Path(name).name
        if "controller" in options:
            options = dict(options)
            export_controller(model, options.pop("controller"), out, **options)
        else:
            export_observer(model, out, **options)
        return out.read_bytes()


MPC_COLUMNS = ("iae", "max_dev_mm", "settling_s", "travel_mm", "violations",
               "gate_reversals_per_hour", "solve_ms_median", "solve_ms_p99")  # fmt: skip
#: The MPC table's column titles: scenario, controller, then ``MPC_COLUMNS``.
MPC_HEADER = ("scenario", "controller", "IAE (mm·s)", "max dev (mm)", "settling (s)",
              "travel (mm)", "violations", "reversals per hour", "solve median (ms)",
              "solve p99 (ms)")  # fmt: skip


#: Controllers of the MPC demo, as the tables name them.
MPC_CONTROLLERS = {"mpc": "MPC", "mpc_envelope": "MPC (envelope)", "pi": "PI"}


def _mpc_rows(doc: dict[str, Any]) -> list[list[str]]:
    rows = []
    for name, pair in doc["scenarios"].items():
        for ctrl in (c for c in MPC_CONTROLLERS if c in pair):
            m = pair[ctrl]
            cells = [name, MPC_CONTROLLERS[ctrl]]
            for key in MPC_COLUMNS:
                v = m.get(key)
                v = v.get("total", v) if isinstance(v, dict) else v
                cells.append("–" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v))
            rows.append(cells)
    return rows


def mpc_table(doc: dict[str, Any]) -> str:
    """The MPC demo's table (one row per scenario and controller) from ``mpc.json``; the
    docs render its MPC results with it too."""
    lines = ["| " + " | ".join(MPC_HEADER) + " |", "|" + "---|" * len(MPC_HEADER)]
    lines += ["| " + " | ".join(r) + " |" for r in _mpc_rows(doc)]
    return "\n".join(lines) + "\n"


def _mpc_markdown(doc: dict[str, Any]) -> str:
    lines = ["## MPC demo", "", f"Model {doc['model']}, {doc['minutes']:g} simulated minutes "
             "per scenario, control period 1.2 s.", "", mpc_table(doc).rstrip("\n")]  # fmt: skip
    envelope = doc.get("envelope_vs_single_point", {})
    if envelope:
        lines += ["", "Envelope MPC (re-linearised at each sample) against the single-point "
                  "MPC, same scenario:", "",
                  "| scenario | IAE single-point (mm·s) | IAE envelope (mm·s) | ratio | "
                  "violations single-point / envelope |", "|---|---|---|---|---|"]  # fmt: skip
        for name, row in envelope.items():
            ratio = "–" if row["iae_ratio"] is None else f"{row['iae_ratio']:.3f}"
            lines.append(f"| {name} | {row['iae_mpc']:.0f} | {row['iae_mpc_envelope']:.0f} | "
                         f"{ratio} | {row['violations_mpc']} / "
                         f"{row['violations_mpc_envelope']} |")  # fmt: skip
    return "\n".join(lines) + "\n"


#: Records ``gatetwin run`` diagnoses, each against the baseline identified from the record
#: itself (FOPDT for steps, ARX for PRBS) — and D, C also against the step tests' scheduled
#: FOPDT (does the model the step tests see miss something at the PRBS openings?).
DIAGNOSE = (("A", None), ("B", None), ("C", None), ("D", None), ("Q55", None),
            ("C", "fopdt_3F"), ("D", "fopdt_3F"))  # fmt: skip


def diagnose_records(ctx: Any) -> None:
    """Diagnose the bundled records: ``diagnose.json``, augmented models and their FMUs
    (one record per task where ``ctx.fleet`` says; the same outputs)."""
    from gatetwin._io import write_json_atomic
    from gatetwin.diagnosis import DiagnosisSettings
    from gatetwin.diagnosis.spread import DiagnoseTask, diagnose_records

    plots = str(ctx.out_dir / "figures" / "diagnose")
    chosen = [(r, m) for r, m in DIAGNOSE if (ctx.records_dir / f"{r}.csv").exists()]
    tasks = [DiagnoseTask(str(ctx.records_dir / f"{r}.csv"),
                          str(ctx.out_dir / "models" / f"{m}.json") if m else None, plots,
                          str(ctx.out_dir / "diagnose" / f"{r}_{m or 'own'}"),
                          DiagnosisSettings()) for r, m in chosen]  # fmt: skip
    found = _output_relative(diagnose_records(tasks, ctx.fleet), ctx.out_dir)
    results = []
    for (record, model), res in zip(chosen, found, strict=True):
        results.append({**res, "record": record,
                        "baseline_source": model or "identified from the record"})  # fmt: skip
        before, after = res["rmse_before_mm"], res["rmse_after_mm"]
        ctx.progress(f"      {record} vs {model or 'own baseline'}: {res['named_effect']} "
                     f"(RMSE {before:.2f} → {after:.2f} mm)")  # fmt: skip
    skipped = not_diagnosed(ctx)
    for s in skipped:
        ctx.progress(f"      {s['record']}: not diagnosed ({s['reason']})")
    write_json_atomic(ctx.out_dir / "diagnose.json",
                      {"diagnoses": results, "not_diagnosed": skipped})  # fmt: skip
    ctx.results["diagnose"] = results
    ctx.add_section(_diagnose_markdown(results))


def _output_relative(value: Any, out_dir: Any) -> Any:
    """``value`` with every path under ``out_dir`` (the run's work folder, renamed at the
    end) written relative to the output folder, in strings nested in dicts and lists."""
    if isinstance(value, str):
        return value.replace(f"{out_dir}{os.sep}", "")
    if isinstance(value, dict):
        return {k: _output_relative(v, out_dir) for k, v in value.items()}
    if isinstance(value, list):
        return [_output_relative(v, out_dir) for v in value]
    return value


def not_diagnosed(ctx: Any) -> list[dict[str, str]]:
    """The records of the folder that :data:`DIAGNOSE` leaves out, each with why.

    Validation records (several moves, discharge changes, or no move at all) are only
    validated against; the other fitted step tests repeat what A, B and Q55 show.
    """
    from gatetwin.identification.suite import role_of
    from gatetwin.records.sidecar import VALIDATION_ROLE

    ident = ctx.results.get("ident")
    listed = {record for record, _ in DIAGNOSE}
    out = []
    for name, rec in sorted(ident.records.items() if ident is not None else ()):
        if name in listed:
            continue
        why = (
            "validation record: only validated against, in the validation matrix"
            if role_of(rec) == VALIDATION_ROLE
            else "not in the run's diagnosis list"
        )
        out.append({"record": name, "reason": why})
    return out


def _diagnose_rows(results: list[dict[str, Any]]) -> list[list[str]]:
    rows = []
    for r in results:
        best = next((c for c in r["candidates"] if c["effect"] == r["named_effect"]), None)
        params = ", ".join(f"{k} {v:.3g}" for k, v in (best or {}).get("params", {}).items()
                           if isinstance(v, (int, float)))  # fmt: skip
        rows.append([r["record"], r["baseline_source"], r["named_effect"], params or "–",
                     f"{r['rmse_before_mm']:.2f}", f"{r['rmse_after_mm']:.2f}",
                     str(len(r.get("windows", []))), _control_cell(r.get("control"))])  # fmt: skip
    return rows


def _control_cell(control: dict[str, Any] | None) -> str:
    """``IAE augmented / blind`` of the closed-loop check, or why there is none."""
    if not control:
        return "–"
    if "error" in control:
        return f"not run: {control['error']}"
    return f"{control['augmented_mpc']['iae']:.1f} / {control['blind_mpc']['iae']:.1f}"


DIAGNOSE_HEADER = ("record", "baseline", "named effect", "parameters", "RMSE before (mm)",
                   "RMSE after (mm)", "windows above noise",
                   "MPC IAE augmented / blind (mm·s)")  # fmt: skip


def _diagnose_markdown(results: list[dict[str, Any]]) -> str:
    lines = ["## Diagnosis", "", "| " + " | ".join(DIAGNOSE_HEADER) + " |",
             "|" + "---|" * len(DIAGNOSE_HEADER)]  # fmt: skip
    lines += ["| " + " | ".join(r) + " |" for r in _diagnose_rows(results)]
    return "\n".join(lines) + "\n"


def _families_section(ctx: Any, report: Any) -> None:
    from gatetwin.report import Table

    rows = ctx.results.get("families")
    if not rows:
        return
    header = ("record", "floor fit %", *(f"{n}: fit % / RMSE / bias (mm)" for n in FAMILY_NAMES))
    body = tuple((r["record"], f"{r['noise_floor_fit_percent']:.1f}",
                  *(f"{r[n]['fit_percent']:.1f} / {r[n]['rmse_mm']:.1f} / {r[n]['bias_mm']:+.1f}"
                    for n in FAMILY_NAMES)) for r in rows)  # fmt: skip
    report.add_section(
        "Model families per record",
        f"Gauge {FAMILY_GAUGE}, free run of each model on every record (reference simulator; "
        "the FMUs equal it to 1e-9 mm). Local FOPDT: linear around the step conditions' "
        "operating line; envelope FOPDT: the same file with its envelope (gate law and "
        "storage); physical: storage, gate law and actuator. Records E* and Q55 were never "
        "fitted.",
        Table(header, body),
    )


def write_report(ctx: Any) -> None:
    """``report.html``: tables, figures, validation matrix (and later sections)."""
    from gatetwin.report import Report, Table

    report = Report("gatetwin run", "Digital twin of the sluice gate from the bundled records")
    tables = ctx.results.get("tables", [])
    report.add_section(
        "Published vs ours",
        "The reference study's Tables 2–5 next to what gatetwin measures on the bundled "
        "(virtual-flume) records; docs/flume.md and docs/identification.md say why each "
        "difference exists.",
        *(Table(t.header, t.rows, caption=t.title) for t in tables),
    )
    from gatetwin.run.figures import caption

    figures = [(p, caption(p)) for p in ctx.results.get("figures", [])]
    report.add_section("Identification figures", figures=figures)
    cells = ctx.results.get("validation", [])
    if cells:
        from gatetwin.validation.harness import validity_text

        columns = ("backend", "fmu", "record", "fit_percent", "noise_floor_fit_percent",
                   "fit_vs_floor", "r2", "rmse_mm", "bias_mm", "validity", "passed")  # fmt: skip
        rows = [{**c, "validity": validity_text(c)} for c in cells]
        report.add_section(
            "Validation matrix",
            f"Every exported FMU driven through fmpy by every bundled record; criterion "
            f"{', '.join(MATRIX_FAIL_UNDER)}. {FLOOR_NOTE}",
            Table.from_dicts(rows, columns, titles=MATRIX_TITLES),
        )
    _families_section(ctx, report)
    doc = ctx.results.get("mpc")
    if doc:
        plots = sorted((ctx.out_dir / "figures").glob("mpc_*/*.png"))
        report.add_section(
            "MPC demo",
            f"CasADi MPC (condensed QP, DAQP) against a SIMC-tuned PI, built from "
            f"{doc['model']}; plants: the exported C FMU through fmpy, and the virtual flume. "
            f"On wide_range (120 → 300 mm at 50 m³/h, then Q ±30 m³/h) the MPC re-linearised "
            f"on the envelope at every sample runs against the single-point MPC.",
            Table(MPC_HEADER, tuple(tuple(r) for r in _mpc_rows(doc))),
            figures=[(p, f"{p.parent.name.replace('_', ' ')}: {p.stem.replace('_', ' ')}")
                     for p in plots],
        )  # fmt: skip
    diagnoses = ctx.results.get("diagnose")
    if diagnoses:
        plots = sorted((ctx.out_dir / "figures" / "diagnose").glob("*.png"))
        report.add_section(
            "Diagnosis",
            "Where each record and its baseline disagree beyond the noise floor, which missing "
            "effect explains it, and the RMSE before and after adding it.",
            Table(DIAGNOSE_HEADER, tuple(tuple(r) for r in _diagnose_rows(diagnoses))),
            figures=[(p, p.stem.replace("_", " ")) for p in plots],
        )
    for title, blocks in ctx.results.get("report_sections", []):
        report.add_section(title, *blocks)
    report.write(ctx.out_dir / "report.html")
