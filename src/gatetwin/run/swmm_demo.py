"""``gatetwin swmm demo``: a check gate of an EPA SWMM canal, from experiments to control.

Stages, each timed (``demo.json`` ``times_s``):

1. **experiments** — the records of ``gatetwin swmm experiment --design all``
   (:func:`gatetwin.plants.swmm_designs.run_design`) into ``records/``;
2. **identification** — the library calls of ``gatetwin models --records``
   (:mod:`gatetwin.identification.suite`: the physical, FOPDT and ARX models) into ``models/``.
   A gauge whose physical fit fails gets the FOPDT of its step records alone, and the
   failure is reported (``identification.physical_failures``), not hidden;
3. **export** — ``fopdt_<G>`` and ``physical_<G>`` of every gauge as C FMUs into ``fmus/``
   (the calls of ``gatetwin export --backend c``);
4. **validation** — every FMU on the held-out records (roles ``held_out`` and
   ``validation``, never fitted) with :func:`gatetwin.validation.validate_fmu`, the call of
   ``gatetwin validate``; ``validation.json``. Criterion per FMU × record: free-run fit
   ≥ :data:`FIT_PASS_PERCENT` % or within :data:`FLOOR_MARGIN_POINTS` points of the
   record's noise floor (the fit a perfect model scores against the gauge noise), and
   ``|bias|`` ≤ :data:`BIAS_SHARE` of the record's level range;
5. **closed loop** — the MPC and the SIMC PI designed on ``fopdt_<G>`` of the gauge next to
   the gate, on the SWMM model, in the scenarios of :mod:`gatetwin.plants.swmm_loop`;
   their canal-control indicators and one PNG per scenario in ``loops/``;
6. **controller FMUs** — the PI and MPC FMUs of ``gatetwin export-controller`` (settings
   derived from the model file) through fmpy with SWMM as the plant, same scenarios
   (``fmus/controllers/``); one that cannot be built or run is reported, not fatal.

The output is built in a hidden sibling of ``--out`` and renamed at the end
(:mod:`gatetwin.run.outdir`): bad input leaves no partial folder.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin._io import write_json_atomic, write_text_atomic
from gatetwin.errors import GatetwinError
from gatetwin.plants.swmm import SwmmCore, SwmmPlantSpec, swmm_versions
from gatetwin.plants.swmm_loop import (
    INFLOW_DOWN,
    TwinPoint,
    canal_indicators,
    canal_scenarios,
    core_factory,
    inflow_up_factor,
    loop_settings,
    record_ranges,
    settings_summary,
    spec_to_dict,
)

#: Free-run fit that passes on its own, %.
FIT_PASS_PERCENT = 90.0
#: A fit this close to the record's noise floor passes too, points.
FLOOR_MARGIN_POINTS = 5.0
#: Largest |bias| as a share of the record's level range.
BIAS_SHARE = 0.1
#: Roles of the records no model is fitted on.
HELD_OUT_ROLES = ("held_out", "validation")


@dataclass(frozen=True)
class DemoRequest:
    """What to run.

    Attributes
    ----------
    spec : SwmmPlantSpec
        The SWMM plant (gate, gauges, inflow, sample period, gate speed).
    out : Path
        The output folder.
    flow_m3s : float or None
        Base inflow, m³/s (default: the model's constant inflow at the inflow nodes).
    opening_mm : float or None
        Base opening, mm (default: the one the model's rules hold the gate at, else half
        the orifice height).
    noise_mm : float
        Gauge noise SD of the records and the loops, mm.
    seed : int
        Seed of the noise.
    """

    spec: SwmmPlantSpec
    out: Path
    flow_m3s: float | None = None
    opening_mm: float | None = None
    noise_mm: float = 3.0
    seed: int = 0


def run_swmm_demo(req: DemoRequest, progress: Callable[[str], None] | None = None) -> dict:
    """Run every stage into a hidden sibling of ``req.out`` and put it in place.

    Returns
    -------
    dict
        The content of ``demo.json``.

    Raises
    ------
    GatetwinError
        Bad input or a stage that cannot run; nothing is left at ``req.out``.
    """
    from gatetwin.run.outdir import (
        MARKER,
        check_replaceable,
        clean_stale_work,
        make_work_dir,
        replace_output,
    )

    say = progress or (lambda _m: None)
    target = Path(req.out)
    owner = check_replaceable(target)
    clean_stale_work(target, say)  # a killed run's hidden folder
    work = make_work_dir(target)
    try:
        doc = _stages(req, work, say)
        write_json_atomic(work / "demo.json", doc)
        write_text_atomic(work / "summary.md", summary_markdown(doc))
        (work / MARKER).write_text("gatetwin swmm demo\n", encoding="utf-8")
        for leftover in work.glob(".gatetwin-run.pid"):
            leftover.unlink()
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    replace_output(work, target, owner)
    return doc


def _stages(req: DemoRequest, work: Path, say: Callable[[str], None]) -> dict[str, Any]:
    times: dict[str, float] = {}

    def timed(name: str, fn: Callable[[], Any]) -> Any:
        say(f"swmm demo: {name} ...")
        clock = time.perf_counter()
        result = fn()
        times[name] = round(time.perf_counter() - clock, 2)
        return result

    core = SwmmCore(req.spec)
    flow_m3h, opening = _base_point(req, core)
    response = timed("experiments", lambda: _experiments(req, core, flow_m3h, opening, work, say))
    ident = timed("identification", lambda: identify_twins(work / "records", work / "models"))
    fmus = timed("export", lambda: export_twins(work / "models", work / "fmus"))
    rows = timed("validation", lambda: validate_twins(fmus, work / "records", work))
    point_doc = {"flow_m3h": flow_m3h, "opening_mm": opening}
    write_json_atomic(work / "plant.json", {**spec_to_dict(req.spec), "noise_sd_mm": req.noise_mm})
    loops = timed("closed_loop", lambda: closed_loops(req, core, point_doc, work, say))
    fmu_loops = timed("controller_fmus", lambda: controller_fmu_loops(req, loops, work, say))
    return {
        "swmm": swmm_versions(),
        "plant": spec_to_dict(req.spec),
        "operating_point": point_doc,
        "step_response": response,
        "noise_sd_mm": req.noise_mm,
        "seed": req.seed,
        "identification": ident,
        "validation": {
            "criterion": _criterion_text(),
            "rows": rows,
            "passed": all(r["passed"] for r in rows),
        },  # fmt: skip
        "closed_loop": loops,
        "controller_fmus": fmu_loops,
        "times_s": times,
    }


def _base_point(req: DemoRequest, core: SwmmCore) -> tuple[float, float]:
    flow_m3s = core.base_flow_m3s if req.flow_m3s is None else req.flow_m3s
    if not (np.isfinite(flow_m3s) and flow_m3s > 0):
        raise GatetwinError(f"{req.spec.inp_path.name}: no constant inflow at "
                            f"{', '.join(req.spec.inflow_nodes)}; give --flow")  # fmt: skip
    return 3600.0 * float(flow_m3s), core.base_opening_mm(req.opening_mm)


def rule_opening_mm(core: SwmmCore) -> float | None:
    """:meth:`SwmmCore.rule_opening_mm` (kept for callers of this name)."""
    return core.rule_opening_mm()


def _experiments(req: DemoRequest, core: SwmmCore, flow_m3h: float, opening: float,
                 work: Path, say: Callable[[str], None]) -> dict[str, float]:  # fmt: skip
    from gatetwin.plants.swmm_designs import run_design
    from gatetwin.plants.swmm_experiments import write_outputs

    try:
        outputs, base = run_design(core, "all", opening, flow_m3h, noise_mm=req.noise_mm,
                                   seed=req.seed, progress=say)  # fmt: skip
    finally:
        core.close()
    write_outputs(work / "records", outputs)
    return base.response.to_dict()


def identify_twins(records: Path, models: Path) -> dict[str, Any]:
    """The models of ``gatetwin models --records`` (physical, FOPDT and ARX), written into
    ``models``; a failed physical fit leaves that gauge its step-only FOPDT (reported by
    gauge in ``physical_failures``, :attr:`Identified.not_identified`)."""
    from gatetwin.identification.suite import identify_folder
    from gatetwin.modelfile import write_model_files

    ident = identify_folder(records)
    gauges = sorted({g for s in ident.steps.values() for g in s.gauges})
    failures = {name.removeprefix("physical_"): why for name, why in ident.not_identified.items()}
    write_model_files(ident.models, models)
    return {"models": sorted(ident.models), "gauges": gauges, "physical_failures": failures}


def export_twins(models: Path, fmus: Path) -> list[tuple[str, Path]]:
    """``fopdt_<G>`` and ``physical_<G>`` of every gauge as C FMUs: ``[(gauge, path)]``."""
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.modelfile import read_model_file

    out = []
    for path in sorted(models.glob("*.json")):
        if not path.stem.startswith(("fopdt_", "physical_")):
            continue
        model = read_model_file(path)
        fmu = export_fmu(model.plant, fmus / f"{model.name}.fmu", backend="c",
                         model_name=model.name, provenance=fmu_provenance(model))  # fmt: skip
        out.append((model.plant.gauge, Path(fmu)))
    return out


def validate_twins(fmus: list[tuple[str, Path]], records: Path, work: Path) -> list[dict]:
    """Every FMU on the held-out records; writes ``validation.json``; one row per pair."""
    from gatetwin.records import read_record
    from gatetwin.validation import validate_fmu

    held = [read_record(p) for p in sorted(records.glob("*.csv"))
            if json.loads(p.with_suffix(".json").read_text(encoding="utf-8")).get("role")
            in HELD_OUT_ROLES]  # fmt: skip
    if not held:
        raise GatetwinError(f"{records}: no held-out record to validate on")
    docs, rows = {}, []
    for gauge, fmu in fmus:
        result = validate_fmu(fmu, held, gauge=gauge)
        docs[fmu.stem] = result.to_dict()
        rows += [_row(fmu.stem, r, rec) for r, rec in zip(result.records, held, strict=True)]
    write_json_atomic(work / "validation.json", docs)
    return rows


def _row(fmu: str, r: Any, record: Any) -> dict[str, Any]:
    measured = record.levels_mm[r.gauge]
    span = float(np.nanmax(measured) - np.nanmin(measured))
    fit, floor, bias = r.metrics.fit_percent, r.noise_floor_fit_percent, r.metrics.bias_mm
    fit_ok = fit >= FIT_PASS_PERCENT or (np.isfinite(floor) and fit >= floor - FLOOR_MARGIN_POINTS)
    return {"fmu": fmu, "record": r.record, "gauge": r.gauge, "fit_percent": _num(fit),
            "noise_floor_fit_percent": _num(floor), "bias_mm": _num(bias),
            "level_range_mm": round(span, 1),
            "passed": bool(fit_ok and abs(bias) <= BIAS_SHARE * span)}  # fmt: skip


def _num(x: float) -> float | None:
    return round(float(x), 2) if np.isfinite(x) else None


def _criterion_text() -> str:
    return (f"free-run fit >= {FIT_PASS_PERCENT:g} % or >= noise floor - "
            f"{FLOOR_MARGIN_POINTS:g} points, and |bias| <= {BIAS_SHARE:g} x the record's "
            "level range")  # fmt: skip


def closed_loops(req: DemoRequest, core: SwmmCore, point_doc: dict[str, float], work: Path,
                 say: Callable[[str], None]) -> dict[str, Any]:  # fmt: skip
    """MPC and PI on the SWMM model, designed on the output gauge's FOPDT twin with the
    settings ``export-controller`` derives from its model file (the controller FMUs' own)."""
    from dataclasses import replace

    from gatetwin.fmu.controller_settings import controller_plant, derived_settings
    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc.demo import compare_controllers, plot_runs
    from gatetwin.plants.swmm_experiments import gate_step_mm
    from gatetwin.records import read_record

    gauge = req.spec.gauge_names[req.spec.output_node]
    model = read_model_file(work / "models" / f"fopdt_{gauge}.json")
    plant = controller_plant(model)
    # the MPC controller FMU is exported without the model's effect blocks, the PI with them
    designs = {"mpc": replace(plant, effects=()), "pi": plant}
    opening, flow = point_doc["opening_mm"], point_doc["flow_m3h"]
    point = TwinPoint.of(plant, flow, opening, gate_step_mm(opening))
    series = [read_record(p) for p in sorted((work / "records").glob("*.csv"))
              if p.stem != "static"]  # fmt: skip
    _, band = record_ranges(series, gauge)
    s = loop_settings(point, sample_period_s=req.spec.sample_period_s, noise_sd_mm=req.noise_mm,
                      gate_speed_mm_s=req.spec.gate_speed_mm_s,
                      opening_range_mm=(0.0, core.height_mm), level_band_mm=band)  # fmt: skip
    derived = derived_settings(model, plant, s.mpc.opening_range_mm)
    s = replace(s, mpc=derived.mpc, pi=derived.pi)
    factory = core_factory(req.spec)
    up = inflow_up_factor(plant, point, s.mpc.opening_range_mm)
    out: dict[str, Any] = {"gauge": gauge, "twin": point.__dict__, "settings": settings_summary(s),
                           "inflow_up_factor": up, "scenarios": {}}  # fmt: skip
    for scenario in canal_scenarios(point, s.setpoint_step_mm, up):
        runs = {name: compare_controllers(design, scenario, plant_kind="swmm", settings=s,
                                          controllers=(name,), core_factory=factory)[name]
                for name, design in designs.items()}  # fmt: skip
        out["scenarios"][scenario.name] = {n: canal_indicators(r, point, s.loop)
                                           for n, r in runs.items()}  # fmt: skip
        plot_runs(runs, work / "loops" / f"{scenario.name}.png", s.loop, gauge)
        iae = {n: round(m["iae_mean_mm"], 1) for n, m in out["scenarios"][scenario.name].items()}
        say(f"swmm demo: {scenario.name}: mean |error| (mm) {iae}")
    return out


def controller_fmu_loops(req: DemoRequest, loops: dict[str, Any], work: Path,
                         say: Callable[[str], None]) -> dict[str, Any]:  # fmt: skip
    """The PI and MPC controller FMUs of ``gatetwin export-controller`` (settings derived
    from the model file) through fmpy, SWMM as the plant, in the closed loop's scenarios.
    A controller FMU that cannot be built or run is reported with its one-line cause."""
    from gatetwin.fmu.controller import export_controller
    from gatetwin.fmu.controller_settings import controller_plant, derived_settings
    from gatetwin.modelfile import read_model_file

    gauge = loops["gauge"]
    model = read_model_file(work / "models" / f"fopdt_{gauge}.json")
    point = TwinPoint(**loops["twin"])
    out: dict[str, Any] = {}
    for kind in ("pi", "mpc"):
        path = work / "fmus" / "controllers" / f"fopdt_{gauge}_{kind}.fmu"
        try:
            # the gate's whole range, as the Python loops have it (export-controller's
            # --opening-range): the inflow steps need openings the records never set
            plant = controller_plant(model)
            gate = tuple(loops["settings"]["mpc"]["opening_range_mm"])
            settings = derived_settings(model, plant, gate)
            export_controller(model, kind, path, settings=settings,
                              without_effects=kind == "mpc")  # fmt: skip
            out[kind] = _fmu_scenarios(req, path, point, loops, say)
        except GatetwinError as exc:
            out[kind] = {"failed": " ".join(str(exc).split())}
    return out


def _fmu_scenarios(req: DemoRequest, path: Path, point: TwinPoint, loops: dict[str, Any],
                   say: Callable[[str], None]) -> dict[str, Any]:  # fmt: skip
    from dataclasses import replace

    from gatetwin.mpc.fmu_controller import FmuController
    from gatetwin.mpc.loop import LoopSettings, run_closed_loop
    from gatetwin.mpc.plants import LoopPlant, MeasurementNoise

    controller = FmuController(path)
    ts = controller.sample_period_s
    spec = replace(req.spec, sample_period_s=ts)  # the plant steps at the FMU's own period
    noise = MeasurementNoise(**loops["settings"]["noise"])
    resolution = loops["settings"]["actuator_resolution_mm"]
    out: dict[str, Any] = {"sample_period_s": ts}
    try:
        for scenario in canal_scenarios(point, loops["settings"]["setpoint_step_mm"],
                                        loops["inflow_up_factor"]):  # fmt: skip
            plant = LoopPlant(SwmmCore(spec), noise=noise, sample_period_s=ts,
                              actuator_resolution_mm=resolution)  # fmt: skip
            try:
                run = run_closed_loop(plant, controller, scenario, level_band_mm=None,
                                      max_move_mm=req.spec.gate_speed_mm_s * ts,
                                      opening_range_mm=(0.0, plant.core.height_mm),
                                      sample_period_s=ts)  # fmt: skip
            finally:
                plant.close()
            out[scenario.name] = canal_indicators(run, point, LoopSettings(sample_period_s=ts))
            say(f"swmm demo: {path.stem} {scenario.name}: mean |error| "
                f"{out[scenario.name]['iae_mean_mm']:.1f} mm")  # fmt: skip
    finally:
        controller.cleanup()
    return out


_INDICATOR_HEAD = (
    "| scenario | controller | MAE | IAE (mean) | IAE (mm·s) | StE | IAW | "
    "violations | reversals/h |",
    "|---|---|---|---|---|---|---|---|---|",
)


def _indicator_row(scenario: str, controller: str, m: dict[str, Any]) -> str:
    return (f"| {scenario} | {controller} | {m['mae_mm']:.1f} | {m['iae_mean_mm']:.2f} | "
            f"{m['iae_mm_s']:.0f} | {m['ste_mm']:.2f} | {m['iaw_mm']:.0f} | "
            f"{m['violations']} | {m['gate_reversals_per_hour']:.0f} |")  # fmt: skip


def summary_markdown(doc: dict[str, Any]) -> str:
    """``summary.md``: the stage times, the validation and the indicators as tables."""
    lines = [f"# SWMM demo: gate {doc['plant']['gate']} of {Path(doc['plant']['inp']).name}",
             "", f"{doc['swmm']}; step response {doc['step_response']}", "",
             "| stage | wall time (s) |", "|---|---|"]  # fmt: skip
    lines += [f"| {k} | {v:.1f} |" for k, v in doc["times_s"].items()]
    lines += ["", f"## Validation on held-out records ({doc['validation']['criterion']})", "",
              "| FMU | record | fit % | noise floor % | bias (mm) | level range (mm) | pass |",
              "|---|---|---|---|---|---|---|"]  # fmt: skip
    lines += [f"| {r['fmu']} | {r['record']} | {r['fit_percent']} | "
              f"{r['noise_floor_fit_percent']} | {r['bias_mm']} | {r['level_range_mm']} | "
              f"{'yes' if r['passed'] else 'NO'} |" for r in doc["validation"]["rows"]]  # fmt: skip
    failures = doc["identification"]["physical_failures"]
    if failures:
        lines += [""] + [f"- physical fit of {g} failed: {m}" for g, m in failures.items()]
    loops = doc["closed_loop"]
    up = round(100.0 * (loops["inflow_up_factor"] - 1.0))
    lines += ["", f"## Closed loop at {loops['gauge']} (Clemmens et al. 1998 indicators, mm)",
              "", f"Inflow steps +{up} % (the largest of +40/30/20/10 % the gate can take) "
              f"and {round(100.0 * (INFLOW_DOWN - 1.0))} %.",
              "", *_INDICATOR_HEAD]  # fmt: skip
    for name, by in loops["scenarios"].items():
        lines += [_indicator_row(name, c, m) for c, m in by.items()]
    lines += ["", "## Controller FMUs through fmpy, SWMM as the plant (the same indicators)", "",
              *_INDICATOR_HEAD]  # fmt: skip
    for name in loops["scenarios"]:
        for kind, res in doc["controller_fmus"].items():
            lines.append(f"| {name} | {kind} | {res['failed']} |" if "failed" in res
                         else _indicator_row(name, kind, res[name]))  # fmt: skip
    return "\n".join(lines) + "\n"


__all__ = [
    "DemoRequest",
    "closed_loops",
    "controller_fmu_loops",
    "export_twins",
    "identify_twins",
    "rule_opening_mm",
    "run_swmm_demo",
    "summary_markdown",
    "validate_twins",
]
