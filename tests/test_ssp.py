"""The closed loop as an SSP: the package follows the SSP 1.0 schemas, gatetwin's master runs
it as the Python loop runs the PI on the same plant FMU, fmpy's own SSP simulation reads it,
and bad packages are refused in one line without output."""

from __future__ import annotations

import re
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmu_support import compiler, with_zip_bomb
from gatetwin.cli import main
from gatetwin.errors import ExportError, SspError
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.demo import DemoSettings, demo_scenarios
from gatetwin.mpc.loop import loop_metrics
from gatetwin.ssp import simulate_ssp, write_ssp
from gatetwin.ssp.documents import SSD_SCHEMA, SSV_SCHEMA, read_parameter_set, schema_problems
from gatetwin.ssp.master import MAX_STEPS, SIGNAL_TIME_TOL_S, _signal, _signal_at
from gatetwin.ssp.reference import python_loop
from gatetwin.ssp.write import CONTROLLER_SOURCE, OBSERVER_SOURCE, PARAMETERS_SOURCE, SSD_NAME
from test_validate_isolation import build_hostile

MODELS = Path(__file__).resolve().parents[1] / "models"
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


def test_fmpy_simulate_ssp_reads_and_runs_the_package(package):
    """fmpy's own master (Jacobi: every FMU steps on the values of the previous point, its
    connectors start at 0) reads the SSD and, given the parameter set and the scenario as
    inputs, runs the loop to the end; the PI brings the level back to the set-point."""
    from fmpy.ssp.simulation import simulate_ssp as fmpy_simulate_ssp
    from fmpy.ssp.ssd import read_ssv

    parameters = read_parameter_set(_read(package, PARAMETERS_SOURCE), "ssv")
    signals = {n: _signal(parameters, n, "ssv") for n in ("setpoint_mm", "flow_m3h")}
    inputs = {n: (lambda t, sig=sig: _signal_at(sig, t)) for n, sig in signals.items()}
    out = fmpy_simulate_ssp(str(package), stop_time=MINUTES * 60, step_size=1.2,
                            parameter_set=read_ssv(str(package), resource=PARAMETERS_SOURCE),
                            input=inputs)  # fmt: skip
    assert len(out) == int(round(MINUTES * 60 / 1.2))
    # the settle band of the demo's scoring (LoopSettings.settle_band_mm)
    assert abs(out["plant.level_3F_mm"][-1] - out["controller.setpoint_mm"][-1]) <= 5.0


def test_signals_switch_at_their_times():
    params = {"x.time_s[1]": 0.0, "x.value[1]": 1.0, "x.time_s[2]": 6.0, "x.value[2]": 2.0}
    sig = _signal(params, "x", "test")
    assert [_signal_at(sig, t) for t in (0.0, 5.9, 6.0 - SIGNAL_TIME_TOL_S / 2, 7.0)] == [
        1.0, 1.0, 2.0, 2.0]  # fmt: skip
    with pytest.raises(SspError, match="increase strictly"):
        _signal({**params, "x.time_s[2]": 0.0}, "x", "test")


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


#: Where a hostile plant (tests/test_validate_isolation.py, misbehaving after its tenth step
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
    the unprotected run's values."""
    long_loop = tmp_path / "long.ssp"
    assert main(["ssp", str(MODEL), "--out", str(long_loop), "--minutes", "600"]) == 0
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
#: The MPC FMU against the Python MPC (the FMU's dense active-set solver and qpOASES): the
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
