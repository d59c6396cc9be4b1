"""The C FMU's step cache (``StepCache`` in fmu_templates/plant_data.h): what a step derives
from its discharge and the parameters alone (the knot position, the scheduled parameters, an
envelope's steady point at the arrived opening) is kept between steps and re-derived when the
discharge, the opening or a parameter changes. It must change no output bit, and a restored
FMU state must carry a cache that is what a recomputation gives.

Each test plant (the bundled envelope FOPDT and ARX, the local FOPDT and ARX test plants) is
driven with openings and discharges that go back and forth, so the cache is hit, missed and
overwritten; the references are the Python simulator, the uncached python FMU (it derives
everything at every step) and the C FMU itself with its cache dropped before every step.
"""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error

from fmu_support import PLANTS, TESTS, compiler, fmu_run, open_fmu, reference_run
from gatetwin.fmu import export_fmu
from gatetwin.modelfile import read_model_file

MODELS = Path(__file__).resolve().parents[2] / "models"
#: C and Python run the same IEEE operations in the same order and call the same libm here;
#: another C library's exp and pow may differ by an ulp, which the dynamics carry at most to
#: ~1e-12 mm on levels of a few hundred mm (the bound tests/fmu/test_fmu_bundled.py also uses).
TOLERANCE_MM = 1e-9
#: name -> (the plant, two parameters set between steps with the factor each is scaled by)
CASES = {
    "fopdt_3F": ("envelope.width_m", 1.03, "opening_ref_mm", 1.05),
    "arx_3F": ("envelope.width_m", 1.03, "opening_ref_mm", 1.05),
    "fopdt": ("schedule.gain_mm_per_mm[2]", 1.1, "opening_ref_mm", 1.05),
    "arx": ("schedule.b1[1]", 1.1, "opening_ref_mm", 1.05),
}
N_STEPS = 240


def _plant(name: str):
    if name in PLANTS:
        return PLANTS[name]()
    return read_model_file(MODELS / f"{name}.json").plant


@pytest.fixture(scope="module")
def extracted(tmp_path_factory) -> dict[tuple[str, str], Path]:
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("cache")
    out = {}
    for name in CASES:
        for key, backend, version in (("c", "c", "2.0"), ("fmi3", "c", "3.0"),
                                      ("python", "python", "2.0")):  # fmt: skip
            fmu = export_fmu(_plant(name), folder / f"{name}_{key}.fmu", backend=backend,
                             model_name=f"cache_{name}", provenance={"purpose": "test"},
                             fmi_version=version)  # fmt: skip
            out[(name, key)] = Path(extract(str(fmu), str(folder / f"{name}_{key}")))
    return out


def _inputs(name: str, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, openings and discharges that go back and forth among a few values, each held
    for 1-3 (opening) or 1-5 (discharge) steps, independently: every step meets a cache that
    holds for its inputs, for its discharge only, or for neither. The discharge visits a knot
    exactly; FOPDT steps of 0.4-2.5 s let inputs arrive inside a step after the dead time."""
    rng = np.random.default_rng(seed)
    plant = _plant(name)
    period = getattr(plant, "sample_period_s", None)
    if period is None:
        steps = rng.choice([0.4, 1.0, 2.5], N_STEPS - 1)
    else:
        steps = period * rng.integers(1, 3, N_STEPS - 1)
    times = np.concatenate([[0.0], np.cumsum(steps)])
    ref = plant.opening_ref_mm
    knot = plant.schedule.flow_m3h[len(plant.schedule.flow_m3h) // 2]
    openings = np.repeat(rng.choice([ref - 5.0, ref, ref + 4.0], N_STEPS),
                         rng.integers(1, 4, N_STEPS))[:N_STEPS]  # fmt: skip
    flows = np.repeat(rng.choice([47.0, 55.0, float(knot)], N_STEPS),
                      rng.integers(1, 6, N_STEPS))[:N_STEPS]  # fmt: skip
    return times, openings, flows


def _set(driver, name: str, value: float) -> None:
    vr = [driver.vr[name]]
    if hasattr(driver.slave, "setFloat64"):
        driver.slave.setFloat64(vr, [value])
    else:
        driver.slave.setReal(vr, [value])


def _get(driver, name: str) -> float:
    vr = [driver.vr[name]]
    if hasattr(driver.slave, "getFloat64"):
        return driver.slave.getFloat64(vr)[0]
    return driver.slave.getReal(vr)[0]


def _run(path: Path, times, openings, flows, before_step=None) -> np.ndarray:
    """Levels of one instance; ``before_step(driver, i)`` is called before step i."""
    driver = open_fmu(path, path.name, logging_on=False)
    try:
        if before_step is None:
            return fmu_run(driver, times, openings, flows)
        driver.start(float(openings[0]), float(flows[0]), float(times[0]))
        out = [driver.level()]
        for i in range(1, len(times)):
            before_step(driver, i)
            out.append(driver.step(float(times[i] - times[i - 1]), float(openings[i - 1]),
                                   float(flows[i - 1])))  # fmt: skip
        return np.array(out)
    finally:
        driver.close()


@pytest.mark.parametrize("name", CASES)
def test_steps_through_the_cache_are_the_steps_without_it(extracted, name):
    times, openings, flows = _inputs(name)
    cached = _run(extracted[(name, "c")], times, openings, flows)

    def drop_cache(driver, i):  # a parameter set (to its own value) drops the cache
        _set(driver, "opening_ref_mm", _get(driver, "opening_ref_mm"))

    fresh = _run(extracted[(name, "c")], times, openings, flows, drop_cache)
    assert cached.tobytes() == fresh.tobytes()  # bit for bit
    fmi3 = _run(extracted[(name, "fmi3")], times, openings, flows)
    assert fmi3.tobytes() == cached.tobytes()
    reference = reference_run(_plant(name), times, openings, flows)
    assert np.max(np.abs(cached - reference)) <= TOLERANCE_MM


@pytest.mark.parametrize("name", CASES)
def test_a_parameter_set_between_steps_acts_from_the_next_step(extracted, name):
    times, openings, flows = _inputs(name, seed=4)
    first, first_factor, second, second_factor = CASES[name]
    start = {}

    def change(driver, i):
        if i == 1:
            start.update({n: _get(driver, n) for n in (first, second)})
        if i == N_STEPS // 4:
            _set(driver, first, start[first] * first_factor)
        if i == N_STEPS // 2:
            _set(driver, second, start[second] * second_factor)
        if i == 3 * N_STEPS // 4:
            _set(driver, first, start[first])

    c = _run(extracted[(name, "c")], times, openings, flows, change)
    python = _run(extracted[(name, "python")], times, openings, flows, change)
    assert np.max(np.abs(c - python)) <= TOLERANCE_MM
    unchanged = _run(extracted[(name, "c")], times, openings, flows)
    k = N_STEPS // 4
    assert unchanged[:k].tobytes() == c[:k].tobytes()
    # the change moves the level by far more than round-off (a few % of a parameter)
    assert np.max(np.abs(c[k + 1 :] - unchanged[k + 1 :])) > 1e3 * TOLERANCE_MM


@pytest.mark.parametrize("name", CASES)
def test_a_state_taken_before_a_discharge_change_repeats_the_steps_after_it(extracted, name):
    plant = _plant(name)
    h = getattr(plant, "sample_period_s", 1.0)
    before = (float(plant.opening_ref_mm), 47.0)
    after = (float(plant.opening_ref_mm) + 4.0, 55.0)
    driver = open_fmu(extracted[(name, "c")], name, logging_on=False)
    try:
        driver.start(*before)
        for _ in range(12):
            driver.step(h, *before)
        state, taken_s = driver.slave.getFMUstate(), driver.time_s
        serialised = driver.slave.serializeFMUstate(state)
        changed = [driver.step(h, *after) for _ in range(12)]
        driver.slave.setFMUstate(state)
        driver.time_s = taken_s
        held = [driver.step(h, *before) for _ in range(12)]
        driver.slave.deSerializeFMUstate(serialised, state)
        driver.slave.setFMUstate(state)
        driver.time_s = taken_s
        again = [driver.step(h, *after) for _ in range(12)]
        driver.slave.freeFMUstate(state)
    finally:
        driver.close()
    assert again == changed
    t = h * np.arange(25)  # the start, 12 steps before the state, 12 after it
    for levels, inputs in ((changed, after), (held, before)):
        opening = np.array([before[0]] * 12 + [inputs[0]] * 13)  # step i takes inputs[i - 1]
        flow = np.array([before[1]] * 12 + [inputs[1]] * 13)
        direct = _run(extracted[(name, "c")], t, opening, flow)
        assert direct[13:].tolist() == levels  # bit for bit
        reference = reference_run(plant, t, opening, flow)
        assert np.max(np.abs(np.array(levels) - reference[13:])) <= TOLERANCE_MM


# -- restored caches ---------------------------------------------------------------------------


def _layout(extracted: Path, folder: Path) -> tuple[int, dict[str, int]]:
    """sizeof(ModelData) and the offsets of the step cache's fields (tests/c/fmu_layout.c)."""
    probe = folder / f"{extracted.name}_layout"
    subprocess.run(
        [compiler(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-I", str(extracted / "sources"),
         "-o", str(probe), str(TESTS / "c" / "fmu_layout.c")],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    size = subprocess.run([str(probe)], check=True, capture_output=True, text=True).stdout
    fields = subprocess.run([str(probe), "cache"], check=True, capture_output=True, text=True)
    data_size = int(next(line.split()[1] for line in size.splitlines()
                         if line.startswith("data_size")))  # fmt: skip
    return data_size, {k: int(v) for k, v in (line.split() for line in fields.stdout.splitlines())}


def _tampered(data: bytes, data_size: int, offset: int, fmt: str, change) -> bytes:
    """The serialised state with one field of ModelData (at ``offset``) changed; a serialised
    state ends with ModelData."""
    out = bytearray(data)
    at = len(data) - data_size + offset
    (value,) = struct.unpack_from(fmt, out, at)
    struct.pack_into(fmt, out, at, change(value))
    return bytes(out)


#: field -> (struct format, change): each makes the cache disagree with its recomputation
TAMPERING = {
    "cache.valid": ("=i", lambda v: 2),
    "cache.flow_m3h": ("=d", lambda v: v + 1.0),
    "cache.at.index": ("=i", lambda v: v + 1),
    "cache.at.weight": ("=d", lambda v: v + 0.25),
    "cache.dyn": ("=d", lambda v: v * 1.01),  # K (FOPDT) or a1 (ARX)
    "cache.dyn.point_valid": ("=i", lambda v: 7),
    "cache.dyn.point_u_mm": ("=d", lambda v: v + 1.0),
    "cache.dyn.point_level_mm": ("=d", lambda v: np.nextafter(v, np.inf)),  # one ulp
    "cache.dyn.decay_filled": ("=i", lambda v: 7),  # an FOPDT's decays of its last pieces
    # past the last slot (a full ring takes any next slot in range: an envelope FOPDT's
    # secant time constant fills it while the level moves)
    "cache.dyn.decay_next": ("=i", lambda v: v + 3),
    "cache.dyn.decay": ("=d", lambda v: np.nextafter(v, np.inf)),  # one ulp, the first slot
}


@pytest.mark.parametrize("name", CASES)
def test_a_restored_cache_that_is_not_its_recomputation_is_refused(extracted, name, tmp_path):
    data_size, offsets = _layout(extracted[(name, "c")], tmp_path)
    driver = open_fmu(extracted[(name, "c")], name)
    try:
        driver.start(20.0, 47.0)
        h = 1.2 if name.startswith("arx") else 1.0
        for k in range(6):
            driver.step(h, 20.0 + 2.0 * (k % 2), 55.0)
        state = driver.slave.getFMUstate()
        data = driver.slave.serializeFMUstate(state)
        level = driver.level()
        tried = 0
        for field, (fmt, change) in TAMPERING.items():
            if field not in offsets:
                continue  # a local model's cache holds no steady point
            bad = _tampered(data, data_size, offsets[field], fmt, change)
            assert bad != data
            before = len(driver.messages)
            with pytest.raises(FMICallException) as failure:
                driver.slave.deSerializeFMUstate(bad, state)
            assert failure.value.status == fmi2Error
            errors = [m for status, m in driver.messages[before:] if status >= fmi2Error]
            assert errors and "refused" in errors[-1] and "cache" in errors[-1], field
            tried += 1
        # five fields in every cache, three of an envelope's steady point, three of an FOPDT's
        # decays
        assert tried == 5 + 3 * name.endswith("3F") + 3 * name.startswith("fopdt")
        assert driver.slave.serializeFMUstate(state) == data  # the refusals changed nothing
        assert driver.level() == level
        driver.slave.freeFMUstate(state)
    finally:
        driver.close()


@pytest.mark.parametrize("name", ["fopdt_3F", "arx"])
def test_a_cache_a_parameter_change_drops_is_not_held_against_a_state(extracted, name,
                                                                      tmp_path):  # fmt: skip
    """After a parameter is set the cache is re-derived before any use, so whatever it holds
    does not matter: the state restores and steps as the untouched one does."""
    data_size, offsets = _layout(extracted[(name, "c")], tmp_path)
    driver = open_fmu(extracted[(name, "c")], name)
    h = 1.2 if name.startswith("arx") else 1.0
    try:
        driver.start(20.0, 47.0)
        for _ in range(4):
            driver.step(h, 22.0, 55.0)
        _set(driver, "opening_ref_mm", _get(driver, "opening_ref_mm") * 1.05)
        state, taken_s = driver.slave.getFMUstate(), driver.time_s
        data = driver.slave.serializeFMUstate(state)
        expected = [driver.step(h, 22.0, 55.0) for _ in range(3)]
        stale = _tampered(data, data_size, offsets["cache.dyn"], "=d", lambda v: v * 1.01)
        driver.slave.deSerializeFMUstate(stale, state)
        driver.slave.setFMUstate(state)
        driver.time_s = taken_s
        assert [driver.step(h, 22.0, 55.0) for _ in range(3)] == expected
        driver.slave.freeFMUstate(state)
    finally:
        driver.close()
