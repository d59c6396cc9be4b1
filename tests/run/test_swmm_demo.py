"""The SWMM canal demo (:mod:`gatetwin.run.swmm_demo`) and the SWMM plant in the closed
loop (:mod:`gatetwin.plants.swmm_loop`), on the field-scale canal of ``swmm_canal.py``
(not the shipped ASCE model)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

pytest.importorskip("pyswmm", reason="the SWMM plant needs the swmm extra (pyswmm)")

from gatetwin.cli import main  # noqa: E402
from gatetwin.mpc.demo import compare_controllers  # noqa: E402
from gatetwin.mpc.loop import Scenario  # noqa: E402
from gatetwin.plant.model import FopdtPlant, Schedule  # noqa: E402
from gatetwin.plants import swmm_loop  # noqa: E402
from gatetwin.plants.swmm import SwmmCore, SwmmPlantSpec  # noqa: E402
from gatetwin.plants.swmm_experiments import gate_step_mm, measure_step  # noqa: E402
from swmm_canal import (  # noqa: E402
    FLOW_M3S,
    GATE,
    GAUGES,
    INFLOW_NODE,
    OPENING_MM,
    write_field_canal,
)

NOISE_MM = 3.0
FLOW_M3H = 3600.0 * FLOW_M3S


def _spec(inp: Path) -> SwmmPlantSpec:
    return SwmmPlantSpec(inp, GATE, dict(GAUGES), (INFLOW_NODE,), gate_speed_mm_s=5.0,
                         sample_period_s=10.0, steady_tolerance_mm=NOISE_MM / 10)  # fmt: skip


def _measured_twin(spec: SwmmPlantSpec) -> tuple[FopdtPlant, swmm_loop.TwinPoint]:
    """An FOPDT of the output gauge from one noise-free step test on the canal (K, T, L
    measured, the level at the base point from the spin-up)."""
    core = SwmmCore(spec)
    try:
        r = measure_step(core, OPENING_MM, FLOW_M3H)
        level = core.level_mm() - r.gain_mm_per_mm * r.step_mm  # back to the base opening
    finally:
        core.close()
    flows = (0.5 * FLOW_M3H, 1.5 * FLOW_M3H)
    values = {"gain_mm_per_mm": (r.gain_mm_per_mm,) * 2,
              "time_constant_s": (r.time_constant_s,) * 2,
              "dead_time_s": (r.dead_time_s,) * 2, "level_ref_mm": (level,) * 2}  # fmt: skip
    plant = FopdtPlant(spec.gauge_names[spec.output_node], OPENING_MM, Schedule(flows, values))
    return plant, swmm_loop.TwinPoint.of(plant, FLOW_M3H, OPENING_MM, gate_step_mm(OPENING_MM))


def test_the_mpc_tracks_a_setpoint_step_on_the_swmm_canal(tmp_path: Path) -> None:
    spec = _spec(write_field_canal(tmp_path))
    plant, point = _measured_twin(spec)
    assert 1.5 <= point.level_mm / 1000 <= 3.5  # field scale: metres of water at the gate
    core = SwmmCore(spec)
    s = swmm_loop.loop_settings(point, sample_period_s=10.0, noise_sd_mm=NOISE_MM,
                                gate_speed_mm_s=5.0, opening_range_mm=(0.0, core.height_mm),
                                level_band_mm=None)  # fmt: skip
    hold = swmm_loop.HOLD_TIME_CONSTANTS * point.response_s
    scenario = Scenario("step", point.response_s + hold, flow_m3h=FLOW_M3H, opening_mm=OPENING_MM,
                        setpoint_changes=((point.response_s, s.setpoint_step_mm),))  # fmt: skip
    runs = compare_controllers(plant, scenario, plant_kind="swmm", settings=s,
                               controllers=("mpc",),
                               core_factory=swmm_loop.core_factory(spec))  # fmt: skip
    ind = swmm_loop.canal_indicators(runs["mpc"], point, s.loop)
    assert s.setpoint_step_mm > 10 * NOISE_MM  # the step stands well out of the noise
    # steady error: the mean over the last (T + L) of the true level's error. The loop
    # answers noise of SD sigma; the mean of n = (T + L)/Ts such samples has an SD of at most
    # sigma (perfectly correlated) and sigma/sqrt(n) if white: within sigma is >= 1 SD of
    # the worst case and ~sqrt(n) SDs of the white one
    assert abs(ind["ste_mm"]) <= NOISE_MM
    assert ind["violations"] == 0
    assert ind["mae_mm"] >= s.setpoint_step_mm - NOISE_MM  # the step itself was met


def test_a_plant_spec_file_round_trips_and_bad_ones_are_refused(tmp_path: Path) -> None:
    from gatetwin.errors import PlantError

    spec = _spec(write_field_canal(tmp_path))
    path = tmp_path / "plant.json"
    path.write_text(json.dumps(swmm_loop.spec_to_dict(spec)), encoding="utf-8")
    back = swmm_loop.read_spec(path)
    assert (back.gate, back.gauges, back.inflow_nodes) == (spec.gate, spec.gauges,
                                                           spec.inflow_nodes)  # fmt: skip
    path.write_text(json.dumps({"inp": "x.inp", "gate": GATE}), encoding="utf-8")
    with pytest.raises(PlantError, match="lacks gauges, inflow"):
        swmm_loop.read_spec(path)


def _refused(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gatetwin: error: ") and "\n" not in err
    return err


def test_the_demo_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, capsys) -> None:
    out = tmp_path / "demo"
    err = _refused(capsys, ["swmm", "demo", "--gate", "G1", "--out", str(out)])
    assert "--gate without --inp" in err
    names = ["--gate", GATE, "--gauges", "U2=0", "--inflow", "U0", "--out", str(out)]
    err = _refused(capsys, ["swmm", "demo", "--inp", str(tmp_path / "none.inp"), *names])
    assert "no such SWMM input file" in err
    inp = write_field_canal(tmp_path)
    err = _refused(capsys, ["swmm", "demo", "--inp", str(inp), *names, "--opening", "5000"])
    assert "--opening 5000" in err
    err = _refused(capsys, ["mpc-demo", "--plant", "swmm", "--json", str(tmp_path / "m.json"),
                            "--plots", str(tmp_path / "p")])  # fmt: skip
    assert "--swmm-plant" in err
    assert not out.exists() and not list(tmp_path.glob(".demo.*"))


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> dict:
    """The whole demo on the field canal, once for the slow tests."""
    folder = tmp_path_factory.mktemp("swmm_demo")
    inp = write_field_canal(folder)
    out = folder / "demo"
    argv = ["swmm", "demo", "--inp", str(inp), "--gate", GATE, "--gauges",
            *[f"{n}={d:g}" for n, d in GAUGES.items()], "--inflow", INFLOW_NODE,
            "--opening", f"{OPENING_MM:g}", "--noise-mm", f"{NOISE_MM:g}",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    return {"out": out, "doc": json.loads((out / "demo.json").read_text(encoding="utf-8"))}


@pytest.mark.long
@pytest.mark.slow
def test_the_demo_writes_every_stage(demo: dict) -> None:
    out, doc = demo["out"], demo["doc"]
    for name in ("summary.md", "validation.json", "plant.json", "records/static.csv",
                 "loops/setpoint_steps.png"):  # fmt: skip
        assert (out / name).is_file(), name
    gauges = [n for n in GAUGES]
    fmus = {p.stem for p in (out / "fmus").glob("*.fmu")}
    assert {f"fopdt_{g}" for g in gauges} <= fmus
    failed = doc["identification"]["physical_failures"]
    assert {f"physical_{g}" for g in gauges if g not in failed} <= fmus
    assert {r["fmu"] for r in doc["validation"]["rows"]} == fmus
    assert set(doc["times_s"]) == {"experiments", "identification", "export", "validation",
                                   "closed_loop", "controller_fmus"}  # fmt: skip
    assert all(t > 0 for t in doc["times_s"].values())
    for by in doc["closed_loop"]["scenarios"].values():
        for m in by.values():
            assert all(math.isfinite(m[k]) for k in ("mae_mm", "iae_mean_mm", "ste_mm", "iaw_mm"))


@pytest.mark.long
@pytest.mark.slow
def test_the_physical_twins_fit_every_held_out_record(demo: dict) -> None:
    """The canal's check gate is submerged (a pool and a second gate below it): the physical
    family keeps its tail pool and meets the fit criterion on every held-out record."""
    rows = [r for r in demo["doc"]["validation"]["rows"] if r["fmu"].startswith("physical_")]
    assert rows
    failed = [(r["fmu"], r["record"], r["fit_percent"]) for r in rows if not r["passed"]]
    assert not failed
    for path in (demo["out"] / "models").glob("physical_*.json"):
        assert json.loads(path.read_text())["plant"]["parameters"]["tail_area_m2"] > 0, path


@pytest.mark.long
@pytest.mark.slow
def test_every_fmu_fits_every_held_out_record(demo: dict) -> None:
    """Every FMU fits every held-out record (>= 90 % or within 5 points of the noise
    floor, bias within a tenth of the level's range)."""
    doc = demo["doc"]
    failed = [(r["fmu"], r["record"], r["fit_percent"]) for r in doc["validation"]["rows"]
              if not r["passed"]]  # fmt: skip
    assert not failed
    assert not doc["identification"]["physical_failures"]


@pytest.mark.long
@pytest.mark.slow
def test_the_mpc_beats_the_pi_in_every_scenario(demo: dict) -> None:
    """The MPC's mean |error| is below the PI's in every scenario, with no violation, and
    it reverses the gate no more often."""
    doc = demo["doc"]
    for name, by in doc["closed_loop"]["scenarios"].items():
        mpc, pi = by["mpc"], by["pi"]
        assert mpc["iae_mean_mm"] < pi["iae_mean_mm"], name
        assert mpc["gate_reversals_per_hour"] <= pi["gate_reversals_per_hour"], name
        assert mpc["violations"] == 0, name


@pytest.mark.long
@pytest.mark.slow
def test_the_mpc_controller_fmu_beats_the_pi_controller_fmu(demo: dict) -> None:
    """The controller FMUs of ``export-controller`` (settings derived from the model file)
    closing the loop with SWMM through fmpy: the MPC's IAE, over the whole run and per
    second after the first event, is below the PI's in every scenario, with no violation
    and no more gate reversals."""
    doc = demo["doc"]
    fmus = doc["controller_fmus"]
    assert "failed" not in fmus["mpc"] and "failed" not in fmus["pi"], fmus
    for name in doc["closed_loop"]["scenarios"]:
        mpc, pi = fmus["mpc"][name], fmus["pi"][name]
        assert mpc["iae_mean_mm"] < pi["iae_mean_mm"], name
        assert mpc["iae_mm_s"] < pi["iae_mm_s"], name
        assert mpc["gate_reversals_per_hour"] <= pi["gate_reversals_per_hour"], name
        assert mpc["violations"] == 0, name


def test_the_inflow_step_up_is_the_largest_the_gate_can_take() -> None:
    """A twin whose level rises 0.01 mm per m³/h and falls 2 mm per mm of opening: holding
    1050 mm at +40 % (14000 m³/h) needs 120 mm of opening, at +30 % 115 mm. With the gate's
    range 0..130 mm (reserve 13 mm: reach 117 mm) the step is +30 %; with 0..200 mm, +40 %;
    with 0..105 mm none fits and the smallest step is kept."""
    flows = (5000.0, 20000.0)
    values = {"gain_mm_per_mm": (-2.0, -2.0), "time_constant_s": (600.0, 600.0),
              "dead_time_s": (0.0, 0.0), "level_ref_mm": (1000.0, 1150.0)}  # fmt: skip
    plant = FopdtPlant("G", 100.0, Schedule(flows, values))
    point = swmm_loop.TwinPoint.of(plant, 10000.0, 100.0, 10.0)
    assert point.level_mm == pytest.approx(1050.0)
    assert swmm_loop.inflow_up_factor(plant, point, (0.0, 130.0)) == 1.3
    assert swmm_loop.inflow_up_factor(plant, point, (0.0, 200.0)) == 1.4
    assert swmm_loop.inflow_up_factor(plant, point, (0.0, 105.0)) == 1.1
