"""The MPC controller FMU (C, casadi-generated arithmetic, its own dense QP solver): FMI
validity, the generated functions against the numpy controller they are built from, the QP
solver against qpOASES, the closed loop against the Python loop, refusals and the solver
fallback.

The default tests use the demo's settings with a 30-sample horizon (the export's casadi code
generation and compile take ~50 s at the demo's N = 100); the demo's horizon itself is the
slow test.
"""

from __future__ import annotations

import contextlib
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gatetwin.errors import ExportError
from gatetwin.mpc import DemoSettings, demo_plant, demo_scenarios
from gatetwin.mpc.codegen import COLUMNS, build_functions
from gatetwin.mpc.demo import _controller, _PlantFactory, _run_one
from gatetwin.mpc.discrete import discretise, register_length
from gatetwin.mpc.fmu_controller import FmuController
from gatetwin.mpc.observer import DisturbanceObserver, steady_prior_covariance
from gatetwin.mpc.qp import CondensedQp, MpcProblem
from gatetwin.mpc.settings import MpcSettings
from gatetwin.plant.model import FopdtPlant

pytestmark = pytest.mark.skipif(
    shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler"
)

#: Equality of the two loops, mm. Both solve the same strictly convex QP from the same data
#: to its unique solution (the FMU with its dense active-set solver, Python with DAQP), so
#: each sample's opening agrees to the QP's round-off; the loop is stable, so that does not
#: grow. 1e-9 mm leaves four orders of
#: margin and is still far below anything physical (the actuator's resolution is 1 mm).
LOOP_TOL_MM = 1e-9
#: The generated functions against the numpy code: the same operations in (mostly) the same
#: order; sums of up to N terms reordered by BLAS give round-off of N·eps relative to the
#: largest term, well inside 1e-12.
FUNCTION_RTOL = 1e-12
SHORT = DemoSettings(mpc=MpcSettings(horizon=30))


@pytest.fixture(scope="module")
def plant() -> FopdtPlant:
    return demo_plant()


@pytest.fixture(scope="module")
def fmu(plant, tmp_path_factory):
    from gatetwin.fmu.mpc_controller import export_mpc_controller

    path = tmp_path_factory.mktemp("mpc_fmu") / "gatetwin_mpc.fmu"
    return export_mpc_controller(plant, path, settings=SHORT.mpc)


@pytest.fixture(scope="module")
def functions(plant):
    s = SHORT.mpc
    fns, _ = build_functions(len(plant.schedule.flow_m3h), register_length(plant), s)
    values = [*plant.schedule.flow_m3h, *(v for c in COLUMNS for v in plant.schedule.values[c])]
    return fns, np.array([*values, plant.opening_ref_mm])


def test_the_fmu_passes_fmpy_validation(fmu):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu)) == []


@pytest.fixture(scope="module")
def fmu3(plant, tmp_path_factory):
    from gatetwin.fmu.mpc_controller import export_mpc_controller

    path = tmp_path_factory.mktemp("mpc_fmu3") / "gatetwin_mpc.fmu"
    return export_mpc_controller(plant, path, settings=SHORT.mpc, fmi_version="3.0")


def test_the_fmi3_fmu_passes_fmpy_validation(fmu3):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu3)) == []


def _driven(fmu, levels, flows, setpoints):
    """Every output of the controller FMU over one input sequence, one row per sample."""
    from gatetwin.mpc.fmu_controller import OUTPUTS

    controller = FmuController(fmu, SHORT.mpc.sample_period_s)
    rows = []
    try:
        controller.reset(25.0, float(levels[0]), float(flows[0]))
        for y, q, r in zip(levels, flows, setpoints, strict=True):
            controller.step(float(y), float(q), float(r))
            rows.append([controller.diagnostics[n] for n in OUTPUTS])
    finally:
        controller.cleanup()
    return np.array(rows)


def test_fmi3_and_fmi2_controllers_give_identical_outputs(fmu, fmu3):
    """Set-point steps, a noisy level and a discharge swept across the knots (matrices
    re-formed) and beyond them (clamped): the same component compiled with the same flags
    under two glues, so equal to the bit."""
    rng = np.random.default_rng(7)
    n = 150
    setpoints = np.where(np.arange(n) < n // 2, 205.0, 190.0)
    levels = 195.0 + rng.normal(0.0, 2.0, n)
    flows = np.linspace(25.0, 90.0, n)
    two = _driven(fmu, levels, flows, setpoints)
    three = _driven(fmu3, levels, flows, setpoints)
    assert np.all(np.isfinite(three))
    assert np.array_equal(three, two)
    assert np.ptp(two[:, 0]) > 1.0  # the opening moved


# 1e6 mm: a set-point far outside the level band (the band's soft bound then decides)
@pytest.mark.parametrize("setpoint", [300.0, 350.0, 360.0, 1e6])
def test_large_set_point_steps_are_solved_at_every_sample(fmu, setpoint):
    """From rest at 190 mm, a step to ``setpoint`` keeps the rate limit active for most of
    the horizon: every sample's QP is solved (no held opening) and the gate closes at the
    rate limit (the demo plant's gain is negative) until it reaches the opening range's
    lower end."""
    from gatetwin.mpc.fmu_controller import OUTPUTS

    n = 30
    rows = _driven(fmu, np.full(n, 190.0), np.full(n, 40.0), np.full(n, setpoint))
    status = rows[:, OUTPUTS.index("solver_status")]
    assert np.array_equal(status, np.zeros(n))
    openings = rows[:, OUTPUTS.index("opening_mm")]
    moves = np.diff(np.concatenate([[25.0], openings]))
    lowest = SHORT.mpc.opening_range_mm[0]
    closing = openings > lowest + 1e-9
    assert np.all(np.abs(moves[closing] + SHORT.mpc.max_move_mm) <= 1e-9)
    assert np.all(np.abs(openings[~closing] - lowest) <= 1e-9) and not closing[-1]


@pytest.mark.slow  # ~15 s: the controller at the demo's horizon of 100
def test_set_points_outside_the_band_are_solved_at_the_demos_horizon(plant, tmp_path):
    """Above the band, tracking works against the band's soft bound: a cold start takes
    several hundred iterations at N = 100 (a fixed bound of 500 held the opening at every
    sample). With the default bound every sample is solved, within its bound, and the gate
    closes at the rate limit (the plant's gain is negative) until the opening range's end."""
    import json
    import zipfile

    from gatetwin.fmu.mpc_controller import export_mpc_controller
    from gatetwin.mpc.fmu_controller import OUTPUTS

    demo = DemoSettings()
    fmu = export_mpc_controller(plant, tmp_path / "mpc100.fmu", settings=demo.mpc)
    with zipfile.ZipFile(fmu) as z:
        bound = json.loads(z.read("resources/controller.json"))["max_iter"]
    n = 40
    setpoints = np.where(np.arange(n) < n // 2, 2000.0, 1e6)
    rows = _driven(fmu, np.full(n, 316.0), np.full(n, 50.0), setpoints)
    status = rows[:, OUTPUTS.index("solver_status")]
    iterations = rows[:, OUTPUTS.index("solver_iterations")]
    assert np.array_equal(status, np.zeros(n)) and np.all(iterations <= bound)
    assert np.max(iterations) > 500  # the case the former fixed bound could not solve
    openings = rows[:, OUTPUTS.index("opening_mm")]
    moves = np.diff(np.concatenate([[25.0], openings]))
    lowest = demo.mpc.opening_range_mm[0]
    closing = openings > lowest + 1e-9
    assert np.all(np.abs(moves[closing] + demo.mpc.max_move_mm) <= 1e-9)
    assert np.all(np.abs(openings[~closing] - lowest) <= 1e-9) and not closing[-1]


def _close(actual, expected, rtol=FUNCTION_RTOL):
    actual = np.asarray(actual, dtype=float).ravel()
    expected = np.asarray(expected, dtype=float).ravel()
    finite = np.isfinite(expected)
    assert np.array_equal(finite, np.isfinite(actual))
    assert np.array_equal(actual[~finite], expected[~finite])
    scale = np.max(np.abs(expected[finite]), initial=1.0)
    assert np.max(np.abs(actual[finite] - expected[finite]), initial=0.0) <= rtol * scale


# knots, between knots, a knot's neighbourhood and both clamped ends
@pytest.mark.parametrize("q", [29.5, 40.0, 47.3, 60.0 + 1e-9, 84.9, 10.0, 120.0])
def test_generated_functions_equal_the_numpy_controller(plant, functions, q):
    fns, theta = functions
    s = SHORT.mpc
    model = discretise(plant, q, s.sample_period_s)
    qp = CondensedQp(model, s)
    h, a = fns["matrices"](theta, q)
    _close(h, qp.h)
    _close(a, qp.a)
    obs = DisturbanceObserver(s.observer)
    obs.reset(model, 31.0, 205.0)
    z, d = fns["start"](theta, q, 31.0, 205.0)
    _close(z, obs.state)
    _close(d, obs.disturbance_mm)
    data = qp.data(MpcProblem(model, obs.state, obs.disturbance_mm, 215.0, 31.0, s))
    got = fns["vectors"](theta, q, obs.state, obs.disturbance_mm, 31.0, 215.0)
    for vector, want in zip(got, (data.g, data.lba, data.uba, data.lbx, data.ubx), strict=True):
        _close(vector, want)
    p0 = obs.covariance.copy()
    z1, d1, p1 = fns["correct"](theta, q, obs.state, obs.disturbance_mm, p0, 207.5)
    obs.correct(model, 207.5)
    _close(z1, obs.state)
    _close(d1, obs.disturbance_mm)
    _close(p1, obs.covariance)


def test_the_riccati_iteration_settles_on_scipys_steady_covariance(plant, functions):
    fns, theta = functions
    s = SHORT.mpc
    model = discretise(plant, 47.3, s.sample_period_s)
    p = np.zeros((model.n_states + 1,) * 2)
    for _ in range(10_000):  # the FMU's loop: until a step moves nothing by 1e-14 relative
        nxt = np.array(fns["riccati"](theta, 47.3, p))
        done = np.max(np.abs(nxt - p)) <= 1e-14 * np.max(np.abs(nxt))
        p = nxt
        if done:
            break
    # scipy's solver and the fixed point agree to the Riccati map's round-off
    _close(p, steady_prior_covariance(model, s.observer), rtol=1e-12)


def _loops(plant, fmu, scenario, settings):
    """Python MPC (DAQP) and the FMU, each on a fresh plant FMU."""
    controller = FmuController(fmu, settings.mpc.sample_period_s)
    try:
        with _PlantFactory(plant, "fmu", settings) as factory:
            python = _run_one(factory.make(), _controller("mpc", plant, settings), scenario,
                              settings)  # fmt: skip
            on_fmu = _run_one(factory.make(), controller, scenario, settings)
    finally:
        controller.cleanup()
    return python, on_fmu, np.asarray(controller.statuses)


def _assert_equal_runs(python, on_fmu, upto=None):
    stop = python.level_mm.size if upto is None else upto
    assert stop > 0
    assert np.max(np.abs(python.level_mm[:stop] - on_fmu.level_mm[:stop])) <= LOOP_TOL_MM
    assert np.max(np.abs(python.command_mm[:stop] - on_fmu.command_mm[:stop])) <= LOOP_TOL_MM


def _check_loops(plant, fmu, scenario, settings):
    """The FMU's loop equals the Python controller's, and its solver never gave up."""
    python, on_fmu, statuses = _loops(plant, fmu, scenario, settings)
    assert not np.any(statuses == 1.0)
    assert python.extra["solver_failures"] == 0
    _assert_equal_runs(python, on_fmu)
    assert np.ptp(on_fmu.command_mm) > 1.0  # the controller did move the gate


@pytest.mark.parametrize("index", [0, 1], ids=["setpoint_steps", "inflow_step"])
def test_closed_loop_on_the_fmu_equals_the_python_loop(plant, fmu, index):
    _check_loops(plant, fmu, demo_scenarios(4.0, SHORT)[index], SHORT)


@pytest.mark.long
@pytest.mark.slow
def test_closed_loop_equals_the_python_loop_at_the_demos_horizon(plant, tmp_path):
    from gatetwin.fmu.mpc_controller import export_mpc_controller

    demo = DemoSettings()
    path = export_mpc_controller(plant, tmp_path / "mpc100.fmu", settings=demo.mpc)
    for scenario in demo_scenarios(2.5, demo):
        _check_loops(plant, path, scenario, demo)


def _start(fmu, opening=25.0, level=190.0, flow=40.0):
    """The FMU initialised at rest, with a logger that keeps every message."""
    from fmpy import extract

    from fmu_support import open_fmu

    folder = extract(str(fmu))
    driver = open_fmu(folder)
    slave, vr = driver.slave, driver.vr
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([vr["start_opening_mm"], vr["level_3F_mm"], vr["flow_m3h"], vr["setpoint_mm"]],
                  [opening, level, flow, level])  # fmt: skip
    slave.exitInitializationMode()
    return slave, vr, driver.messages, folder


@contextlib.contextmanager
def _initialising(fmu):
    """The FMU instantiated and in initialisation mode (slave, value references, logged
    messages); freed and deleted afterwards."""
    from fmpy import extract

    from fmu_support import open_fmu

    folder = extract(str(fmu))
    driver = open_fmu(folder)
    try:
        driver.slave.setupExperiment(startTime=0.0)
        driver.slave.enterInitializationMode()
        yield driver.slave, driver.vr, driver.messages
    finally:
        driver.slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_before_initialisation_the_opening_is_the_start_opening_set(fmu):
    """A master propagating initial values (gatetwin's SSP master) reads the opening before
    the controller leaves initialisation mode: it must be the start opening set, as the
    PI's, not the start value it was built with."""
    with _initialising(fmu) as (slave, vr, _):
        built = slave.getReal([vr["opening_mm"]])[0]
        slave.setReal([vr["start_opening_mm"]], [built + 7.0])
        assert slave.getReal([vr["opening_mm"]]) == [built + 7.0]


def test_a_nan_level_is_refused_with_a_logged_reason(fmu):
    from fmpy.fmi1 import FMICallException

    slave, vr, logged, folder = _start(fmu)
    try:
        with pytest.raises(FMICallException):
            slave.setReal([vr["level_3F_mm"]], [float("nan")])
        assert any("level_3F_mm" in m and "not finite" in m for _, m in logged), logged
    finally:
        slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_a_solver_that_does_not_converge_holds_the_opening_and_says_so(plant, tmp_path):
    from gatetwin.fmu.mpc_controller import export_mpc_controller

    fmu = export_mpc_controller(plant, tmp_path / "one_iteration.fmu", settings=SHORT.mpc,
                                max_iter=1)  # fmt: skip
    slave, vr, _, folder = _start(fmu, opening=25.0, level=190.0)
    try:
        # a 20 mm set-point step: the plan runs into the rate limit at many samples, i.e.
        # many active bounds, each one iteration from the unconstrained minimum
        slave.setReal([vr["setpoint_mm"]], [210.0])
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=SHORT.mpc.sample_period_s)
        names = ["opening_mm", "solver_status", "solver_iterations"]
        opening, status, iterations = slave.getReal([vr[n] for n in names])
        assert (opening, status, iterations) == (25.0, 1.0, 1.0)
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_a_set_point_outside_the_level_band_is_warned_about_once_per_value(fmu):
    """fmi2Warning with the reason at the first step with such a set-point and at each change
    of it, nothing while it is held or back inside the band; the QP is solved throughout."""
    from fmpy.fmi2 import fmi2OK, fmi2Warning

    slave, vr, logged, folder = _start(fmu)
    ts = SHORT.mpc.sample_period_s
    try:
        statuses = []
        for k, r in enumerate([1e6, 1e6, 2e6, 200.0, 1e6]):
            slave.setReal([vr["setpoint_mm"]], [r])
            statuses.append(slave.fmi2DoStep(slave.component, k * ts, ts, 1))
            assert slave.getReal([vr["solver_status"]]) == [0.0]
        assert statuses == [fmi2Warning, fmi2OK, fmi2Warning, fmi2OK, fmi2Warning]
        warned = [m for _, m in logged if "outside the level band" in m]
        assert len(warned) == 3 and "setpoint_mm = 2000000" in warned[1]
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_what_the_controller_fmu_does_not_cover_is_refused(plant, tmp_path):
    from gatetwin.fmu.mpc_controller import export_mpc_controller

    rate = {"kind": "actuator_rate_limit", "rate_mm_per_s": 1.0}
    with_block = replace(plant, effects=(rate,))
    with pytest.raises(ExportError, match="effect blocks"):
        export_mpc_controller(with_block, tmp_path / "x.fmu", settings=SHORT.mpc)
    with pytest.raises(ExportError, match="level band"):
        export_mpc_controller(plant, tmp_path / "x.fmu",
                              settings=replace(SHORT.mpc, level_band_mm=None))  # fmt: skip
    assert not list(tmp_path.iterdir())  # no partial output


def test_a_restored_state_repeats_the_same_steps(fmu):
    slave, vr, _, folder = _start(fmu)
    ts = SHORT.mpc.sample_period_s
    outputs = [vr[n] for n in ("opening_mm", "predicted_level_mm", "solver_iterations")]

    def run(t0, n):
        rows = []
        for k in range(n):
            slave.setReal([vr["level_3F_mm"], vr["setpoint_mm"]], [190.0 + 0.4 * k, 205.0])
            slave.doStep(currentCommunicationPoint=t0 + k * ts, communicationStepSize=ts)
            rows.append(slave.getReal(outputs))
        return np.array(rows)

    try:
        run(0.0, 3)
        state = slave.getFMUstate()
        serialized = slave.serializeFMUstate(state)
        first = run(3 * ts, 5)
        slave.setFMUstate(state)
        again = run(3 * ts, 5)
        slave.setFMUstate(slave.deSerializeFMUstate(serialized))
        restored = run(3 * ts, 5)
        slave.freeFMUstate(state)
        # the same instance from the same state: the same arithmetic, bit for bit
        assert np.array_equal(first, again) and np.array_equal(first, restored)
        assert np.ptp(first[:, 0]) > 0.0  # the opening moved
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_a_dead_time_beyond_the_generated_register_is_refused_at_initialisation(fmu):
    from fmpy.fmi1 import FMICallException

    with _initialising(fmu) as (slave, vr, logged):
        slave.setReal([vr["schedule.dead_time_s[2]"]], [60.0])  # the register holds ~3.6 s
        with pytest.raises(FMICallException):
            slave.exitInitializationMode()
        assert any("schedule.dead_time_s[2]" in m for _, m in logged), logged


def test_export_controller_builds_the_mpc_from_a_model_file(tmp_path, capsys):
    """The command line's ``--kind mpc`` (at a short horizon, to keep the build quick) writes
    the same kind of FMU: valid, with the MPC's diagnostic outputs; the bundled model's
    seiche block is refused unless dropped on purpose."""
    from pathlib import Path

    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from gatetwin.cli import main

    model = Path(__file__).resolve().parents[2] / "models" / "fopdt_3F.json"
    out = tmp_path / "mpc.fmu"
    args = ["export-controller", str(model), "--kind", "mpc", "--horizon", "20", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "effect blocks are not covered" in err and "--without-effects" in err
    assert not out.exists()
    assert main([*args, "--without-effects"]) == 0
    assert str(out) in capsys.readouterr().out
    assert validate_fmu(str(out)) == []
    outputs = {v.name for v in read_model_description(str(out)).modelVariables
               if v.causality == "output"}  # fmt: skip
    assert {"opening_mm", "solver_status", "solver_iterations"} <= outputs
    three = tmp_path / "mpc3.fmu"
    assert main([*args[:-1], str(three), "--without-effects", "--fmi", "3"]) == 0
    assert read_model_description(str(three)).fmiVersion == "3.0"
    assert validate_fmu(str(three)) == []


def test_the_benchmarks_c_host_builds_and_steps_the_fmu(fmu, tmp_path):
    """``benchmarks/bench_controller_fmu.py``'s C host compiles against the FMU's sources and
    steps it in its closed loop (a short run: what the benchmark measures stays buildable)."""
    import importlib.util

    from fmpy import extract

    path = Path(__file__).resolve().parents[2] / "benchmarks/bench_controller_fmu.py"
    spec = importlib.util.spec_from_file_location("bench_controller_fmu", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    extracted = Path(extract(str(fmu), str(tmp_path / "x")))
    bench.build_host(extracted / "sources", tmp_path / "host")
    got = bench.run_host(tmp_path / "host", extracted, 300)
    assert got["fallbacks"] == 0.0
    assert 0.0 < got["p50_ns"] <= got["p99_ns"] <= got["max_ns"]
    assert got["active_share"] > 0.0  # the set-point steps drive the constraints
    assert got["heap_during_steps_bytes"] == 0.0


def test_export_controller_takes_the_gates_opening_range(tmp_path, capsys):
    """``--opening-range`` widens the controller's openings past the model's validity (an
    inflow step may need more); an empty, inverted or non-finite range is refused in one
    line and nothing is written."""
    from pathlib import Path

    from fmpy import read_model_description

    from gatetwin.cli import main

    model = Path(__file__).resolve().parents[2] / "models" / "fopdt_3F.json"
    out = tmp_path / "pi.fmu"
    for bad in (["5", "-1"], ["5", "5"], ["0", "nan"], ["0", "1e9"]):
        assert main(["export-controller", str(model), "--opening-range", *bad, "--out",
                     str(out)]) == 2  # fmt: skip
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--opening-range" in err[0], err
        assert not out.exists()
    assert main(["export-controller", str(model), "--opening-range", "0", "300", "--out",
                 str(out)]) == 0  # fmt: skip
    start = {v.name: float(v.start) for v in read_model_description(str(out)).modelVariables
             if v.causality == "parameter"}  # fmt: skip
    assert (start["opening_min_mm"], start["opening_max_mm"]) == (0.0, 300.0)
