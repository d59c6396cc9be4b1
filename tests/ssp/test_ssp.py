"""The closed loop as an SSP: the package follows the SSP 1.0 schemas, gatetwin's master runs
it as the Python loop runs the PI on the same plant FMU, fmpy's own SSP simulation reads it,
and bad packages are refused in one line without output."""

from __future__ import annotations

import math
import re
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmu_support import compiler, fmpy_ssp_runner_from_start_values, with_zip_bomb
from gatetwin.cli import main
from gatetwin.errors import ExportError, SspError
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.demo import DemoSettings, demo_scenarios
from gatetwin.mpc.loop import loop_metrics
from gatetwin.ssp import simulate_ssp, write_ssp
from gatetwin.ssp.documents import SSD_SCHEMA, SSV_SCHEMA, read_parameter_set, schema_problems
from gatetwin.ssp.master import MAX_STEPS, read_ssd
from gatetwin.ssp.reference import python_loop
from gatetwin.ssp.write import (
    CONTROLLER_SOURCE,
    OBSERVER_SOURCE,
    PARAMETERS_SOURCE,
    SCENARIO_SOURCE,
    SSD_NAME,
)
from hostile_fmus import build_hostile

MODELS = Path(__file__).resolve().parents[2] / "models"
MODEL = MODELS / "fopdt_3F.json"
#: Same operations in the same order in both loops (the PI's C is generated from the Python,
#: -ffp-contract=off; the plant FMU is the same file): equal to the bit; 1e-9 leaves room only
#: for a compiler ordering a library call differently.
SAME_ARITHMETIC = 1e-9
MINUTES = 30.0


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ssp")
    out = folder / "loop.ssp"
    assert main(["ssp", str(MODEL), "--out", str(out), "--minutes", str(MINUTES)]) == 0
    return out


def _read(package: Path, name: str) -> bytes:
    with zipfile.ZipFile(package) as zf:
        return zf.read(name)


def test_the_ssd_and_the_parameter_set_follow_the_ssp_1_0_schemas(package):
    assert schema_problems(_read(package, SSD_NAME), SSD_SCHEMA) == []
    assert schema_problems(_read(package, PARAMETERS_SOURCE), SSV_SCHEMA) == []
    broken = _read(package, SSD_NAME).replace(b'kind="input"', b'kind="sideways"', 1)
    assert schema_problems(broken, SSD_SCHEMA)  # the check can fail


def _python_loop(package: Path, tmp_path: Path):
    """PiController against the package's own plant FMU, noise-free, no actuator rounding:
    the loop the SSP describes."""
    s = DemoSettings()
    return python_loop(package, read_model_file(MODEL).plant, demo_scenarios(MINUTES, s)[0], s)


def test_the_ssp_run_is_the_python_loop(package, tmp_path, capsys):
    csv = tmp_path / "result.csv"
    assert main(["simulate-ssp", str(package), "--out", str(csv)]) == 0
    assert "closed-loop IAE" in capsys.readouterr().out
    table = np.genfromtxt(csv, delimiter=",", names=True)
    run = simulate_ssp(package)
    python = _python_loop(package, tmp_path)
    assert np.array_equal(table["plantopening_mm"], run.columns["plant.opening_mm"])
    level, setpoint = run.columns["controller.level_3F_mm"], run.columns["controller.setpoint_mm"]
    assert np.max(np.abs(python.command_mm - run.columns["plant.opening_mm"])) <= SAME_ARITHMETIC
    assert np.max(np.abs(python.level_mm - level)) <= SAME_ARITHMETIC
    assert np.max(np.abs(python.setpoint_mm - setpoint)) <= SAME_ARITHMETIC
    assert np.ptp(setpoint) > 30 and np.ptp(run.columns["plant.opening_mm"]) > 1  # it acts
    iae = run.iae("controller.level_3F_mm", "controller.setpoint_mm")
    # the same doubles summed in the same order (numpy's sum of |level - set-point|, times Ts)
    assert abs(iae - loop_metrics(python)["iae"]) <= SAME_ARITHMETIC


@pytest.fixture(scope="module")
def jacobi_run(package):
    return simulate_ssp(package, scheme="jacobi")


def _connector_kinds(package: Path) -> dict[str, str]:
    """``{"<element>.<connector>": kind}`` of the package's components."""
    system = read_ssd(_read(package, SSD_NAME), "test")
    return {f"{c.name}.{n}": kind for c in system.components for n, kind in c.connectors.items()}


def test_the_jacobi_scheme_gives_the_move_to_the_plant_a_sample_later(package, jacobi_run):
    """Under Jacobi the plant receives at t_(k+1) the opening the controller computed from
    what it received at t_k: the Python PI fed the run's logged controller inputs gives the
    plant's logged openings one sample later, to the bit."""
    from gatetwin.mpc.demo import pi_controller

    s = DemoSettings()
    pi = pi_controller(read_model_file(MODEL).plant, s)
    level, flow, setpoint = (jacobi_run.columns[f"controller.{n}"]
                             for n in ("level_3F_mm", "flow_m3h", "setpoint_mm"))  # fmt: skip
    opening = jacobi_run.columns["plant.opening_mm"]
    pi.reset(opening[0], level[0], flow[0])
    moves = np.array([pi.step(level[k], flow[k], setpoint[k]) for k in range(level.size - 1)])
    assert np.max(np.abs(moves - opening[1:])) <= SAME_ARITHMETIC
    assert np.ptp(opening) > 1.0  # the gate moved
    gauss_seidel = simulate_ssp(package).columns["plant.opening_mm"]
    assert not np.array_equal(opening, gauss_seidel)  # the schemes differ on this loop


def test_fmpys_ssp_runner_gives_the_jacobi_run(package, jacobi_run, monkeypatch):
    """fmpy's own runner reads the package with nothing but its path and the experiment's
    length: it steps every FMU on the values of the last point (Jacobi) and applies no
    parameter set, which changes nothing here (every value in the set is the FMU's start
    value). Its one departure from the Jacobi master is at the first step: it starts every
    connector at 0.0 (``fmpy/ssp/simulation.py``, "initialize the connectors") instead of
    the values the FMUs hold after initialisation, so the plant gets a closed gate and no
    inflow for 1.2 s. With that one step given the start values the package sets (each
    input's start value is what its source gives at the start), the runs are equal to the
    bit: the same FMU binaries given the same doubles in the same order (each FMU keeps its
    own time; the engines' communication points only have to pass its check)."""
    import fmpy.ssp.simulation as runner

    fmpy_ssp_runner_from_start_values(monkeypatch)
    out = runner.simulate_ssp(str(package), stop_time=MINUTES * 60, step_size=1.2)
    n = jacobi_run.time_s.size
    assert len(out) == n
    kinds = _connector_kinds(package)
    compared = 0
    for name, column in jacobi_run.columns.items():
        # fmpy's row k holds the connectors after the step from t_k: an input as it goes
        # into the step from t_(k+1)
        if kinds[name] == "input":
            assert np.array_equal(out[name][:-1], column[1:]), name
            compared += 1
    assert compared == 5 and np.ptp(out["plant.opening_mm"]) > 1  # every input, and it acts


def test_ecos_runs_the_package_as_the_jacobi_master(package, jacobi_run):
    """ecos (``ecospy``) runs the package as it is: Jacobi, from the values the FMUs hold
    after initialisation; every input of every component and every monitored output equal
    to the bit (the same binaries given the same doubles in the same order)."""
    _compare_ecos(package, jacobi_run)


def _compare_ecos(package: Path, run) -> None:
    from ecos_support import load_ecospy

    ecospy = load_ecospy()
    kinds = _connector_kinds(package)
    names = list(run.columns)
    with ecospy.EcosSimulation(step_size=run.step_s, ssp_path=str(package)) as sim:
        assert sim.init(), "ecos could not initialise the package"
        rows = [[sim.get_real(n.replace(".", "::", 1)) for n in names]]
        for _ in range(run.time_s.size):
            sim.step()
            rows.append([sim.get_real(n.replace(".", "::", 1)) for n in names])
        sim.terminate()
    got = np.array(rows)
    for i, name in enumerate(names):
        # row k: after k steps; an input then holds what goes into the step from t_k, an
        # output what the step from t_(k-1) gave
        ours = got[:-1, i] if kinds[name] == "input" else got[1:, i]
        assert np.array_equal(ours, run.columns[name]), name


def _scenario_run(fmu: Path, stop_s: float, **start_values: float):
    """fmpy's run of a scenario FMU at 1.2 s steps; ``(result, logged messages)``."""
    from fmpy import simulate_fmu

    messages: list[str] = []

    def logger(_env, _name, _status, _category, message):
        messages.append(message.decode() if isinstance(message, bytes) else str(message))

    try:
        out = simulate_fmu(str(fmu), stop_time=stop_s, step_size=1.2, output_interval=1.2,
                           start_values=start_values, debug_logging=True,
                           logger=logger)  # fmt: skip
    except Exception as exc:  # noqa: BLE001 - fmpy's FMICallException
        return exc, messages
    return out, messages


def test_the_scenario_fmu_gives_its_tables(tmp_path):
    """The scenario FMU's outputs are :func:`signal_value` of its tables at each point (the
    C is generated from it), held or linear; tables it cannot run are refused by the
    export in one line naming the knot, and by the FMU (an FMI error, the reason logged)
    when a parameter set breaks them."""
    from gatetwin.fmu.signal_source import TableSignal, export_signal_source
    from gatetwin.mpc.signal_law import TIME_TOL_S, signal_value

    held = TableSignal("setpoint_mm", "mm", (0.0, 6.0, 12.0), (100.0, 110.0, 90.0))
    ramp = TableSignal("flow_m3h", "m3/h", (1.0, 10.0), (50.0, 60.0), linear=True)
    fmu = export_signal_source([held, ramp], tmp_path / "s.fmu", step_size_s=1.2)
    out, _ = _scenario_run(fmu, 14.4)
    for sig in (held, ramp):
        want = [signal_value(t, list(sig.times_s), list(sig.values), len(sig.times_s),
                             float(sig.linear), TIME_TOL_S) for t in out["time"]]  # fmt: skip
        assert np.array_equal(out[sig.name], want), sig.name
    assert list(out["setpoint_mm"][:7]) == [100.0] * 5 + [110.0] * 2
    assert out["flow_m3h"][0] == 50.0 and out["flow_m3h"][-1] == 60.0  # held outside
    assert 50.0 < out["flow_m3h"][4] < 60.0  # linear between the knots
    for bad, match in (
        (TableSignal("x", "mm", (0.0, 0.0), (1.0, 2.0)), r"time 2 \(0.0 s\) must lie after"),
        (TableSignal("x", "mm", (0.0,), (math.nan,)), "knot 1 .* is not finite"),
        (TableSignal("x", "mm", (0.0, 5e9), (1.0, 2.0)), "x_table.time_s.2. = 5e.09 is beyond"),
    ):
        with pytest.raises(ExportError, match=match):
            export_signal_source([bad], tmp_path / "x.fmu", step_size_s=1.0)
    with pytest.raises(ExportError, match="names signal x twice"):
        export_signal_source([TableSignal("x", "mm", (0.0,), (1.0,))] * 2,
                             tmp_path / "x.fmu", step_size_s=1.0)  # fmt: skip
    assert not (tmp_path / "x.fmu").exists()
    for name, value, reason in (
        ("setpoint_mm_table.time_s[2]", 20.0, r"time_s.3. = 12 s must lie after \S+.2. = 20 s"),
        ("setpoint_mm_table.linear", 0.5, "must be 0 .held. or 1 .linear."),
        ("setpoint_mm_table.value[1]", 1e300, "must be finite with"),
    ):
        failed, messages = _scenario_run(fmu, 2.4, **{name: value})
        assert isinstance(failed, Exception), name
        assert any(re.search(reason, m) for m in messages), (name, messages)


def test_a_knot_is_reached_on_a_point_formed_as_a_running_sum():
    """The knot rule is relative: a knot at a communication point is in force there whether
    the point is k h or a running sum of h, which lags k h by more than 1e-9 s after a few
    ten thousand steps of 1.2 s (the FMUs count their time so)."""
    from gatetwin.mpc.signal_law import TIME_TOL_S, in_force

    steps, h = 36_000, 1.2
    summed = 0.0
    for _ in range(steps):
        summed += h
    knot = steps * h
    assert knot - summed > TIME_TOL_S  # an absolute 1e-9 s would miss this point
    assert in_force(knot, summed, TIME_TOL_S) == 1.0
    assert in_force(knot, knot, TIME_TOL_S) == 1.0
    assert in_force(knot, knot - h, TIME_TOL_S) == 0.0  # not a step early
    # the relative margin: in force just within it, not just beyond it
    margin = TIME_TOL_S * knot
    assert in_force(knot, knot - 0.5 * margin, TIME_TOL_S) == 1.0
    assert in_force(knot, knot - 2.0 * margin, TIME_TOL_S) == 0.0


def test_every_parameter_in_the_set_is_its_fmus_start_value(tmp_path):
    """An engine that applies no parameter set (ecos applies only bindings on components;
    FMPy none unless given) runs the same loop: every value of the set is the start value
    of the FMU it names, also for a scenario that starts elsewhere than the demo's point."""
    from dataclasses import replace

    from fmpy import read_model_description

    scn = replace(demo_scenarios(6.0, DemoSettings())[0], opening_mm=30.0)
    out = write_ssp(read_model_file(MODEL), tmp_path / "loop.ssp", scenario=scn)
    parameters = read_parameter_set(_read(out, PARAMETERS_SOURCE), "ssv")
    folder = tmp_path / "x"
    with zipfile.ZipFile(out) as zf:
        zf.extractall(folder)
    starts = {}
    for element, source in (("controller", CONTROLLER_SOURCE), ("scenario", SCENARIO_SOURCE),
                            ("plant", "resources/plant.fmu")):  # fmt: skip
        md = read_model_description(str(folder / source))
        starts.update({f"{element}.{v.name}": float(v.start) for v in md.modelVariables
                       if v.start is not None})  # fmt: skip
    assert parameters and all(starts[n] == v for n, v in parameters.items()), [
        n for n, v in parameters.items() if starts.get(n) != v]  # fmt: skip
    assert starts["controller.start_opening_mm"] == 30.0 == starts["plant.opening_mm"]


def test_bad_packages_and_requests_are_one_line_without_output(package, tmp_path, capsys):
    not_zip = tmp_path / "not.ssp"
    not_zip.write_text("hello", encoding="utf-8")
    no_ssd = tmp_path / "no_ssd.ssp"
    with zipfile.ZipFile(no_ssd, "w") as zf:
        zf.writestr("other.txt", "x")
    bad_ssd = tmp_path / "bad_ssd.ssp"
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(bad_ssd, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            dst.writestr(item, data.replace(b"resources/plant.fmu", b"../plant.fmu")
                         if item.filename == SSD_NAME else data)  # fmt: skip
    for bad in (not_zip, no_ssd, bad_ssd, tmp_path / "missing.ssp"):
        out = tmp_path / "r.csv"
        assert main(["simulate-ssp", str(bad), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("gatetwin: error:") and str(bad) in err[0]
        assert not out.exists()
    for argv in (
        ["--controller", "mpc"],
        ["--observer"],
        ["--horizon", "20"],
        ["--controller", "mpc", "--horizon", "0", "--without-effects"],
    ):
        assert main(["ssp", str(MODEL), "--out", str(tmp_path / "m.ssp"), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("gatetwin: error:"), (argv, err)
        assert not (tmp_path / "m.ssp").exists()
    # too many steps: refused in one short line (the count was printed with all its digits)
    assert main(["simulate-ssp", str(package), "--out", str(tmp_path / "r.csv"),
                 "--step-size", "1e-300"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "need 1 to" in err[0] and len(err[0]) < 300, err
    assert not (tmp_path / "r.csv").exists()
    # a scenario longer than simulate-ssp runs is refused when the package would be written:
    # far longer, and one step longer (at the PI's 1.2 s)
    for minutes in ("1e9", f"{(MAX_STEPS + 1) * 1.2 / 60:.17g}"):
        assert main(["ssp", str(MODEL), "--out", str(tmp_path / "m.ssp"),
                     "--minutes", minutes]) == 2  # fmt: skip
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "simulate-ssp runs at most" in err[0] and len(err[0]) < 200, err
        assert not (tmp_path / "m.ssp").exists()
    assert main(["ssp", str(MODELS / "arx_3F.json"), "--out", str(tmp_path / "m.ssp"),
                 "--controller", "mpc", "--without-effects"]) == 2  # fmt: skip
    assert "FOPDT" in capsys.readouterr().err and not (tmp_path / "m.ssp").exists()
    with pytest.raises(ExportError, match="must end in .ssp"):
        write_ssp(read_model_file(MODEL), tmp_path / "loop.zip")


def _repacked(package: Path, dst: Path, change) -> Path:
    """``package`` with each member's bytes passed through ``change(name, data)``."""
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(dst, "w") as out:
        for item in src.infolist():
            out.writestr(item, change(item.filename, src.read(item)))
    return dst


def _refused_line(package: Path, tmp_path: Path, capsys) -> str:
    """simulate-ssp on ``package``: exit 2, one error line (returned), no CSV."""
    out = tmp_path / "r.csv"
    assert main(["simulate-ssp", str(package), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gatetwin: error:"), err
    assert not out.exists()
    return err[0]


def test_system_connectors_and_an_unknown_scheme_are_refused_in_one_line(package, tmp_path,
                                                                         capsys):  # fmt: skip
    """What drives the loop must be a component: a system input, or a connection to a system
    connector, is refused (nothing would give it a value); so is a scheme the master lacks."""
    ssd = _read(package, SSD_NAME)
    system_input = ssd.replace(
        b"<ssd:ParameterBindings>",
        b'<ssd:Connectors><ssd:Connector name="setpoint_mm" kind="input"><ssc:Real/>'
        b"</ssd:Connector></ssd:Connectors><ssd:ParameterBindings>", 1)  # fmt: skip
    to_system = ssd.replace(b'startElement="scenario" ', b"", 1)
    assert system_input != ssd and to_system != ssd
    for body, reason in ((system_input, "system input setpoint_mm has no value here"),
                         (to_system, "joins a system connector")):  # fmt: skip
        changed = _repacked(package, tmp_path / "changed.ssp",
                            lambda name, data, body=body: (
                                body if name == SSD_NAME else data))  # fmt: skip
        assert reason in _refused_line(changed, tmp_path, capsys)
    with pytest.raises(SspError, match="scheme 'seidel' is not one of gauss-seidel, jacobi"):
        simulate_ssp(package, scheme="seidel")


def test_two_components_of_one_name_are_refused_before_any_is_instantiated(package, tmp_path,
                                                                          capsys):  # fmt: skip
    twins = _repacked(
        package,
        tmp_path / "twins.ssp",
        lambda name, data: (
            data.replace(b'Component name="controller"', b'Component name="plant"')
            if name == SSD_NAME
            else data
        ),
    )
    assert "two components are named 'plant'" in _refused_line(twins, tmp_path, capsys)


def test_an_fmu_that_unpacks_past_the_limit_is_refused_before_it_is_unpacked(package, tmp_path,
                                                                            capsys):  # fmt: skip
    plant = tmp_path / "plant.fmu"
    plant.write_bytes(_read(package, "resources/plant.fmu"))
    bomb = with_zip_bomb(plant, tmp_path / "bomb.fmu").read_bytes()
    bombed = _repacked(
        package,
        tmp_path / "bombed.ssp",
        lambda name, data: bomb if name == "resources/plant.fmu" else data,
    )
    line = _refused_line(bombed, tmp_path, capsys)
    assert "component plant: its members unpack to" in line


#: Where a hostile plant (tests/hostile_fmus.py, misbehaving after its tenth step
#: whatever the inflow) stops in the loop: its eleventh step, from t = 10 × 1.2 s.
HOSTILE_AT = r"at t = 12 s \(communication step 10, component plant\)"
#: The per-call limit the hostile runs get, s (a step of these FMUs takes microseconds).
HOSTILE_TIMEOUT_S = 2.0
HOSTILE_CAUSES = {
    "exit": rf"the FMU called exit\(0\) during fmi2DoStep {HOSTILE_AT}",
    "abort": rf"the FMU process died with signal 6 \(SIGABRT\) during fmi2DoStep {HOSTILE_AT}",
    "null_write": rf"the FMU process died with signal 11 \(SIGSEGV\) during fmi2DoStep "
    rf"{HOSTILE_AT}",
    "hang": rf"no FMI call returned within {HOSTILE_TIMEOUT_S:g} s \(the FMU was in fmi2DoStep "
    rf"{HOSTILE_AT}\); its process was killed",
    # read at the end of that step
    "nan": r"output level_3F_mm not finite \(nan\) at t = 12 s \(communication step 10, "
    r"component plant\)",
}


@pytest.mark.skipif(compiler() is None, reason="no C compiler (cc/gcc) on PATH")
@pytest.mark.parametrize("kind", sorted(HOSTILE_CAUSES))
def test_a_plant_that_exits_crashes_hangs_or_gives_nan_ends_the_run_in_one_line(
    kind, package, tmp_path, capsys
):
    """The master runs the FMUs in a child process: whatever the plant does, simulate-ssp
    exits 2 with the cause, the component, the call and the time in one line, no CSV."""
    plant = tmp_path / "plant.fmu"
    plant.write_bytes(_read(package, "resources/plant.fmu"))
    hostile = build_hostile(plant, kind, tmp_path, flow_above=0.0).read_bytes()
    loop = _repacked(
        package,
        tmp_path / f"{kind}.ssp",
        lambda name, data: hostile if name == "resources/plant.fmu" else data,
    )
    out = tmp_path / "r.csv"
    code = main(["simulate-ssp", str(loop), "--out", str(out),
                 "--timeout", str(HOSTILE_TIMEOUT_S)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert re.fullmatch(rf"gatetwin: error: {re.escape(str(loop))}: {HOSTILE_CAUSES[kind]}",
                        err[0]), err[0]  # fmt: skip
    assert not out.exists()


def test_an_fmus_refusal_is_one_line_with_its_logged_reason(package, tmp_path, capsys):
    """A controller refusing a negative integral time names the call, where, and why."""
    assert b'value="4.8" unit="s"' in _read(package, PARAMETERS_SOURCE)
    negative = _repacked(package, tmp_path / "negative.ssp", lambda name, data: (
        data.replace(b'value="4.8" unit="s"', b'value="-4.8" unit="s"')
        if name == PARAMETERS_SOURCE else data))  # fmt: skip
    line = _refused_line(negative, tmp_path, capsys)
    assert "component controller" in line and "FMU log:" in line, line


#: A per-call limit far above one call of these FMUs (microseconds) and the child's start
#: (milliseconds), far below the long run's length, s.
PER_CALL_LIMIT_S = 0.5


def test_a_long_run_of_quick_calls_is_not_cut_by_the_per_call_limit(tmp_path):
    """The limit bounds each call, not the run: a run several limits long passes and gives
    the unprotected run's values. (1,200 minutes: 600 ran in 1.0 s on a quiet machine, at
    the edge of the two limits the run must outlast.)"""
    long_loop = tmp_path / "long.ssp"
    assert main(["ssp", str(MODEL), "--out", str(long_loop), "--minutes", "1200"]) == 0
    start = time.perf_counter()
    unprotected = simulate_ssp(long_loop, isolate=False)
    assert time.perf_counter() - start > 2 * PER_CALL_LIMIT_S  # a run longer than the limit
    isolated = simulate_ssp(long_loop, timeout_s=PER_CALL_LIMIT_S)
    assert list(isolated.columns) == list(unprotected.columns)
    for name, values in unprotected.columns.items():
        assert np.array_equal(isolated.columns[name], values), name


#: The MPC package: a short horizon keeps the build to seconds (the demo's N = 100 takes
#: ~30 s), a short scenario keeps the Python MPC's run to seconds.
MPC_HORIZON = 20
MPC_MINUTES = 6.0
#: The MPC FMU against the Python MPC (the FMU's dense active-set solver and DAQP): the
#: same QP from the same data solved to its unique solution, so the openings agree to the
#: QP's round-off (~1e-13 mm measured
#: on the FMU alone; here, the plant's seiche exciting the loop, isolated samples reach 3e-10
#: mm: round-off amplified by the QP's conditioning, not a drift that grows); 1e-9 mm is far
#: below the actuator's 1 mm resolution.
MPC_LOOP_TOL_MM = 1e-9
#: The observer FMU against OnlineObserver: the same arithmetic generated by casadi, without
#: FMA; what is left is the order of a few sums (round-off ~1e-13 mm on ~200 mm levels).
OBSERVER_TOL = 1e-9


@pytest.fixture(scope="module")
def mpc_package(tmp_path_factory):
    out = tmp_path_factory.mktemp("ssp_mpc") / "mpc_loop.ssp"
    assert main(["ssp", str(MODEL), "--out", str(out), "--controller", "mpc", "--observer",
                 "--without-effects", "--horizon", str(MPC_HORIZON),
                 "--minutes", str(MPC_MINUTES)]) == 0  # fmt: skip
    return out


@pytest.fixture(scope="module")
def mpc_run(mpc_package):
    return simulate_ssp(mpc_package)


def test_the_mpc_and_observer_ssd_follows_the_ssp_1_0_schema(mpc_package):
    from fmpy import read_model_description

    ssd = _read(mpc_package, SSD_NAME)
    assert schema_problems(ssd, SSD_SCHEMA) == []
    assert schema_problems(_read(mpc_package, PARAMETERS_SOURCE), SSV_SCHEMA) == []
    with zipfile.ZipFile(mpc_package) as zf:
        names = set(zf.namelist())
        folder = Path(str(mpc_package) + ".x")
        zf.extractall(folder)
    assert {CONTROLLER_SOURCE, OBSERVER_SOURCE} <= names
    controller = read_model_description(str(folder / CONTROLLER_SOURCE))
    assert "solver_status" in {v.name for v in controller.modelVariables}
    assert b'name="observer"' in ssd


def test_the_mpc_ssp_run_is_the_python_mpc_loop(mpc_package, mpc_run):
    import dataclasses

    from gatetwin.mpc.settings import MpcSettings

    run = mpc_run
    s = DemoSettings(mpc=MpcSettings(horizon=MPC_HORIZON))
    covered = dataclasses.replace(read_model_file(MODEL).plant, effects=())
    python = python_loop(mpc_package, covered, demo_scenarios(MPC_MINUTES, s)[0], s,
                         controller="mpc")  # fmt: skip
    opening, level = run.columns["plant.opening_mm"], run.columns["controller.level_3F_mm"]
    assert np.max(np.abs(python.command_mm - opening)) <= MPC_LOOP_TOL_MM
    assert np.max(np.abs(python.level_mm - level)) <= MPC_LOOP_TOL_MM
    assert np.max(np.abs(python.setpoint_mm - run.columns["controller.setpoint_mm"])) == 0.0
    assert np.ptp(opening) > 1.0  # the MPC moved the gate


def test_the_observer_in_the_ssp_logs_the_python_observers_estimates(mpc_package, mpc_run):
    """The observer's logged outputs are OnlineObserver's on the inputs it was given, started
    at rest at the start opening (what it was initialised with)."""
    import dataclasses

    from gatetwin.mpc.online import OUTPUTS, OnlineObserver

    run = mpc_run
    y, e, q = (run.columns[f"observer.{n}"] for n in ("level_3F_mm", "opening_mm", "flow_m3h"))
    assert np.array_equal(y, run.columns["controller.level_3F_mm"])
    assert np.array_equal(e, run.columns["plant.opening_mm"])  # the opening held from t_k
    covered = dataclasses.replace(read_model_file(MODEL).plant, effects=())
    observer = OnlineObserver(covered)
    start = read_parameter_set(_read(mpc_package, PARAMETERS_SOURCE), "ssv")
    observer.reset(start["controller.start_opening_mm"], y[0], q[0])
    ref = np.array([observer.step(y[k], e[k], q[k]).values() for k in range(y.size)])
    for i, name in enumerate(OUTPUTS):
        got = run.columns[f"observer.{name}"]
        assert np.max(np.abs(got - ref[:, i])) <= OBSERVER_TOL, name
    assert np.ptp(run.columns["observer.innovation_mm"]) > 0.1  # the set-point steps move it


def test_ecos_runs_the_mpc_and_observer_package_as_the_jacobi_master(mpc_package):
    """The MPC controller, the observer (a monitor: its outputs compared too), the plant and
    the scenario in ecos: the Jacobi master's run to the bit."""
    run = simulate_ssp(mpc_package, scheme="jacobi")
    assert any(name.startswith("observer.") for name in run.columns)
    _compare_ecos(mpc_package, run)


def _field_fopdt(tmp_path: Path) -> Path:
    """fopdt_3F's schedule carried to a field gate: discharges ×600 (5-14 m³/s), levels ×10,
    openings ×20, time constants ×60 (an hour), 60 s records with 3 mm of gauge noise; no
    envelope and no effect blocks (the gate law is the flume's)."""
    import json

    doc = json.loads(MODEL.read_text(encoding="utf-8"))
    plant, sched = doc["plant"], doc["plant"]["schedule"]
    sched["flow_m3h"] = [600.0 * q for q in sched["flow_m3h"]]
    sched["level_ref_mm"] = [10.0 * h for h in sched["level_ref_mm"]]
    sched["time_constant_s"] = [60.0 * t for t in sched["time_constant_s"]]
    sched["gain_mm_per_mm"] = [k / 2.0 for k in sched["gain_mm_per_mm"]]
    plant["opening_ref_mm"] *= 20.0
    plant.pop("envelope"), plant.pop("effects")
    doc["operating_point"] = {"opening_ref_mm": plant["opening_ref_mm"],
                              "level_ref_mm": sched["level_ref_mm"],
                              "flow_m3h": sched["flow_m3h"]}  # fmt: skip
    doc["validity"] = {"flow_m3h": [600.0 * 20.0, 600.0 * 90.0],
                       "opening_range_mm": [200.0, 1600.0], "level_range_mm": [940.0, 3720.0],
                       "sample_period_s": 60.0, "level_noise_sd_mm": 3.0}  # fmt: skip
    path = tmp_path / "fopdt_field.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_the_loop_of_a_field_model_is_its_own(tmp_path, capsys):
    """A gate whose validity does not hold the flume demo's operating point (40 m³/h, 25 mm)
    gets a loop sized from its model file: its sample period, the middle of its discharge
    range, set-point steps of a tenth of its level band inside that band, and a run of six
    MPC horizons (hours for an hour-long pool) instead of the flume's 30 minutes of 1.2 s
    steps at 40 m³/h. The bundled flume model keeps the flume demo's loop. The PI closes the
    loop: at the end of each set-point segment the level is within the settle band (three
    gauge SDs) of the set-point."""
    from gatetwin.fmu.controller_settings import demo_minutes, demo_settings

    assert demo_settings(read_model_file(MODEL)) == DemoSettings()
    model = read_model_file(_field_fopdt(tmp_path))
    s = demo_settings(model)
    band = (940.0, 3720.0)
    assert s.pi.sample_period_s == 60.0 and 12000.0 <= s.flow_m3h <= 54000.0
    assert 200.0 <= s.opening_mm <= 1600.0 and s.setpoint_step_mm == 0.1 * (band[1] - band[0])
    assert s.loop.settle_band_mm == 9.0 and demo_minutes(s) > 60.0
    out = tmp_path / "loop.ssp"
    assert main(["ssp", str(_field_fopdt(tmp_path)), "--out", str(out)]) == 0
    capsys.readouterr()
    run = simulate_ssp(out)
    assert np.allclose(np.diff(run.time_s), 60.0)
    assert run.time_s[-1] + 60.0 == pytest.approx(demo_minutes(s) * 60.0)
    setpoint = run.columns["controller.setpoint_mm"]
    level = run.columns["controller.level_3F_mm"]
    assert band[0] <= setpoint.min() < setpoint.max() <= band[1]
    ends = np.flatnonzero(np.diff(setpoint) != 0.0).tolist() + [setpoint.size - 1]
    assert len(ends) == 4
    for k in ends:
        assert abs(level[k] - setpoint[k]) <= s.loop.settle_band_mm, (k, level[k], setpoint[k])
    # with the observer: it samples at the records' period too, so the loop runs
    watched = tmp_path / "watched.ssp"
    assert main(["ssp", str(_field_fopdt(tmp_path)), "--observer", "--out", str(watched)]) == 0
    capsys.readouterr()
    assert np.allclose(np.diff(simulate_ssp(watched).time_s), 60.0)
