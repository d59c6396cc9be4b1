"""The PI controller FMU: a valid FMI 2.0 and FMI 3.0 co-simulation FMU whose closed loop with
the plant FMU is the Python PI's (and the FMI 3.0 one's the FMI 2.0 one's, to the bit), which
refuses what it cannot honour with a logged reason, and whose C arithmetic is the Python's
(generated from gatetwin.mpc.pi_law)."""

from __future__ import annotations

import ctypes
import math
import subprocess
import zipfile
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from fmu_support import open_fmu
from gatetwin.cli import main
from gatetwin.errors import ExportError
from gatetwin.fmu import export_fmu
from gatetwin.fmu.c_build import CFLAGS, find_compiler
from gatetwin.fmu.controller import export_controller, generated_pi_law
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.demo import DemoSettings, demo_scenarios, pi_controller
from gatetwin.mpc.fmu_controller import FmuController
from gatetwin.mpc.loop import loop_metrics, run_closed_loop
from gatetwin.mpc.pi_law import pi_step
from gatetwin.mpc.plants import FmuCore, LoopPlant

MODELS = Path(__file__).resolve().parents[2] / "models"
MODEL = MODELS / "fopdt_3F.json"
#: Both loops run the same IEEE-754 operations in the same order (the C is generated from the
#: Python and compiled with -ffp-contract=off), so they agree to the bit; 1e-9 mm is far below
#: any physical meaning and only leaves room for a compiler that orders a library call
#: differently.
SAME_ARITHMETIC_MM = 1e-9


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("controller")
    model = read_model_file(MODEL)
    # the demo's settings, which the Python loop it is compared with runs (without them the
    # controller takes its settings from the model file)
    demo = DemoSettings()
    controller = export_controller(model, "pi", folder / "fopdt_3F_pi.fmu", settings=demo)
    controller3 = export_controller(model, "pi", folder / "fmi3" / "fopdt_3F_pi.fmu",
                                    settings=demo, fmi_version="3.0")  # fmt: skip
    # and with a measurement filter of five sample periods
    filtered = replace(demo, pi=replace(demo.pi, filter_time_s=6.0))
    controller_filtered = export_controller(model, "pi", folder / "filtered" / "fopdt_3F_pi.fmu",
                                            settings=filtered)  # fmt: skip
    # the plant FMU as run_mpc_demo(plant_kind="fmu") exports it
    plant = export_fmu(model.plant, folder / "gatetwin_mpc_plant.fmu", backend="c",
                       model_name="gatetwin_mpc_plant",
                       provenance={"purpose": "gatetwin mpc-demo plant"})  # fmt: skip
    return {"model": model, "controller": controller, "controller3": controller3,
            "controller_filtered": controller_filtered, "filtered": filtered, "plant": plant,
            "folder": folder}  # fmt: skip


@pytest.mark.parametrize("which", ["controller", "controller3"], ids=["fmi2", "fmi3"])
def test_the_controller_fmu_passes_fmpy_validation(fmus, which):
    assert validate_fmu(str(fmus[which])) == []


def test_the_fmi3_controller_declares_the_fmi2_ones_variables_and_time(fmus):
    """One description, two renderings: FMI 3.0 adds only the independent ``time``."""

    def variables(path: Path) -> dict[str, dict[str, str]]:
        with zipfile.ZipFile(path) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
        found = {}
        for element in root.find("ModelVariables"):
            attrs = dict(element.attrib)
            attrs.update(getattr(element.find("Real"), "attrib", {}))
            found[attrs.pop("name")] = attrs
        return found

    two, three = variables(fmus["controller"]), variables(fmus["controller3"])
    time = three.pop("time")
    assert time["causality"] == "independent" and int(time["valueReference"]) == len(two)
    assert three == two


def _loop(fmus, controller, scenario, s: DemoSettings):
    core = FmuCore(fmus["plant"], s.mpc.sample_period_s)
    plant = LoopPlant(core, noise=s.noise, actuator_resolution_mm=s.actuator_resolution_mm,
                      sample_period_s=s.mpc.sample_period_s)  # fmt: skip
    try:
        return run_closed_loop(plant, controller, scenario, level_band_mm=s.mpc.level_band_mm,
                               max_move_mm=s.mpc.max_move_mm,
                               opening_range_mm=s.mpc.opening_range_mm,
                               sample_period_s=s.mpc.sample_period_s)  # fmt: skip
    finally:
        core.cleanup()


def _fmu_loop(fmus, which, scenario, s: DemoSettings):
    fmu = FmuController(fmus[which])
    try:
        return _loop(fmus, fmu, scenario, s)
    finally:
        fmu.cleanup()


@pytest.mark.parametrize("which", [0, 1], ids=["setpoint_steps", "inflow_step"])
def test_plant_fmu_with_pi_fmu_is_the_python_loop(fmus, which):
    """Plant FMU + PI FMU through fmpy against PiController on the same plant FMU: the demo's
    scenario, noise (same seed) and actuator resolution, 30 simulated minutes. The FMI 3.0 PI
    compiles the same component with the same flags as the FMI 2.0 one, only the glue
    differs: its loop is the FMI 2.0 one's to the bit."""
    s = DemoSettings()
    scenario = demo_scenarios(30.0, s)[which]
    python = _loop(fmus, pi_controller(fmus["model"].plant, s), scenario, s)
    cosim = _fmu_loop(fmus, "controller", scenario, s)
    cosim3 = _fmu_loop(fmus, "controller3", scenario, s)
    assert np.array_equal(cosim3.command_mm, cosim.command_mm)
    assert np.array_equal(cosim3.level_mm, cosim.level_mm)
    assert np.max(np.abs(np.diff(python.command_mm))) > 0.5  # the controller acts
    assert np.max(np.abs(cosim.command_mm - python.command_mm)) <= SAME_ARITHMETIC_MM
    assert np.max(np.abs(cosim.level_mm - python.level_mm)) <= SAME_ARITHMETIC_MM
    iae_py, iae_fmu = loop_metrics(python)["iae"], loop_metrics(cosim)["iae"]
    # the IAE sums |error| over 1500 samples of 1.2 s: the per-sample bound times that
    assert abs(iae_fmu - iae_py) <= SAME_ARITHMETIC_MM * scenario.samples(1.2) * 1.2


def test_a_filtered_pi_fmu_is_the_filtered_python_loop(fmus):
    """The PI FMU exported with a 6-s level filter against PiController tuned for the same
    filter (SIMC on the filtered loop), on the demo's noisy set-point steps: the same
    arithmetic, so the same loop to the bit; and the filter calms the gate with no loss of IAE
    (the unfiltered PI is the comparison, the same scenario and noise seed)."""
    s = fmus["filtered"]
    scenario = demo_scenarios(30.0, s)[0]
    pi = pi_controller(fmus["model"].plant, s)
    assert pi.tuning.filter_time_s == 6.0
    python = _loop(fmus, pi, scenario, s)
    cosim = _fmu_loop(fmus, "controller_filtered", scenario, s)
    assert np.max(np.abs(cosim.command_mm - python.command_mm)) <= SAME_ARITHMETIC_MM
    assert np.max(np.abs(cosim.level_mm - python.level_mm)) <= SAME_ARITHMETIC_MM
    unfiltered = _loop(fmus, pi_controller(fmus["model"].plant, DemoSettings()), scenario, s)
    filtered_metrics, unfiltered_metrics = loop_metrics(python), loop_metrics(unfiltered)
    # "takes most of the noise out of the gate's travel": less than half of it is left
    assert filtered_metrics["travel_mm"] < 0.5 * unfiltered_metrics["travel_mm"]
    assert filtered_metrics["iae"] <= unfiltered_metrics["iae"]  # as docs/closed-loop.md says


def _driver(fmus, name, which="controller"):
    unzipped = Path(extract(str(fmus[which]), str(fmus["folder"] / name)))
    driver = open_fmu(unzipped, name)
    driver.slave.setupExperiment(startTime=0.0)
    driver.slave.enterInitializationMode()
    driver.slave.exitInitializationMode()
    return driver


def _errors(driver):
    return [text for status, text in driver.messages if status >= 3]  # fmi2Error, fmi2Fatal


def test_a_nan_level_is_refused_with_a_logged_reason(fmus):
    driver = _driver(fmus, "nan_level")
    with pytest.raises(FMICallException):
        driver.slave.setReal([driver.vr["level_3F_mm"]], [math.nan])
    assert any("level_3F_mm" in m and "not finite" in m for m in _errors(driver))
    driver.close()


@pytest.mark.parametrize("value", [-1.0, math.nan])
def test_a_bad_filter_time_is_refused_with_a_logged_reason(fmus, value):
    """filter_time_s set to a negative number (or NaN, which the glue refuses itself) in step
    mode: the call or the next step fails with the reason logged, and the opening holds."""
    driver = _driver(fmus, f"bad_filter_{value}", "controller_filtered")
    vr, slave = driver.vr, driver.slave
    period = slave.getReal([vr["sample_period_s"]])[0]
    slave.doStep(0.0, period)
    before = slave.getReal([vr["opening_mm"]])[0]
    with pytest.raises(FMICallException):
        slave.setReal([vr["filter_time_s"]], [value])
        slave.doStep(period, period)
    assert any("filter_time_s" in m for m in _errors(driver))
    assert slave.getReal([vr["opening_mm"]])[0] == before
    driver.close()


def test_a_step_off_the_sample_grid_is_refused_with_a_logged_reason(fmus):
    driver = _driver(fmus, "off_grid")
    period = driver.slave.getReal([driver.vr["sample_period_s"]])[0]
    with pytest.raises(FMICallException):
        driver.slave.doStep(0.0, 1.5 * period)
    assert any("not a whole multiple" in m for m in _errors(driver))
    driver.close()


def test_a_step_that_overflows_is_refused_with_a_logged_reason(fmus):
    """Finite inputs whose error overflows (set-point − level = −2e308, read unfiltered): the
    range limits would hide it in the opening, not in the integral; the step is refused and
    says why."""
    driver = _driver(fmus, "overflow")
    vr, slave = driver.vr, driver.slave
    period = slave.getReal([vr["sample_period_s"]])[0]
    slave.doStep(0.0, period)
    slave.setReal([vr["filter_time_s"], vr["level_3F_mm"], vr["setpoint_mm"]],
                  [0.0, 1e308, -1e308])  # fmt: skip
    with pytest.raises(FMICallException):
        slave.doStep(period, period)
    assert any("sample 1 of the step overflows" in m for m in _errors(driver))
    driver.close()


@pytest.mark.parametrize("which", ["controller", "controller_filtered"])
def test_first_output_is_the_start_opening_and_a_multiple_step_is_that_many_samples(fmus, which):
    """Bumpless start; a step of 3 samples runs the PI 3 times on the inputs held (FMI's
    piecewise-constant inputs), as the Python PI stepped 3 times on the same inputs (with a
    level filter, its state carried from sample to sample)."""
    driver = _driver(fmus, f"three_samples_{which}", which)
    vr = driver.vr
    start = driver.slave.getReal([vr["start_opening_mm"]])[0]
    assert driver.slave.getReal([vr["opening_mm"]])[0] == start
    level = driver.slave.getReal([vr["level_3F_mm"]])[0]
    driver.slave.setReal([vr["setpoint_mm"], vr["level_3F_mm"]], [level + 15.0, level + 5.0])
    period = driver.slave.getReal([vr["sample_period_s"]])[0]
    driver.slave.doStep(0.0, 3 * period)
    settings = fmus["filtered"] if which == "controller_filtered" else DemoSettings()
    pi = pi_controller(fmus["model"].plant, settings)
    pi.reset(start, level, 40.0)
    expected = [pi.step(level + 5.0, 40.0, level + 15.0) for _ in range(3)][-1]
    assert driver.slave.getReal([vr["opening_mm"]])[0] == expected != start
    driver.close()


def test_the_c_pi_law_is_the_python_one_to_the_bit(tmp_path):
    for name, text in generated_pi_law().items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    flags = [f for f in CFLAGS if not f.startswith("-fvisibility")]
    subprocess.run([*find_compiler(), *flags, "-o", "pi_law.so", "pi_law.c", "-lm"],
                   cwd=tmp_path, check=True, capture_output=True)  # fmt: skip
    f = ctypes.CDLL(str(tmp_path / "pi_law.so")).gt_pi_step
    f.argtypes = [ctypes.c_double] * 13 + [ctypes.POINTER(ctypes.c_double)] * 3
    f.restype = None
    rng = np.random.default_rng(3)
    for k in range(5000):
        lo = float(rng.uniform(0, 30))
        args = [float(rng.uniform(100, 400)), float(rng.uniform(100, 400)),
                float(rng.uniform(-50, 150)), float(rng.uniform(lo, lo + 80)),
                float(rng.uniform(100, 400)),
                float(-rng.uniform(0.1, 20)), float(rng.uniform(1, 100)),
                float(rng.uniform(0.5, 50)), lo, lo + float(rng.uniform(1, 100)),
                float(rng.uniform(0.01, 2)), float(rng.uniform(0.1, 5)),
                0.0 if k % 4 == 0 else float(rng.uniform(0.01, 500))]  # fmt: skip
        out = [ctypes.c_double(), ctypes.c_double(), ctypes.c_double()]
        f(*args, *[ctypes.byref(o) for o in out])
        assert tuple(o.value for o in out) == pi_step(*args)


def test_export_controller_refuses_what_it_does_not_build_without_output(tmp_path, capsys):
    for argv in (
        ["--kind", "mpc", "--fmi", "3", str(MODEL)],
        ["--kind", "pi", "--horizon", "30", str(MODEL)],
        ["--kind", "mpc", "--pi-filter", "6", str(MODEL)],
        ["--kind", "pi", "--pi-filter", "-1", str(MODEL)],
        ["--kind", "pi", "--pi-filter", "nan", str(MODEL)],
        ["--kind", "pi", str(MODELS / "arx_3F.json")],
        ["--fmi", "3", str(MODELS / "arx_3F.json")],
    ):
        out = tmp_path / "c.fmu"
        assert main(["export-controller", *argv, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("gatetwin: error:")
        assert not out.exists() and list(tmp_path.iterdir()) == []
    bad = tmp_path / "bad.json"
    bad.write_text("{not json", encoding="utf-8")
    assert main(["export-controller", str(bad), "--out", str(tmp_path / "c.fmu")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]
    with pytest.raises(ExportError, match="fmi_version must be one of 2.0, 3.0"):
        export_controller(read_model_file(MODEL), "mpc", tmp_path / "c.fmu", fmi_version="4.0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


def test_export_controller_cli_writes_the_fmu(tmp_path, capsys):
    out = tmp_path / "pi.fmu"
    assert main(["export-controller", str(MODEL), "--kind", "pi", "--out", str(out)]) == 0
    assert out.is_file() and str(out) in capsys.readouterr().out


@pytest.mark.parametrize("which", ["controller", "controller_filtered"])
def test_fmu_states_round_trip_and_a_corrupt_state_is_refused(fmus, which):
    """A serialised state restores the PI exactly (integral, last opening and filtered level
    travel with it); bytes turned to NaN are refused, the instance unchanged."""
    driver = _driver(fmus, f"states_{which}", which)
    vr, slave = driver.vr, driver.slave
    level = slave.getReal([vr["level_3F_mm"]])[0]
    period = slave.getReal([vr["sample_period_s"]])[0]

    def run(k0: int, n: int) -> list[float]:
        out = []
        for k in range(k0, k0 + n):
            slave.setReal([vr["setpoint_mm"], vr["level_3F_mm"]], [level + 20.0, level + k])
            slave.doStep(k * period, period)
            out.append(slave.getReal([vr["opening_mm"]])[0])
        return out

    run(0, 10)
    saved = slave.serializeFMUstate(slave.getFMUstate())
    first = run(10, 10)
    slave.setFMUstate(slave.deSerializeFMUstate(saved))
    assert run(10, 10) == first and len(set(first)) > 1
    # keep the header (format, GUID, size) and the mode; every double of the data becomes NaN
    corrupt = bytes(saved[:104]) + b"\xff" * (len(saved) - 104)
    before = slave.getReal([vr["opening_mm"]])[0]
    with pytest.raises(FMICallException):
        slave.deSerializeFMUstate(corrupt)
    assert any("corrupt state refused" in m for m in _errors(driver))
    assert slave.getReal([vr["opening_mm"]])[0] == before
    assert run(20, 1)  # still in step mode, at its own time
    driver.close()


def _driver3(fmus, name):
    unzipped = Path(extract(str(fmus["controller3"]), str(fmus["folder"] / name)))
    driver = open_fmu(unzipped, name)
    driver.slave.enterInitializationMode(startTime=0.0)
    driver.slave.exitInitializationMode()
    return driver


def test_fmi3_bad_inputs_and_steps_return_error_with_a_logged_reason(fmus):
    driver = _driver3(fmus, "fmi3_bad")
    vr, slave = driver.vr, driver.slave
    try:
        with pytest.raises(FMICallException) as info:
            slave.setFloat64([vr["level_3F_mm"]], [math.nan])
        assert info.value.status == 3  # fmi3Error
        assert driver.messages[-1][0] == 3
        assert "level_3F_mm" in driver.messages[-1][1] and "finite" in driver.messages[-1][1]
        slave.reset()  # out of the error state, as the FMI 3.0 standard allows
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        period = slave.getFloat64([vr["sample_period_s"]])[0]
        with pytest.raises(FMICallException) as info:
            slave.doStep(0.0, 1.5 * period)
        assert info.value.status == 3
        assert driver.messages[-1][0] == 3 and "not a whole multiple" in driver.messages[-1][1]
    finally:
        driver.close()


def test_export_controller_cli_writes_fmi3_and_refuses_an_unknown_version(tmp_path, capsys):
    out = tmp_path / "pi3.fmu"
    assert main(["export-controller", str(MODEL), "--fmi", "3", "--out", str(out)]) == 0
    with zipfile.ZipFile(out) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
        binaries = [n for n in zf.namelist() if n.startswith("binaries/")]
    assert root.get("fmiVersion") == "3.0" and root.find("CoSimulation") is not None
    assert binaries and all(n.count("/") == 2 and "-" in n.split("/")[1] for n in binaries)
    capsys.readouterr()
    with pytest.raises(ExportError, match="fmi_version"):
        export_controller(read_model_file(MODEL), "pi", tmp_path / "x.fmu", fmi_version="4.0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pi3.fmu"]
