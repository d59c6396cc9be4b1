"""The virtual flume: conservation, well-balancedness, grid convergence, determinism."""

from __future__ import annotations

import json
from dataclasses import replace
from importlib import resources

import numpy as np
import pytest

from gatetwin.errors import FlumeError
from gatetwin.flume import FlumeConfig, run_flume, spin_up
from gatetwin.flume.experiments import (
    Scenario,
    load_scenario,
    reference_scenarios,
    run_scenario,
)
from gatetwin.flume.solver import Grid, advance, law_of, leaf_speed, time_step_s

RECORDS = resources.files("gatetwin") / "data" / "records"


def test_volume_balance_over_a_run_with_moving_gate_and_varying_inflow():
    cfg = FlumeConfig()
    n = 2500  # 3000 s
    k = np.arange(n)
    cmd = np.where((k // 300) % 2 == 0, 20.0, 26.0)
    flow = 40.0 + 10.0 * np.sin(k / 200.0)
    run = run_flume(cfg, cmd, flow, state=spin_up(cfg, 40.0, 20.0))
    # the scheme is conservative: only round-off may break the balance (target < 0.1 %)
    assert run.volume_balance_error < 1e-3
    assert run.volume_balance_error < 1e-9


def test_lake_at_rest_stays_at_rest_over_the_sloping_bed():
    cfg = FlumeConfig()
    grid = Grid.of(cfg)
    dt, n_sub = time_step_s(cfg, grid)
    h = 0.30 - grid.bed_m + grid.bed_m[-1]  # level water surface
    q = np.zeros(grid.n_cells)
    steps = 50 * n_sub
    zeros = np.zeros(steps)
    levels = np.empty((50, 1))
    closed = np.array([0.0, cfg.actuator_speed_mm_s / 1000, cfg.actuator_stall_depth_m])
    advance(h, q, grid.bed_m, grid.dx_m, dt, zeros, zeros, closed, np.empty(steps), zeros,
            cfg.manning_n, -1.0, law_of(cfg), np.array([0]), np.array([0.0]), n_sub, levels,
            np.empty(50))  # fmt: skip
    surface = h + grid.bed_m
    assert np.ptp(surface) < 1e-12
    assert np.max(np.abs(q)) < 1e-12


def _step_response_3f(dx_m: float) -> np.ndarray:
    cfg = FlumeConfig(dx_m=dx_m)
    n = 400
    cmd = np.full(n, 15.0)
    cmd[50:] = 20.0
    run = run_flume(cfg, cmd, np.full(n, 29.5), state=spin_up(cfg, 29.5, 15.0))
    return run.depth_mm["3F"]


def test_grid_convergence_of_a_step_response():
    coarse, mid, fine = (_step_response_3f(dx) for dx in (0.10, 0.05, 0.025))
    err_coarse = np.max(np.abs(coarse - fine))
    err_mid = np.max(np.abs(mid - fine))
    # first-order scheme: halving dx should roughly halve the error (allow 0.7)
    assert err_mid < 0.7 * err_coarse
    # at the default 5 cm the discretisation error is below the gauges' 0.1 mm resolution
    # ... plus margin for the reference itself still carrying an error of its own
    assert err_mid < 0.3


def test_steady_state_does_not_drift():
    cfg = FlumeConfig()
    state = spin_up(cfg, 72.5, 30.0)
    run = run_flume(cfg, np.full(200, 30.0), np.full(200, 72.5), state=state)
    for depth in run.depth_mm.values():
        assert np.ptp(depth) < 0.01  # mm over 240 s
    assert abs(run.outflow_m3h[-1] - 72.5) < 1e-3


def test_actuator_moves_at_its_loaded_speed_and_logger_marks_open():
    cfg = FlumeConfig()
    scn = Scenario("t", ((0.0, 29.5),), ((0.0, 15.0), (60.0, 20.0)), 200.0, 1, "step")
    rec = run_scenario(scn, cfg)
    open_idx = np.flatnonzero(~rec.hold)
    depth_m = rec.levels_mm["5H"][0] / 1000
    travel_s = 5.0 / leaf_speed(depth_m, cfg.actuator_speed_mm_s, cfg.actuator_stall_depth_m)
    # every sample inside the motion is `open` with an empty opening
    assert abs(open_idx.size * cfg.sample_period_s - travel_s) <= 2 * cfg.sample_period_s
    assert np.all(np.isnan(rec.opening_mm[open_idx]))
    assert np.all(np.isin(rec.opening_mm[rec.hold], (15.0, 20.0)))


@pytest.mark.parametrize("name", ["A", "EflowHigh"])  # a step test; a validation record
def test_reference_record_regenerates_from_its_seed(name):
    scn = next(s for s in reference_scenarios() if s.name == name)
    record = run_scenario(scn)
    assert record.to_csv() == (RECORDS / f"{name}.csv").read_text(encoding="utf-8")
    assert record.sidecar == json.loads((RECORDS / f"{name}.json").read_text(encoding="utf-8"))


def test_every_bundled_record_has_a_sidecar_that_says_synthetic():
    names = sorted(p.name for p in RECORDS.iterdir() if p.name.endswith(".csv"))
    expected = {f"{s.name}.csv" for s in reference_scenarios()} | {"static.csv"}
    assert expected == set(names)
    for name in names:
        side = json.loads((RECORDS / name.replace(".csv", ".json")).read_text())
        assert side["synthetic"] is True
        assert side["flume_version"] and isinstance(side["seed"], int)


def test_held_out_record_is_marked():
    roles = {s.name: s.meta["role"] for s in reference_scenarios()}
    assert roles["Q55"] == "held_out"
    assert sum(r == "held_out" for r in roles.values()) == 1


def test_infeasible_scenario_is_refused_before_running():
    scn = Scenario("deep", ((0.0, 90.0),), ((0.0, 10.0),), 60.0, 1)
    with pytest.raises(FlumeError, match="deep"):
        run_scenario(scn)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("{", "invalid JSON"),
        ('{"duration_s": 10, "opening_mm": 20}', "flow_m3h"),
        ('{"duration_s": 10, "opening_mm": 20, "flow_m3h": [[5, 30]]}', "start at t = 0"),
        ('{"duration_s": -1, "opening_mm": 20, "flow_m3h": 30}', "duration_s"),
        ('{"duration_s": 10, "opening_mm": "x", "flow_m3h": 30}', "malformed"),
    ],
)
def test_bad_scenario_files_are_refused(tmp_path, text, match):
    path = tmp_path / "scn.json"
    path.write_text(text)
    with pytest.raises(FlumeError, match=match):
        load_scenario(path)


def test_scenario_file_runs(tmp_path):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({
        "duration_s": 120, "seed": 3, "test": "step",
        "flow_m3h": [[0, 40.0]], "opening_mm": [[0, 20], [30, 25]],
    }))  # fmt: skip
    rec = run_scenario(load_scenario(path))
    assert rec.sidecar["condition"] == "mine"
    assert rec.time_s.size == 101


def test_config_refuses_a_gauge_outside_the_pool():
    with pytest.raises(FlumeError, match="gauge"):
        replace(FlumeConfig(), gauges_m={"X": 50.0})


def test_actuator_slows_under_a_deeper_load():
    cfg = FlumeConfig()
    shallow = leaf_speed(0.2, cfg.actuator_speed_mm_s, cfg.actuator_stall_depth_m)
    deep = leaf_speed(0.35, cfg.actuator_speed_mm_s, cfg.actuator_stall_depth_m)
    assert deep < 0.6 * shallow
    assert leaf_speed(10.0, 1.0, 0.45) == pytest.approx(0.05)  # floored, never stalls
