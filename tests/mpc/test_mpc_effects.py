"""Effect blocks in the MPC: the discrete rendering equals the reference simulation, and
an augmented model controls the plant it describes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gatetwin.mpc import (
    LoopPlant,
    ModelCore,
    MpcController,
    MpcProblem,
    MpcSettings,
    OptiBackend,
    QpBackend,
    Scenario,
    discretise,
    loop_metrics,
    run_closed_loop,
)
from gatetwin.mpc.actuation import CommandShaper
from gatetwin.mpc.observer import steady_prior_covariance
from gatetwin.plant import PlantSimulator, simulate
from gatetwin.plant.effects import effect_dict
from test_mpc_model import AGREE_MM, EXACT_MM, STEADY_MM, TS, arx, fopdt, model_run

SEICHE = effect_dict("seiche", period_s=15.7, decay_time_s=23.0, amplitude_mm_per_mm=-2.0)
INFLOW = effect_dict("inflow_disturbance", gain_mm_per_m3h=3.0, time_constant_s=40.0,
                     flow_ref_m3h=45.0)  # fmt: skip
DRIFT = effect_dict("sensor_drift", rate_mm_per_s=0.01)
LAG = effect_dict("sensor_lag", time_constant_s=6.0)
FLOW_GAIN = effect_dict("flow_dependent_gain", gain_slope_per_m3h=0.01,
                        time_constant_slope_per_m3h=-0.005, flow_ref_m3h=50.0)  # fmt: skip
LINEAR = {"seiche": [SEICHE], "inflow_disturbance": [INFLOW], "sensor_drift": [DRIFT],
          "sensor_lag": [LAG], "flow_dependent_gain": [FLOW_GAIN],
          "all": [SEICHE, INFLOW, DRIFT, LAG, FLOW_GAIN]}  # fmt: skip
#: Smallest difference the block must make to the reference over the test input, mm: a
#: rendering that dropped the block would miss by at least this, far above EXACT_MM.
MATERIAL_MM = 1.0


def _inputs(n: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    opening = 25.0 + np.repeat(rng.integers(-6, 7, n // 10), 10).astype(float)
    flow = np.interp(np.arange(n), [0, 100, 200, 300], [30.0, 80.0, 45.0, 62.0])
    return np.arange(n) * TS, opening, flow


#: (blocks, family) pairs: every linear block on both families (the flow-dependent gain is
#: an FOPDT block, so ARX carries the others).
RENDERINGS = [(n, "fopdt") for n in sorted(LINEAR)] + [
    (n, "arx") for n in sorted(LINEAR) if n != "flow_dependent_gain"
]


@pytest.mark.parametrize(("name", "family"), RENDERINGS)
def test_rendering_with_effects_equals_the_reference(name, family):
    effects = LINEAR[name]
    if family == "arx":
        effects = [e for e in effects if e["kind"] != "flow_dependent_gain"]
    base = fopdt(dead_times=(0.5, 1.3, 2.0, 2.9, 3.7, 5.5)) if family == "fopdt" else arx()
    plant = replace(base, effects=tuple(effects))
    t, opening, flow = _inputs()
    reference = simulate(plant, t, opening, flow)
    assert np.max(np.abs(model_run(plant, opening, flow) - reference)) <= EXACT_MM
    assert np.max(np.abs(reference - simulate(base, t, opening, flow))) > MATERIAL_MM


def test_sensor_blocks_leave_the_controlled_level_alone():
    plant = replace(fopdt(), effects=(LAG, DRIFT))
    t, opening, flow = _inputs(120)
    sim = PlantSimulator(plant)
    sim.initialize(opening[0], flow[0])
    model = discretise(plant, flow[0])
    z = model.steady_state(opening[0])
    for k in range(1, t.size):
        sim.do_step(TS, opening[k - 1], flow[k - 1])
        model = discretise(plant, flow[k - 1])
        z = model.step(z, opening[k - 1])
        assert abs(model.process_level_mm(z) - sim.process_level_mm) <= EXACT_MM
        assert abs(model.level_mm(z) - sim.level_mm) <= EXACT_MM
    assert abs(sim.level_mm - sim.process_level_mm) > MATERIAL_MM  # the gauge drifted


def test_drift_states_start_known_and_are_never_corrected():
    model = discretise(replace(fopdt(), effects=(DRIFT,)), 40.0)
    z = model.steady_state(25.0)
    assert [z[i] for i in model.fixed_states] == [0.0, DRIFT["rate_mm_per_s"]]
    p = steady_prior_covariance(model, MpcSettings().observer)
    fixed = list(model.fixed_states)
    assert np.all(p[fixed] == 0.0) and np.all(p[:, fixed] == 0.0)
    assert p[0, 0] > 0.0


def test_qp_and_ipopt_agree_on_an_augmented_model():
    plant = replace(fopdt(), effects=(SEICHE, INFLOW, DRIFT, LAG))
    settings = MpcSettings(horizon=60, level_band_mm=(130.0, 360.0))
    start, later = discretise(plant, 40.0), discretise(plant, 60.0)
    z = start.steady_state(25.0)
    problems = [
        MpcProblem(start, z, 0.0, start.process_level_mm(z) + 20.0, 25.0, settings),
        MpcProblem(later, z, 0.3, start.process_level_mm(z), 25.0, settings,
                   max_move_mm=0.3, opening_range_mm=(10.0, 40.0)),
    ]  # fmt: skip
    qp, reference = QpBackend(settings), OptiBackend(settings)
    for problem in problems:
        ours, ref = qp.solve(problem), reference.solve(problem)
        assert ours.success and ref.success
        assert abs(ours.first_move_mm - ref.first_move_mm) <= AGREE_MM
        moves = np.diff(np.concatenate([[25.0], ours.openings_mm]))
        assert np.max(np.abs(moves)) <= problem.move_bound_mm + 1e-9


def _closed_loop(model_plant, true_plant, *, flow_step: bool = True):
    settings = MpcSettings(horizon=80)
    loop = LoopPlant(ModelCore(true_plant), noise=None, actuator_resolution_mm=0.0)
    scenario = Scenario(
        "effects", 900.0, setpoint_changes=((60.0, 15.0),),
        flow_changes=((400.0, 50.0),) if flow_step else (),
    )  # fmt: skip
    controller = MpcController(model_plant, settings)
    run = run_closed_loop(
        loop, controller, scenario, level_band_mm=settings.level_band_mm,
        max_move_mm=settings.max_move_mm, opening_range_mm=settings.opening_range_mm,
    )  # fmt: skip
    return run, loop, controller


def _tail_error_mm(run) -> float:
    return float(np.max(np.abs(run.level_mm[-50:] - run.setpoint_mm[-50:])))


@pytest.mark.parametrize("name", ["seiche", "inflow_disturbance", "sensor_drift", "sensor_lag",
                                  "flow_dependent_gain", "all"])  # fmt: skip
def test_augmented_mpc_is_offset_free_on_its_plant(name):
    plant = replace(fopdt(), effects=tuple(LINEAR[name]))
    run, _, _ = _closed_loop(plant, plant)
    assert _tail_error_mm(run) <= STEADY_MM
    assert loop_metrics(run)["violations"] == 0


def test_drift_misleads_the_baseline_mpc_and_not_the_augmented_one():
    plant = replace(fopdt(), effects=(DRIFT,))
    augmented, _, _ = _closed_loop(plant, plant)
    baseline, _, _ = _closed_loop(fopdt(), plant)
    # the baseline holds the drifting reading at the set-point, so the water level is off
    # by the drift accumulated (0.01 mm/s over ~15 min, minus nothing it can see)
    drifted = DRIFT["rate_mm_per_s"] * baseline.time_s[-1]
    assert _tail_error_mm(baseline) > 0.5 * drifted
    assert _tail_error_mm(augmented) <= STEADY_MM


def test_rate_limited_gate_reaches_every_command_within_the_sample():
    rate = 0.2  # mm/s, slower than the settings' 0.6 mm/s
    plant = replace(fopdt(), effects=(effect_dict("actuator_rate_limit", rate_mm_per_s=rate),))
    run, loop, _ = _closed_loop(plant, plant)
    moves = np.abs(np.diff(np.concatenate([[run.scenario.opening_mm], run.command_mm])))
    assert np.max(moves) <= rate * TS + 1e-9
    assert np.max(moves) > 0.9 * rate * TS  # the bound was active
    assert loop.core._sim.es.actuator_mm == run.command_mm[-1]
    assert _tail_error_mm(run) <= STEADY_MM
    baseline, _, _ = _closed_loop(fopdt(), plant)  # plans 0.72 mm moves the gate cannot make
    assert _tail_error_mm(baseline) > 100 * STEADY_MM


def test_backlash_is_compensated_so_the_gate_goes_where_wanted():
    band = 2.0
    plant = replace(fopdt(), effects=(effect_dict("actuator_backlash", deadband_mm=band),))
    settings = MpcSettings(horizon=80)
    loop = LoopPlant(ModelCore(plant), noise=None, actuator_resolution_mm=0.0)
    controller = MpcController(plant, settings)
    y = loop.start(25.0, 40.0)
    controller.reset(25.0, y, 40.0)
    setpoints = np.concatenate([np.full(200, y + 15.0), np.full(200, y - 10.0)])
    reversals = 0
    for r in setpoints:
        before = controller.shaper.direction
        command = controller.step(y, 40.0, r)
        reversals += before * controller.shaper.direction < 0
        y = loop.step(command, 40.0)
        gate = loop.core._sim.es.gate_mm
        assert gate == pytest.approx(controller.shaper.gate_mm, abs=1e-9)  # it knows the gate
        assert abs(gate - controller.previous_gate_mm) <= settings.backlash_hold_mm + 1e-9
    assert reversals >= 2  # the compensation was exercised both ways
    # the gate sits within the hold of the plan, so the level within |K| x hold of the set-point
    gain = max(abs(k) for k in plant.schedule.values["gain_mm_per_mm"])
    steady_mm = gain * settings.backlash_hold_mm + STEADY_MM
    assert abs(loop.true_level_mm - setpoints[-1]) <= steady_mm


def test_opening_nonlinearity_is_planned_through():
    slope = -0.03
    plant = replace(fopdt(), effects=(effect_dict("opening_nonlinearity",
                                                  gain_slope_per_mm=slope),))  # fmt: skip
    run, _, controller = _closed_loop(plant, plant)
    moves = np.abs(np.diff(np.concatenate([[run.scenario.opening_mm], run.command_mm])))
    assert np.max(moves) <= controller.settings.max_move_mm + 1e-9
    assert _tail_error_mm(run) <= STEADY_MM
    shaper = controller.shaper
    for gate in (6.0, 25.0, 60.0):  # the first move's bound maps exactly
        up = shaper.to_gate(shaper.to_model(gate) + shaper.model_move_mm(gate))
        down = shaper.to_gate(shaper.to_model(gate) - shaper.model_move_mm(gate))
        assert max(up - gate, gate - down) == pytest.approx(shaper.gate_move_mm, rel=1e-12)
        assert min(up - gate, gate - down) < shaper.gate_move_mm


def test_command_shaper_without_blocks_is_the_identity():
    shaper = CommandShaper(fopdt().effect_set, 25.0, 0.72, TS)
    shaper.reset(25.0)
    for gate in (25.0, 30.0, 28.5, 28.5):
        assert shaper.to_model(gate) == gate == shaper.to_gate(gate) == shaper.command(gate)
    assert shaper.model_move_mm(30.0) == 0.72
    assert shaper.model_range_mm((5.0, 100.0)) == (5.0, 100.0)
