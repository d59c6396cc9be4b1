"""A field gate (1.5 m wide, 3000 m² pool, ~2 m³/s, 10 s sampling) through the public path.

The truth is a :class:`~gatetwin.plant.model.PhysicalPlant` with field parameters
(``tests/field_scale.py``); nothing in identification, export or the controllers may assume
the lab flume. The fast tests check what is fixed from the data; the slow one runs
``models`` → ``export`` → ``validate`` → ``export-controller`` and steps the controllers.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import field_scale as field  # noqa: E402
from gatetwin.fmu.controller import rest_level_mm  # noqa: E402
from gatetwin.fmu.controller_settings import HORIZON_MAX, controller_plant, horizon  # noqa: E402
from gatetwin.identification import physical_start as start  # noqa: E402
from gatetwin.identification.rating import fit_static_table  # noqa: E402
from gatetwin.identification.suite import arx_gauge_of  # noqa: E402
from gatetwin.modelfile import read_model_file  # noqa: E402
from gatetwin.plant import physical_kernel as kernel  # noqa: E402
from gatetwin.plant.inputs import check_inputs  # noqa: E402
from gatetwin.records import read_record, read_static_table  # noqa: E402


@pytest.fixture(scope="module")
def records(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return field.write_field_records(tmp_path_factory.mktemp("field") / "gate")


def _read(folder: Path) -> tuple[object, dict]:
    static = read_static_table(str(folder / "static.csv"))
    recs = {p.stem: read_record(p) for p in sorted(folder.glob("*.csv")) if p.stem != "static"}
    return static, recs


def test_field_inputs_are_not_refused() -> None:
    # 2 m of opening and 50 m³/s: a field gate's ordinary inputs
    check_inputs(2000.0, 180_000.0)


def test_fixed_parameters_come_from_the_field_data(records: Path) -> None:
    static, recs = _read(records)
    width, source = start.gate_width_m(static, recs, field.GAUGE)
    assert width == field.WIDTH_M and "sidecar" in source
    centre, scale, _ = start.flow_normalisation(static)
    assert (centre, scale) == (7200.0, 10_000.0)  # mid-range 7200 m³/h, span 7200 m³/h
    # the recorded openings are whole multiples of 10 mm (350, 400, ...): the quantum seen
    assert start.opening_quantum_mm(recs)[0] == 10.0
    levels = np.concatenate([static.levels_mm[field.GAUGE],
                             *(r.levels_mm[field.GAUGE] for r in recs.values())])  # fmt: skip
    top = 4.0 * float(np.nanmax(levels)) / 1000.0
    assert top <= start.depth_bracket_m(static.levels_mm[field.GAUGE], recs, field.GAUGE) < 2 * top
    assert start.sample_period_s(recs) == field.SAMPLE_PERIOD_S


def test_width_without_sidecar_is_estimated_within_the_cd_spread(records: Path) -> None:
    static, recs = _read(records)
    for rec in recs.values():
        rec.metadata.pop("gate_width_m", None)
    recs = {name: dataclasses.replace(rec, gate_width_m=None) for name, rec in recs.items()}
    width, source = start.gate_width_m(static, recs, field.GAUGE)
    assert "Cd" in source
    # the truth's Cd at the smallest opening ratios lies between its c_inf (0.50) and c0
    # (0.61): a width from Cd = 0.61 is low by at most 0.61/0.50 - 1 = 22 %, never high
    # beyond the static means' noise (0.3 mm of ~1 m: 0.05 %)
    assert field.WIDTH_M * 0.50 / 0.61 <= width <= field.WIDTH_M * 1.001


def test_rating_fits_field_levels(records: Path) -> None:
    static = read_static_table(str(records / "static.csv"))
    rating = fit_static_table(static, field.WIDTH_M)[field.GAUGE]
    # the rating's Cd law is not the kernel's: a few cm of misfit at most over 0.8-5 m
    # levels, against metres when the lab's width and scales were built in
    assert rating.rmse_mm < 50.0
    assert rating.flow_scale_m3h == 10_000.0


def test_the_gate_law_grows_past_a_step_the_data_do_not_ask_for(records: Path) -> None:
    """The field gate's Cd does not drift with discharge, but its transition lies elsewhere
    than the start puts it: the drift step fits the steady points no better than the core,
    the whole law does. The growth passes over the drift step and keeps the whole law, whose
    least-squares fit misses the points by no more than the truth's law does (the truth is
    one of its parameter sets)."""
    from gatetwin.identification import physical
    from gatetwin.identification.suite import role_of

    static, recs = _read(records)
    recs = {n: r for n, r in recs.items() if role_of(r) == "fit"}
    points = physical.steady_points(static, recs, field.GAUGE)
    fixed, sources = physical.fixed_parameters(static, recs, field.GAUGE, points)
    laws = physical._fit_law(points, fixed, sources)
    assert [len(law) for law, _ in laws] == [len(physical.LAW_CORE), len(physical.LAW)], sources
    truth = {**fixed, **physical.FORMAT_DEFAULTS, **field.TRUTH}
    truth["depth_max_m"] = fixed["depth_max_m"]

    def rms(values: dict) -> float:
        return float(
            np.sqrt(np.mean(physical._steady_residuals(points, physical._vector(values)) ** 2))
        )

    assert rms(laws[-1][1]) <= rms(truth)


def test_discrete_gauge_is_the_best_signal_to_noise(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    command = np.repeat(rng.choice([380.0, 420.0], size=40), 60)
    flow = np.full(command.size, 7200.0)
    field.write_record(tmp_path, "R", command, flow, rng, {"test": "prbs"})
    rec = read_record(tmp_path / "R.csv")
    # P2 carries three times P1's gauge noise on the same pool level
    assert arx_gauge_of([rec]) == "P1"


def test_horizon_covers_settling_in_bounded_steps() -> None:
    t, ts = 3600.0, 10.0
    n, step = horizon(t, 20.0, ts)
    # at most HORIZON_MAX steps of whole samples, reaching one time constant past the dead
    # time, and the settling time (4 T + L) when the steps allow it
    assert n <= HORIZON_MAX and step % ts == 0
    assert n * step >= min(4.0 * t + 20.0, HORIZON_MAX * step) >= t + 20.0
    assert (step - ts) * HORIZON_MAX < t + 20.0  # no coarser than it needs to be
    n, step = horizon(500.0, 20.0, ts)  # a pool answering in minutes: every sample
    assert (n, step) == (HORIZON_MAX, ts)


def _gatetwin(*args: str) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run([sys.executable, "-m", "gatetwin", *args], capture_output=True,
                          text=True, env=env, timeout=1200, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr + done.stdout
    return done.stdout


def _step_controller(fmu: Path, model: Path) -> tuple[float, float]:
    """The controller's first opening from rest at its own operating point (the middle of the
    model's discharge range, the opening its model is linearised at), with the set-point
    50 mm below the level there: ``(start, opening)``. (The middle of the opening range is
    no rest of a physical model's controller: 180 mm of opening from its point, its linear
    model holds the field gate at -478 mm.)"""
    fmpy = pytest.importorskip("fmpy")
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    level_name = next(n for n in vr if n.startswith("level_"))
    unzipped = fmpy.extract(str(fmu))
    try:
        inst = fmpy.instantiate_fmu(unzipped, md)
        inst.setupExperiment(startTime=0.0)
        inst.enterInitializationMode()
        content = read_model_file(model)
        flow = float(np.mean(content.content["validity"]["flow_m3h"]))
        plant = controller_plant(content)
        start_mm = float(plant.opening_ref_mm)
        inst.setReal([vr["start_opening_mm"]], [start_mm])
        inst.exitInitializationMode()
        # at rest: the level the controller's model holds at the start opening
        level = rest_level_mm(plant, start_mm, flow)
        inst.setReal([vr[level_name], vr["setpoint_mm"], vr["flow_m3h"]],
                     [level, level - 50.0, flow])  # fmt: skip
        inst.doStep(0.0, float(md.defaultExperiment.stepSize))
        opening = inst.getReal([vr["opening_mm"]])[0]
        inst.terminate()
        inst.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return start_mm, float(opening)


@pytest.fixture(scope="module")
def field_models(records: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("field_models")
    _gatetwin("models", "--records", str(records), "--out", str(out), "--workers", "1")
    return out / records.name  # one gate's folder: its models go under its name


@pytest.mark.long
@pytest.mark.slow
def test_field_gate_public_path(field_models: Path, tmp_path: Path) -> None:
    models = field_models
    physical = json.loads((models / "physical_P1.json").read_text())
    assert {p.name for p in models.glob("*_P1.json")} == {"fopdt_P1.json", "physical_P1.json"}
    fit = physical["provenance"]["metrics"]["fit"]
    values, errors = physical["plant"]["parameters"], fit["standard_errors"]
    assert values["width_m"] == field.WIDTH_M
    # the gauge's noise from the records' holds: the truth's within 10 % (a pooled SD over
    # thousands of hold samples has a relative standard error under 2 %; the margin is for
    # what the inflow's 0.5 % noise makes the level wander through a hold)
    noise = physical["validity"]["level_noise_sd_mm"]
    assert abs(noise / field.LEVEL_SD_MM["P1"] - 1.0) <= 0.1, noise
    # the pool's time constant at the middle of the step tests, identified against the
    # truth: within 4 standard errors of the storage area there (A0 and A1 taken as
    # independent: their covariance is negative at this depth, so this overstates the error)
    # plus the gate law's share, 1 % (its conductance from static points of 0.3 mm noise)
    e, q = 420.0, 7200.0
    depth = field.truth_plant().steady_depth_m(e, q)
    lever = depth - kernel.AREA_DEPTH_REF_M
    t_true = kernel.time_constant_s(depth, e, q, field.truth_plant().vector)
    got = [values[n] for n, _, _ in kernel.PARAMETERS]
    t_got = kernel.time_constant_s(kernel.fmax(depth, 1e-3), e, q, got)
    area = values["area_m2"] + values["area_per_depth_m"] * lever
    rel = math.hypot(errors["area_m2"], errors.get("area_per_depth_m", 0.0) * lever) / area
    assert abs(t_got / t_true - 1.0) <= 4.0 * rel + 0.01

    validation = field.write_validation_record(tmp_path / "validation")
    for family in ("fopdt", "physical"):
        fmu = tmp_path / f"{family}.fmu"
        _gatetwin("export", "--backend", "c", "--out", str(fmu), str(models / f"{family}_P1.json"))
        report = tmp_path / f"{family}_validate.json"
        _gatetwin("validate", "--json", str(report), str(fmu), str(validation))
        text = report.read_text()
        fits = [float(x) for x in _numbers_after(text, '"fit_percent"')]
        assert fits and min(fits) >= 90.0, text[:2000]
        for kind in ("pi", "mpc"):
            ctrl = tmp_path / f"{family}_{kind}.fmu"
            extra = ["--without-effects"] if kind == "mpc" else []
            _gatetwin("export-controller", "--kind", kind, "--out", str(ctrl), *extra,
                      str(models / f"{family}_P1.json"))  # fmt: skip
            start, opening = _step_controller(ctrl, models / f"{family}_P1.json")
            # a set-point 50 mm below the level opens the gate (K < 0), within the range
            assert start < opening <= physical["validity"]["opening_range_mm"][1], (family, kind)


def _numbers_after(text: str, key: str) -> list[str]:
    out, i = [], text.find(key)
    while i >= 0:
        rest = text[i + len(key) :].lstrip(": ")
        num = rest.split(",")[0].split("}")[0].strip()
        if num not in ("null", ""):
            out.append(num)
        i = text.find(key, i + 1)
    return out


@pytest.mark.slow
def test_controller_schedule_reaches_the_validity_range_by_the_gate_law(
    field_models: Path,
) -> None:
    """The step conditions cover part of the discharges the records saw; the controllers'
    schedule is carried to the validity's ends by the envelope's gate law where the gate
    controls the level there, so the level it
    predicts there at the reference opening is nearer the truth's than the last condition's
    level held flat (what a clamped schedule gives)."""
    from gatetwin.modelfile import validity_envelope
    from gatetwin.plant.model import local_fopdt

    model = read_model_file(field_models / "fopdt_P1.json")
    fitted = model.plant.schedule
    extended = controller_plant(model).schedule
    q_lo, q_hi = validity_envelope(model.content)["flow_m3h"]
    ends = [q for q in (q_lo, q_hi) if not fitted.flow_m3h[0] <= q <= fitted.flow_m3h[-1]]
    assert ends  # the records reach beyond the step conditions
    # an end where the gate at the reference opening is lifted clear of the water (K = 0)
    # gets no knot; the other does
    carried = [q for q in ends if q in (extended.flow_m3h[0], extended.flow_m3h[-1])]
    assert carried
    e_ref = model.plant.opening_ref_mm
    for q in carried:
        truth = local_fopdt(field.truth_plant(), q, e_ref)["level_mm"]
        carried, held = (s.at("level_ref_mm", q) for s in (extended, fitted))
        assert abs(carried - truth) < abs(held - truth)


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None,
                    reason="no C compiler (cc/gcc) on PATH")  # fmt: skip
def test_the_observer_fmu_of_a_field_model_starts_at_its_operating_point(tmp_path) -> None:
    """A physical model file of the field gate (the truth's parameters, its validity ranges
    and 10 s records) gets an observer FMU that steps 10 s and starts at rest at the model's
    operating point (the middle discharge, the opening holding the middle level), inside the
    validity ranges, not at the flume's 30 mm (which holds the field pool at tens of metres):
    one step on its start inputs leaves the level where it is (innovation within round-off of
    the steady level, 1e-6 mm)."""
    from fmpy import read_model_description

    from gatetwin.cli import main
    from gatetwin.fmu.controller_settings import operating_point
    from gatetwin.fmu.observer_fmu import run_observer_fmu
    from gatetwin.modelfile import physical_document, write_model_file

    plant = field.truth_plant()
    q, e = (3600.0, 10800.0), (250.0, 700.0)
    levels = [plant.steady_level_mm(o, f) for o in e for f in q]
    doc = physical_document("physical_P1", plant, {"flow_m3h": list(q), "opening_mm": list(e),
                            "level_mm": [min(levels), max(levels)]}, description="field gate",
                            provenance={"method": "the truth", "records": []})  # fmt: skip
    doc["validity"]["sample_period_s"] = field.SAMPLE_PERIOD_S
    model = write_model_file(tmp_path / "physical_P1.json", doc)
    fmu = tmp_path / "observer.fmu"
    assert main(["export-observer", str(model), "--out", str(fmu)]) == 0
    md = read_model_description(str(fmu))
    assert float(md.defaultExperiment.stepSize) == field.SAMPLE_PERIOD_S
    start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "input"}
    level, opening, flow = start["level_P1_mm"], start["opening_mm"], start["flow_m3h"]
    assert (flow, opening) == operating_point(read_model_file(model))
    assert flow == 0.5 * sum(q) and e[0] <= opening <= e[1]
    assert min(levels) <= level <= max(levels)
    assert abs(level - plant.steady_level_mm(opening, flow)) <= 1e-6
    out = run_observer_fmu(fmu, [level] * 3, [opening] * 3, [flow] * 3)
    assert np.all(np.abs(out["innovation_mm"]) <= 1e-6), out["innovation_mm"]
