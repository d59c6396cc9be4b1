"""The MPC's model and optimiser: exact dead-time augmentation, condensing, QP against
Opti + IPOPT, and offset-free control under model mismatch."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gatetwin.mpc import (
    ControlError,
    LoopPlant,
    ModelCore,
    MpcController,
    MpcProblem,
    MpcSettings,
    OptiBackend,
    QpBackend,
    Scenario,
    discretise,
    fopdt_split,
    loop_metrics,
    run_closed_loop,
)
from gatetwin.mpc.discrete import register_length
from gatetwin.mpc.qp import CondensedQp
from gatetwin.plant import ArxPlant, FopdtPlant, Schedule, simulate

TS = 1.2
#: Exactness of the augmented model against the reference simulation, mm (round-off).
EXACT_MM = 1e-9
#: QP and IPOPT must agree on the first move to this, mm.
AGREE_MM = 1e-3
#: Noise-free steady error allowed after offset-free convergence, mm.
STEADY_MM = 1e-6


def fopdt(dead_times=(2.0, 2.0, 2.0, 2.5, 2.5, 3.0), gain_factor: float = 1.0) -> FopdtPlant:
    return FopdtPlant(
        "3F",
        25.0,
        Schedule(
            (29.5, 40.0, 50.0, 60.0, 72.5, 85.0),
            {
                "gain_mm_per_mm": tuple(
                    gain_factor * k for k in (-15.4, -13.6, -12.5, -13.8, -10.6, -10.4)
                ),
                "time_constant_s": (71.0, 62.0, 52.0, 55.0, 42.0, 40.0),
                "dead_time_s": dead_times,
                "level_ref_mm": (120.7, 184.9, 253.6, 330.6, 436.6, 587.6),
            },
        ),
    )


def arx(gain_factor: float = 1.0) -> ArxPlant:
    return ArxPlant(
        "3F", 25.0, TS, 2, 2, 1,
        Schedule((30.0, 85.0), {
            "a1": (0.713, 0.575), "a2": (0.248, 0.148),
            "b1": (-1.93 * gain_factor, -2.53 * gain_factor),
            "b2": (1.17 * gain_factor, -0.51 * gain_factor),
            "level_ref_mm": (120.0, 590.0),
        }),
    )  # fmt: skip


def model_run(plant, openings, flows) -> np.ndarray:
    """Levels of the discrete rendering, stepped with the model of each sample's flow."""
    model = discretise(plant, flows[0])
    z = model.steady_state(openings[0])
    out = [model.level_mm(z)]
    for k in range(1, openings.size):
        model = discretise(plant, flows[k - 1])
        z = model.step(z, openings[k - 1])
        out.append(model.level_mm(z))
    return np.array(out)


@pytest.mark.parametrize("dead_time_s", [0.0, 0.3, 1.2, 1.8, 2.4, 3.0, 3.6, 3.7, 6.1])
def test_augmentation_reproduces_the_reference_step_response(dead_time_s):
    plant = fopdt(dead_times=(dead_time_s,) * 6)
    n = 80
    opening = np.full(n, 25.0)
    opening[5:] = 30.0
    flow = np.full(n, 45.0)
    reference = simulate(plant, np.arange(n) * TS, opening, flow)
    levels = model_run(plant, opening, flow)
    assert np.max(np.abs(levels - reference)) <= EXACT_MM
    assert abs(levels[-1] - levels[0]) > 30.0  # the step really moved the level


def test_augmentation_follows_discharge_changes_and_scheduled_dead_times():
    plant = fopdt(dead_times=(0.5, 1.3, 2.0, 2.9, 3.7, 5.5))
    n = 300
    rng = np.random.default_rng(3)
    opening = 25.0 + np.repeat(rng.integers(-6, 7, n // 10), 10).astype(float)
    flow = np.interp(np.arange(n), [0, 100, 200, 300], [30.0, 80.0, 45.0, 62.0])
    reference = simulate(plant, np.arange(n) * TS, opening, flow)
    assert np.max(np.abs(model_run(plant, opening, flow) - reference)) <= EXACT_MM


def test_arx_rendering_reproduces_the_reference():
    plant = arx()
    n = 200
    opening = np.where((np.arange(n) // 17) % 2 == 0, 25.0, 31.0)
    flow = np.linspace(35.0, 80.0, n)
    reference = simulate(plant, np.arange(n) * TS, opening, flow)
    assert np.max(np.abs(model_run(plant, opening, flow) - reference)) <= EXACT_MM


def test_modified_z_transform_split():
    a, n, b1, b2 = fopdt_split(-13.6, 62.0, 2.4, TS)
    assert n == 2 and b2 == 0.0  # 2.4 / 1.2 is two whole samples despite round-off
    assert math.isclose(b1, -13.6 * (1 - a))
    a, n, b1, b2 = fopdt_split(-13.6, 62.0, 3.0, TS)
    assert n == 2
    assert math.isclose(b1 + b2, -13.6 * (1 - a), rel_tol=1e-12)
    # half a sample late: the first half of the interval still sees the older input
    assert math.isclose(b2, -13.6 * math.exp(-0.6 / 62.0) * (1 - math.exp(-0.6 / 62.0)))


def test_state_size_is_set_by_the_largest_dead_time():
    plant = fopdt()
    assert register_length(plant, TS) == 3  # floor(3.0 / 1.2) + 1
    sizes = {discretise(plant, q).n_states for q in (20.0, 40.0, 66.0, 85.0, 100.0)}
    assert sizes == {4}


def test_condensed_prediction_equals_stepping_the_model():
    plant = fopdt()
    model = discretise(plant, 55.0)
    z0 = discretise(plant, 40.0).steady_state(27.0) + 3.0
    settings = MpcSettings(horizon=60)
    problem = MpcProblem(model, z0, 0.4, 200.0, 27.0, settings)
    plan = 27.0 + np.cumsum(np.random.default_rng(1).uniform(-0.7, 0.7, 60))
    predicted = CondensedQp(model, settings).predicted_levels(problem, plan)
    z, stepped = z0, []
    for e in plan:
        z = model.step(z, e, 0.4)
        stepped.append(model.level_mm(z))
    assert np.max(np.abs(predicted - np.array(stepped))) < 1e-9


def _problems(settings: MpcSettings) -> list[MpcProblem]:
    plant = fopdt()
    start = discretise(plant, 40.0)
    z = start.steady_state(25.0)
    at_60 = discretise(plant, 60.0)
    return [
        MpcProblem(start, z, 0.0, start.level_mm(z) + 20.0, 25.0, settings),  # set-point step
        MpcProblem(at_60, z, 0.0, start.level_mm(z), 25.0, settings),  # inflow step: rate
        MpcProblem(start, z, -1.5, start.level_mm(z) - 60.0, 25.0, settings),  # band bites
        MpcProblem(start, z, 0.0, start.level_mm(z) + 400.0, 25.0, settings),  # range bites
    ]


@pytest.mark.parametrize("solver", ["qpoases", "daqp"])
def test_qp_and_ipopt_agree_on_the_first_move(solver):
    settings = MpcSettings(horizon=100, qp_solver=solver, level_band_mm=(130.0, 360.0))
    qp, reference = QpBackend(settings), OptiBackend(settings)
    active = {"rate": False, "band": False, "range": False}
    for problem in _problems(settings):
        ours, ref = qp.solve(problem), reference.solve(problem)
        assert ours.success and ref.success
        assert abs(ours.first_move_mm - ref.first_move_mm) <= AGREE_MM
        assert abs(ours.slack_mm - ref.slack_mm) <= AGREE_MM
        moves = np.abs(np.diff(np.concatenate([[25.0], ours.openings_mm])))
        active["rate"] |= bool(np.any(moves > settings.max_move_mm - 1e-6))
        active["band"] |= ours.slack_mm > 1e-3 or ours.predicted_level_mm.min() < 130.0 + 1e-3
        active["range"] |= bool(np.any(ours.openings_mm < 5.0 + 1e-6))
    assert all(active.values()), active  # every kind of constraint was exercised


def test_daqp_reports_a_problem_without_solution_and_solves_the_next_on_the_same_model():
    """An opening far outside the range that one move cannot bring back: no point meets both
    the rate and the range bounds. DAQP says so (not a success, its status named: the
    controller then holds the gate), and the same model's next, feasible problem is solved
    on the kept workspace as a fresh backend solves it."""
    settings = MpcSettings(horizon=40)
    plant = fopdt()
    model = discretise(plant, 40.0)
    z = model.steady_state(25.0)
    stuck = MpcProblem(model, z, 0.0, model.level_mm(z), 300.0, settings)
    fine = MpcProblem(model, z, 0.0, model.level_mm(z) + 20.0, 25.0, settings)
    qp = QpBackend(settings)
    refused = qp.solve(stuck)
    assert not refused.success and refused.status == "infeasible"
    solved, fresh = qp.solve(fine), QpBackend(settings).solve(fine)
    assert solved.success and fresh.success
    assert abs(solved.first_move_mm - fresh.first_move_mm) <= AGREE_MM


def test_qp_and_ipopt_agree_without_a_level_band():
    settings = MpcSettings(horizon=60, level_band_mm=None)
    qp, reference = QpBackend(settings), OptiBackend(settings)
    for problem in _problems(settings):
        ours, ref = qp.solve(problem), reference.solve(problem)
        assert abs(ours.first_move_mm - ref.first_move_mm) <= AGREE_MM
        assert ours.slack_mm == 0.0


def _offset_run(plant_model, true_plant, minutes: float = 15.0):
    settings = MpcSettings(horizon=80)
    loop = LoopPlant(ModelCore(true_plant), noise=None, actuator_resolution_mm=0.0)
    scenario = Scenario("offset", minutes * 60.0, setpoint_changes=((60.0, 15.0),))
    run = run_closed_loop(
        loop, MpcController(plant_model, settings), scenario,
        level_band_mm=settings.level_band_mm, max_move_mm=settings.max_move_mm,
        opening_range_mm=settings.opening_range_mm,
    )  # fmt: skip
    return run, loop_metrics(run)


@pytest.mark.parametrize("gain_factor", [1.3, 0.7])
def test_offset_free_under_a_30_percent_gain_mismatch(gain_factor):
    true_plant = fopdt(gain_factor=gain_factor)
    run, metrics = _offset_run(fopdt(), true_plant)
    tail = run.level_mm[-50:] - run.setpoint_mm[-50:]
    assert np.max(np.abs(tail)) <= STEADY_MM
    assert metrics["violations"] == 0


def test_offset_free_arx_mpc_on_a_mismatched_arx_plant():
    run, _ = _offset_run(arx(), arx(gain_factor=1.3), minutes=20.0)
    assert np.max(np.abs(run.level_mm[-50:] - run.setpoint_mm[-50:])) <= STEADY_MM


def test_bad_settings_and_models_are_refused():
    with pytest.raises(ControlError):
        MpcSettings(horizon=0)
    with pytest.raises(ControlError):
        MpcSettings(opening_range_mm=(50.0, 10.0))
    with pytest.raises(ControlError):
        MpcSettings(qp_solver="nope")
    with pytest.raises(ControlError):
        discretise(replace(arx(), sample_period_s=1.0), 40.0)
    with pytest.raises(ControlError):
        discretise(fopdt(), math.nan)
    controller = MpcController(fopdt())
    with pytest.raises(ControlError):
        controller.step(math.nan, 40.0, 180.0)  # a level that is not a number
    with pytest.raises(ControlError):
        controller.reset(200.0, 180.0, 40.0)  # opening outside the range


def test_the_observer_starts_where_the_gate_has_no_hold_on_the_level():
    """An envelope's tangent at the critical-flow cap: the opening (through the register)
    never reaches the level, so the input disturbance is unobservable. The filter starts
    with a steady covariance for the level and none for ``d`` (the Riccati equation has no
    finite solution with an integrator nothing observes: the MPC demo stopped there)."""
    from gatetwin.mpc.observer import DisturbanceObserver, steady_prior_covariance
    from gatetwin.mpc.settings import ObserverSettings
    from gatetwin.mpc.statespace import DiscreteModel

    # the register's path to the level is round-off, not an exact zero
    model = DiscreteModel(a=np.array([[0.945, 1e-18], [0.0, 0.0]]), b=np.array([0.0, 1.0]),
                          c=np.array([1.0, 0.0]), b_dist=np.array([1e-16, 1.0]),
                          level_ref_mm=1800.0, opening_ref_mm=555.0, flow_m3h=14400.0,
                          sample_period_s=30.0, n_dynamic=1)  # fmt: skip
    settings = ObserverSettings(measurement_sd_mm=3.0, level_sd_mm=3.0, disturbance_sd_mm=4.1)
    p = steady_prior_covariance(model, settings)
    assert np.all(np.isfinite(p)) and p[2, 2] == 0.0 and p[0, 0] > 0.0
    # the level's variance is the scalar Riccati equation's: a^2 P R / (P + R) + Q = P
    a, q, r = 0.945, settings.level_sd_mm**2, settings.measurement_sd_mm**2
    assert math.isclose(p[0, 0], a * a * p[0, 0] * r / (p[0, 0] + r) + q, rel_tol=1e-9)
    observer = DisturbanceObserver(settings)
    observer.reset(model, 555.0, 1795.0)
    assert observer.disturbance_mm == 0.0
