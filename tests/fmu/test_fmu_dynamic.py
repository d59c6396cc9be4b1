"""FMU behaviour: the C and pythonfmu FMUs follow the Python reference simulation to the bit,
states roll back and travel between instances, refused calls are errors with a logged reason,
and the C FMU's lifecycle is leak- and memory-error-free."""

from __future__ import annotations

import math
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error

from fmu_support import (
    BACKENDS,
    FAMILIES,
    PLANTS,
    compile_host,
    compiler,
    driven_inputs,
    extract_all,
    fmu_run,
    open_fmu,
    reference_run,
)
from gatetwin.fmu import export_fmu
from gatetwin.fmu.c_build import source_files
from gatetwin.plant.model import FLOW_RANGE_M3H, ArxPlant, FopdtPlant, Schedule
from gatetwin.plant.simulate import PlantSimulator

TOL_MM = 1e-9
#: pythonfmu 0.7.0 can only answer a refused step with fmi2Discard (do_step() -> False).
REFUSED = {"c": fmi2Error, "python": 2}


@pytest.fixture(scope="module")
def fmus(test_plant_fmus, tmp_path_factory) -> dict[tuple[str, str], Path]:
    return extract_all(test_plant_fmus, tmp_path_factory.mktemp("extracted"))


@pytest.fixture
def drivers():
    opened = []

    def open_(path, name="instance"):
        driver = open_fmu(path, name)
        opened.append(driver)
        return driver

    yield open_
    for driver in opened:
        driver.close()


def _start(drivers, fmus, backend, family, name="instance"):
    driver = drivers(fmus[backend, family], name)
    driver.start(20.0, 50.0)
    return driver


@pytest.mark.parametrize("family", FAMILIES)
def test_fmus_follow_the_reference_on_a_long_driven_run(fmus, drivers, family):
    times, opening, flow = driven_inputs(family, 3000)
    reference = reference_run(PLANTS[family](), times, opening, flow)
    for backend in BACKENDS:
        levels = fmu_run(drivers(fmus[backend, family]), times, opening, flow)
        assert np.max(np.abs(levels - reference)) <= TOL_MM, backend
    assert np.ptp(reference) > 50.0  # the run really moves the level


@pytest.mark.parametrize("seed", [1, 2])
def test_fopdt_matches_the_reference_for_random_step_sizes(fmus, drivers, seed):
    rng = np.random.default_rng(seed)
    times, opening, flow = driven_inputs("fopdt", 800, seed=seed)
    times = np.concatenate([[0.0], np.cumsum(rng.choice([1e-3, 0.3, 2.5, 7.0, 30.0], 799))])
    reference = reference_run(PLANTS["fopdt"](), times, opening, flow)
    for backend in BACKENDS:
        levels = fmu_run(drivers(fmus[backend, "fopdt"]), times, opening, flow)
        assert np.max(np.abs(levels - reference)) <= TOL_MM, backend


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("family", FAMILIES)
def test_get_set_state_rollback_reproduces_a_run_bit_for_bit(fmus, drivers, backend, family):
    times, opening, flow = driven_inputs(family, 120, seed=3)
    driver = drivers(fmus[backend, family])
    fmu_run(driver, times[:60], opening[:60], flow[:60])
    state = driver.slave.getFMUstate()
    mark = driver.time_s

    def rest():
        out = []
        for i in range(60, 120):
            out.append(driver.step(times[i] - times[i - 1], opening[i - 1], flow[i - 1]))
        return out

    first = rest()
    driver.slave.setFMUstate(state)
    driver.time_s = mark
    assert rest() == first
    driver.slave.freeFMUstate(state)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("family", FAMILIES)
def test_serialized_state_continues_identically_in_a_fresh_instance(fmus, drivers, backend, family):
    times, opening, flow = driven_inputs(family, 100, seed=4)
    first = drivers(fmus[backend, family], "first")
    fmu_run(first, times[:50], opening[:50], flow[:50])
    state = first.slave.getFMUstate()
    data = first.slave.serializeFMUstate(state)
    first.slave.freeFMUstate(state)
    second = drivers(fmus[backend, family], "second")
    restored = second.slave.deSerializeFMUstate(data)
    second.slave.setFMUstate(restored)
    second.slave.freeFMUstate(restored)
    second.time_s = first.time_s
    for i in range(50, 100):
        args = (times[i] - times[i - 1], opening[i - 1], flow[i - 1])
        assert second.step(*args) == first.step(*args)


def test_dead_time_arrival_that_rounds_onto_a_step_start_is_handled(fmus, drivers):
    """31.3 + 1.1 rounds to 32.4 while 32.4 - 1.1 < 31.3: the reference used to stall here."""
    plant = PLANTS["fopdt"]()
    delay = replace(
        plant,
        schedule=replace(
            plant.schedule, values={**plant.schedule.values, "dead_time_s": (1.1, 1.1, 1.1)}
        ),
    )
    times = np.array([30.0, 31.3, 32.4, 33.4, 40.0])
    opening, flow = np.array([20.0, 25.0, 25.0, 25.0, 25.0]), np.full(5, 50.0)
    reference = reference_run(delay, times, opening, flow)
    for backend in BACKENDS:
        driver = drivers(fmus[backend, "fopdt"])
        driver.slave.setReal(
            [driver.vr[f"schedule.dead_time_s[{k}]"] for k in (1, 2, 3)], [1.1, 1.1, 1.1]
        )
        assert np.array_equal(fmu_run(driver, times, opening, flow), reference), backend


@pytest.mark.parametrize(
    "plant",
    [
        FopdtPlant(
            "G 1",
            50.0,
            Schedule(
                (40.0,),
                {
                    "gain_mm_per_mm": (-8.0,),
                    "time_constant_s": (30.0,),
                    "dead_time_s": (0.0,),
                    "level_ref_mm": (400.0,),
                },
            ),
        ),
        ArxPlant(
            "G2",
            20.0,
            0.5,
            8,
            8,
            8,
            Schedule(
                (60.0,),
                {
                    **{f"a{i}": (0.1,) for i in range(1, 9)},
                    **{f"b{j}": (-0.3 + 0.05 * j,) for j in range(1, 9)},
                    "level_ref_mm": (250.0,),
                },
            ),
        ),
        ArxPlant(
            "G3",
            20.0,
            2.0,
            1,
            1,
            3,
            Schedule(
                (10.0, 30.0, 60.0, 90.0),
                {
                    "a1": (0.9, 0.8, 0.7, 0.6),
                    "b1": (-1.0, -1.5, -2.0, -2.5),
                    "level_ref_mm": (100.0, 150.0, 200.0, 250.0),
                },
            ),
        ),
    ],
    ids=["fopdt-1-knot-no-delay", "arx-8-8-8", "arx-1-1-3-4-knots"],
)
def test_edge_plants_follow_the_reference(tmp_path, drivers, plant):
    family = plant.kind
    times, opening, flow = driven_inputs(family, 300, seed=8)
    if family == "arx":
        times = times / 1.2 * plant.sample_period_s
    reference = reference_run(plant, times, opening, flow)
    for backend in BACKENDS:
        fmu = export_fmu(
            plant,
            tmp_path / f"{backend}.fmu",
            backend=backend,
            model_name=f"edge_{family}",
            provenance={},
        )
        driver = drivers(extract(str(fmu), str(tmp_path / backend)))
        assert np.max(np.abs(fmu_run(driver, times, opening, flow) - reference)) <= TOL_MM


@pytest.mark.parametrize("backend", BACKENDS)
def test_arx_refuses_a_step_that_is_not_a_whole_number_of_samples(fmus, drivers, backend):
    driver = _start(drivers, fmus, backend, "arx")
    driver.step(2.4, 25.0, 50.0)  # two samples: fine
    before = driver.level()
    with pytest.raises(FMICallException) as failure:
        driver.slave.doStep(driver.time_s, 1.0)
    assert failure.value.status == REFUSED[backend]
    assert any("not a whole multiple of the ARX sample period" in m for _, m in driver.messages)
    assert driver.level() == before  # nothing was computed
    assert driver.slave.getReal([driver.vr["sample_period_s"]]) == [1.2]


@pytest.mark.parametrize("backend", BACKENDS)
# a flow twice the physical ceiling of any canal (FLOW_RANGE_M3H) is impossible input
@pytest.mark.parametrize(
    "bad", [(math.nan, 50.0), (-1.0, 50.0), (20.0, math.inf), (20.0, 2.0 * FLOW_RANGE_M3H[1])]
)
def test_nan_or_impossible_input_is_refused_and_the_host_survives(fmus, drivers, backend, bad):
    driver = _start(drivers, fmus, backend, "fopdt")
    state = driver.slave.getFMUstate()
    before = driver.level()
    with pytest.raises(FMICallException) as failure:
        driver.step(1.0, *bad)
    assert failure.value.status == REFUSED[backend]
    assert any(
        ("is outside" in m or "not finite" in m) and status >= 3 for status, m in driver.messages
    )
    driver.slave.setFMUstate(state)  # the documented way back after fmi2Error
    driver.time_s = 0.0
    assert driver.level() == before
    assert driver.step(10.0, 22.0, 50.0) != before  # past the dead time
    driver.slave.freeFMUstate(state)


def test_c_fmu_refuses_bad_pointers_value_references_and_states(fmus, drivers):
    driver = _start(drivers, fmus, "c", "fopdt")
    slave = driver.slave
    for call in (
        lambda: slave.getReal([4242]),
        lambda: slave.setReal([driver.vr["level_3F_mm"]], [1.0]),
        lambda: slave.getInteger([0]),
        lambda: slave.fmi2GetReal(slave.component, None, 1, None),
        lambda: slave.fmi2SetFMUstate(slave.component, None),
        lambda: slave.doStep(driver.time_s + 5.0, 1.0),
        lambda: slave.cancelStep(),
    ):
        with pytest.raises(FMICallException) as failure:
            call()
        assert failure.value.status == fmi2Error
        slave.reset()
        driver.start(20.0, 50.0)
    errors = [m for status, m in driver.messages if status == fmi2Error]
    assert any("no Real variable has value reference 4242" in m for m in errors)
    assert any("is an output" in m for m in errors)
    assert any("differs from the FMU's time" in m for m in errors)


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_interleaved_instances_match_separate_runs(fmus, drivers, backend):
    family = "fopdt"
    a_in = driven_inputs(family, 200, seed=5)
    b_in = driven_inputs(family, 200, seed=6)
    alone = [fmu_run(drivers(fmus[backend, family], n), *i) for n, i in (("a", a_in), ("b", b_in))]
    a, b = drivers(fmus[backend, family], "a2"), drivers(fmus[backend, family], "b2")
    a.start(a_in[1][0], a_in[2][0])
    b.start(b_in[1][0], b_in[2][0])
    together = [[a.level()], [b.level()]]
    for i in range(1, 200):
        for out, d, (t, e, q) in ((together[0], a, a_in), (together[1], b, b_in)):
            out.append(d.step(t[i] - t[i - 1], e[i - 1], q[i - 1]))
    assert np.array_equal(together[0], alone[0]) and np.array_equal(together[1], alone[1])


@pytest.mark.parametrize("backend", BACKENDS)
def test_flow_outside_the_knots_clamps_and_warns_once_per_instance(fmus, drivers, backend):
    driver = _start(drivers, fmus, backend, "fopdt")
    for q in (100.0, 120.0, 10.0):
        driver.step(1.0, 20.0, q)
    warnings = [m for status, m in driver.messages if status == 1]
    assert len(warnings) == 1 and "outside the schedule's validity range [30, 85]" in warnings[0]
    sim = PlantSimulator(PLANTS["fopdt"]())
    sim.initialize(20.0, 50.0)
    with pytest.warns(RuntimeWarning, match="parameters clamped"):
        for q in (100.0, 120.0, 10.0):
            sim.do_step(1.0, 20.0, q)
    assert driver.level() == sim.level_mm


@pytest.mark.parametrize("backend", BACKENDS)
def test_reset_returns_to_the_post_instantiate_state(fmus, drivers, backend):
    times, opening, flow = driven_inputs("fopdt", 50, seed=7)
    driver = drivers(fmus[backend, "fopdt"])
    first = fmu_run(driver, times, opening, flow)
    driver.slave.setReal([driver.vr["schedule.gain_mm_per_mm[2]"]], [-3.0])
    driver.slave.terminate()
    driver.slave.reset()
    assert driver.slave.getReal([driver.vr["schedule.gain_mm_per_mm[2]"]]) == [-12.0]
    assert np.array_equal(fmu_run(driver, times, opening, flow), first)


@pytest.mark.parametrize("backend", BACKENDS)
def test_tunable_parameters_are_honoured_and_checked(fmus, drivers, backend):
    driver = _start(drivers, fmus, backend, "fopdt")
    driver.slave.setReal([driver.vr["schedule.level_ref_mm[2]"]], [310.0])
    level = driver.step(1.0, 20.0, 55.0)
    assert level == pytest.approx(310.0, abs=1e-12)  # at equilibrium, on the middle knot
    driver.slave.setReal([driver.vr["schedule.dead_time_s[3]"]], [20.0])  # beyond the horizon
    with pytest.raises(FMICallException):
        driver.step(1.0, 20.0, 55.0)
    assert any("exceeds the dead-time horizon 9.5" in m for _, m in driver.messages)


@pytest.mark.parametrize("family", FAMILIES)
def test_parameter_changes_mid_run_agree_between_backends(fmus, drivers, family):
    times, opening, flow = driven_inputs(family, 200, seed=9)
    changes = {
        50: {"opening_ref_mm": 22.0, "schedule.flow_m3h[1]": 25.0},
        120: {"schedule.level_ref_mm[2]": 333.0},
    }
    first = "gain_mm_per_mm" if family == "fopdt" else "b1"
    changes[80] = {f"schedule.{first}[1]": -9.0}
    runs = []
    for backend in BACKENDS:
        driver = drivers(fmus[backend, family])
        driver.start(opening[0], flow[0])
        out = []
        for i in range(1, len(times)):
            for name, value in changes.get(i, {}).items():
                driver.slave.setReal([driver.vr[name]], [value])
            out.append(driver.step(times[i] - times[i - 1], opening[i - 1], flow[i - 1]))
        runs.append(out)
    # both backends call the same exp here; the renderings' bound allows another C library's
    assert np.max(np.abs(np.subtract(runs[0], runs[1]))) <= TOL_MM


@pytest.mark.parametrize("backend", BACKENDS)
def test_fmpy_simulate_fmu_with_an_input_table_matches_the_reference(fmus, backend):
    times = np.arange(0.0, 121.0, 1.2)
    opening = np.where(times < 30.0, 20.0, 28.0)
    flow = np.where(times < 60.0, 50.0, 70.0)
    # piecewise-constant inputs as fmpy events: each change appears twice at its time
    change = np.flatnonzero(np.diff(opening) + np.diff(flow)) + 1
    rows = [(times[0], opening[0], flow[0])]
    for i in range(1, len(times)):
        if i in change:
            rows.append((times[i], opening[i - 1], flow[i - 1]))
        rows.append((times[i], opening[i], flow[i]))
    signal = np.array(rows, dtype=[("time", float), ("opening_mm", float), ("flow_m3h", float)])
    result = simulate_fmu(
        str(fmus[backend, "arx"]),
        stop_time=times[-1],
        output_interval=1.2,
        input=signal,
        output=["level_3F_mm"],
    )
    reference = reference_run(PLANTS["arx"](), result["time"], opening, flow)
    assert np.max(np.abs(result["level_3F_mm"] - reference)) <= TOL_MM


def _guid_and_vrs(extracted: Path) -> list[str]:
    from fmpy import read_model_description

    md = read_model_description(str(extracted))
    vr = {v.name: str(v.valueReference) for v in md.modelVariables}
    return [md.guid, vr["opening_mm"], vr["flow_m3h"], vr["level_3F_mm"]]


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind not installed")
@pytest.mark.parametrize("family", FAMILIES)
def test_thousand_instantiate_free_cycles_leak_nothing_under_valgrind(fmus, tmp_path, family):
    extracted = fmus["c", family]
    host = tmp_path / "fmu_host"
    compile_host(extracted / "sources", host)
    binary = extracted / "binaries" / "linux64" / f"gate_3F_{family}.so"
    run = subprocess.run(
        [
            "valgrind",
            "-q",
            "--leak-check=full",
            "--error-exitcode=1",
            str(host),
            str(binary),
            *_guid_and_vrs(extracted),
            "1.2",
            "1000",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "1000 cycles ok" in run.stdout


def _asan_works(tmp_path: Path) -> bool:
    probe = tmp_path / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    try:
        built = subprocess.run(
            [compiler(), "-fsanitize=address", "-o", str(tmp_path / "probe"), str(probe)],
            capture_output=True,
        )
        return built.returncode == 0 and subprocess.run([str(tmp_path / "probe")]).returncode == 0
    except OSError:
        return False


@pytest.mark.parametrize("family", FAMILIES)
def test_lifecycle_is_clean_under_address_sanitizer(fmus, tmp_path, family):
    if not _asan_works(tmp_path):
        pytest.skip("-fsanitize=address does not build or run here")
    sources = fmus["c", family] / "sources"
    flags = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all")
    fmu = tmp_path / "fmu_asan.so"
    subprocess.run(
        [
            compiler(),
            "-std=c99",
            "-O1",
            "-g",
            "-fPIC",
            "-shared",
            "-fvisibility=hidden",
            "-ffp-contract=off",
            "-Wall",
            "-Wextra",
            "-Werror",
            *flags,
            "-o",
            str(fmu),
            *source_files(family),
            "-lm",
        ],
        cwd=sources,
        check=True,
        capture_output=True,
    )
    host = tmp_path / "host_asan"
    compile_host(sources, host, flags)
    run = subprocess.run(
        [str(host), str(fmu), *_guid_and_vrs(fmus["c", family]), "1.2", "1000"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
