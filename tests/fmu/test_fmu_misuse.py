"""The C FMU under misuse: crafted and foreign FMU states, calls after fmi2Terminate, steps
beyond the stated limits, parameters that would make the level non-finite, and the one
warning when an input or the level leaves the model's validity envelope.

Driven through fmpy; a refusal raises FMICallException with status fmi2Error and leaves a log
line saying why.
"""

from __future__ import annotations

import struct
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error

from fmu_support import PLANTS, compiler, open_fmu
from gatetwin.errors import ExportError
from gatetwin.fmu import export_fmu
from gatetwin.fmu.limits import MAX_COMMUNICATION_STEP_S, PARAMETER_MAX_ABS
from gatetwin.plant.model import Schedule
from gatetwin.plant.simulate import ARX_MAX_SUBSTEPS, DELAY_HISTORY_CAPACITY

VALIDITY = {"validity": {"opening_mm": [10.0, 40.0], "flow_m3h": [30.0, 85.0],
                         "level_mm": [150.0, 450.0]}}  # fmt: skip
#: Bytes a serialised FOPDT state ends with after the history's head and count: the history
#: horizon (one double) and the effect blocks' state (nine doubles), see model_fopdt.h and
#: effects.h; the payload ends with ModelData.
TAIL_AFTER_COUNT = 8 + 9 * 8


def _unstable_arx():
    """a1 = 2: every sample doubles the deviation, so it overflows within ~1030 samples."""
    plant = PLANTS["arx"]()
    values = dict(plant.schedule.values, a1=(2.0, 2.0), a2=(0.0, 0.0))
    return replace(plant, schedule=Schedule(plant.schedule.flow_m3h, values))


BUILDS = {
    "fopdt": (lambda: PLANTS["fopdt"](), VALIDITY),
    "fopdt_twin": (lambda: PLANTS["fopdt"](), VALIDITY),  # same layout, another GUID
    "arx": (lambda: PLANTS["arx"](), VALIDITY),
    "arx_fast": (lambda: replace(PLANTS["arx"](), sample_period_s=0.5), {}),
    "arx_unstable": (_unstable_arx, {}),
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("misuse")
    out = {}
    for name, (plant, provenance) in BUILDS.items():
        fmu = export_fmu(plant(), folder / f"{name}.fmu", backend="c", model_name=f"m_{name}",
                         provenance=provenance)  # fmt: skip
        out[name] = Path(extract(str(fmu), str(folder / name)))
    return out


@pytest.fixture
def start(fmus):
    opened = []

    def start_(name, opening_mm=20.0, flow_m3h=50.0):
        driver = open_fmu(fmus[name], name)
        opened.append(driver)
        driver.start(opening_mm, flow_m3h)
        return driver

    yield start_
    for driver in opened:
        driver.close()


def _refused(driver, call, *words):
    """call() raises fmi2Error and logs an error line holding every word."""
    before = len(driver.messages)
    with pytest.raises(FMICallException) as failure:
        call()
    assert failure.value.status == fmi2Error
    errors = [m for status, m in driver.messages[before:] if status >= fmi2Error]
    assert errors and all(w in errors[-1] for w in words), driver.messages[before:]
    return errors[-1]


# -- FMU states -------------------------------------------------------------------------------


def _history_indices(data: bytes) -> tuple[int, int]:
    at = len(data) - TAIL_AFTER_COUNT - 8
    return struct.unpack_from("=ii", data, at)


def _with_indices(data: bytes, head: int, count: int) -> bytes:
    out = bytearray(data)
    struct.pack_into("=ii", out, len(data) - TAIL_AFTER_COUNT - 8, head, count)
    return bytes(out)


@pytest.mark.parametrize("head, count", [
    (0, DELAY_HISTORY_CAPACITY + 1), (0, 2**31 - 1), (0, -1), (0, 0),
    (DELAY_HISTORY_CAPACITY, 1), (-1, 1), (-(2**31), 1),
])  # fmt: skip
def test_a_state_with_history_indices_out_of_range_is_refused_and_changes_nothing(
    start, head, count
):
    driver = start("fopdt")
    for k in range(5):
        driver.step(1.0, 20.0 + 3.0 * k, 50.0)  # five input changes held for the dead time
    state = driver.slave.getFMUstate()
    data = driver.slave.serializeFMUstate(state)
    held = _history_indices(data)
    assert 0 <= held[0] < DELAY_HISTORY_CAPACITY and 2 <= held[1] <= 6  # the layout is right
    before = driver.level(), driver.slave.getReal([driver.vr["schedule.gain_mm_per_mm[2]"]])
    _refused(driver, lambda: driver.slave.deSerializeFMUstate(_with_indices(data, head, count),
                                                              state),
             "refused", "history")  # fmt: skip
    assert (driver.level(), driver.slave.getReal([driver.vr["schedule.gain_mm_per_mm[2]"]])) == \
        before  # fmt: skip
    driver.slave.setFMUstate(state)  # the state it was to overwrite is unchanged
    after = driver.slave.serializeFMUstate(state)
    assert after == data
    driver.step(1.0, 20.0, 50.0)  # the instance is still in step mode
    driver.slave.freeFMUstate(state)


def test_a_state_of_another_fmu_is_refused_by_its_guid(start):
    a, b = start("fopdt"), start("fopdt_twin")
    assert a.slave.guid != b.slave.guid
    state, own = a.slave.getFMUstate(), b.slave.getFMUstate()
    data = a.slave.serializeFMUstate(state)
    assert len(data) == len(b.slave.serializeFMUstate(own))  # same layout: only the GUID differs
    level = b.level()
    message = _refused(b, lambda: b.slave.deSerializeFMUstate(data), "the state is of FMU")
    assert a.slave.guid in message and b.slave.guid in message
    _refused(b, lambda: b.slave.setFMUstate(state), "not a state of this FMU")
    assert b.level() == level
    b.step(1.0, 20.0, 50.0)  # b stayed in step mode
    a.slave.freeFMUstate(state)
    b.slave.freeFMUstate(own)


def test_a_state_whose_guid_is_not_text_is_refused_in_printable_words(start):
    """The GUID of a state comes from the caller's bytes; the log line naming it must stay
    text a host can decode (raw bytes made fmpy's logger raise UnicodeDecodeError)."""
    driver = start("fopdt")
    state = driver.slave.getFMUstate()
    data = driver.slave.serializeFMUstate(state)
    guid = driver.slave.guid.encode()
    at = data.find(guid)
    assert at >= 0
    bad = data[:at] + bytes([0xFF, 0xC3, 0x80, 0x01]) + data[at + 4 :]
    message = _refused(driver, lambda: driver.slave.deSerializeFMUstate(bad), "the state is of FMU")
    assert message.isascii() and message.isprintable()
    assert "????" in message
    driver.slave.freeFMUstate(state)


def test_every_double_of_a_restored_state_must_be_finite(start):
    driver = start("fopdt")
    driver.step(1.0, 25.0, 50.0)
    state = driver.slave.getFMUstate()
    data = driver.slave.serializeFMUstate(state)
    x_at = len(data) - 9 * 8 - 8 - 8 - 2 * 8 * DELAY_HISTORY_CAPACITY - 8  # DynamicsState.x
    for value in (float("nan"), float("inf")):
        bad = bytearray(data)
        struct.pack_into("=d", bad, x_at, value)
        _refused(driver, lambda b=bytes(bad): driver.slave.deSerializeFMUstate(b), "not finite")
    _refused(driver, lambda: driver.slave.deSerializeFMUstate(data[:-1]), "bytes given")
    driver.slave.freeFMUstate(state)


# -- calls after fmi2Terminate -----------------------------------------------------------------


def test_calls_after_terminate_are_refused_and_logged(start):
    driver = start("fopdt")
    driver.step(1.0, 20.0, 50.0)
    level = driver.level()
    driver.slave.terminate()
    assert driver.level() == level  # getting values stays allowed after fmi2Terminate
    _refused(driver, lambda: driver.slave.doStep(1.0, 1.0), "fmi2DoStep", "terminated")
    driver.slave.reset()
    driver.start(20.0, 50.0)
    driver.slave.terminate()
    _refused(driver, lambda: driver.set_inputs(21.0, 50.0), "fmi2SetReal", "terminated")
    driver.slave.reset()
    driver.start(20.0, 50.0)
    driver.slave.terminate()
    _refused(driver, lambda: driver.slave.terminate(), "fmi2Terminate", "terminated")


# -- step limits -------------------------------------------------------------------------------


def test_a_step_beyond_the_maximum_is_refused_naming_the_limit(start):
    for name in ("fopdt", "arx"):
        driver = start(name)
        big = 1.2 * round(2.0 * MAX_COMMUNICATION_STEP_S / 1.2)
        _refused(driver, lambda d=driver, h=big: d.slave.doStep(0.0, h), f"{big:.17g} s",
                 f"{MAX_COMMUNICATION_STEP_S:g} s")  # fmt: skip
    driver = start("arx")
    _refused(driver, lambda: driver.slave.doStep(0.0, 1.2e9), "at most")


def test_an_arx_step_over_the_sample_budget_is_refused(start):
    driver = start("arx_fast")  # 0.5 s samples: the longest step would need 2e6
    h = 0.5 * (ARX_MAX_SUBSTEPS + 2)
    assert h <= MAX_COMMUNICATION_STEP_S
    _refused(driver, lambda: driver.slave.doStep(0.0, h), "ARX samples", "limit")


# -- non-finite levels -------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["schedule.gain_mm_per_mm[2]", "opening_ref_mm"])
def test_a_parameter_that_would_overflow_the_level_is_refused_at_run_time(start, name):
    driver = start("fopdt")
    driver.slave.setReal([driver.vr[name]], [1e308])
    _refused(driver, lambda: driver.step(1.0, 20.0, 50.0), name, f"{PARAMETER_MAX_ABS:g}")


def test_a_parameter_that_would_overflow_the_level_is_refused_at_initialisation(fmus):
    driver = open_fmu(fmus["fopdt"])
    driver.slave.setupExperiment(startTime=0.0)
    driver.slave.enterInitializationMode()
    driver.slave.setReal([driver.vr["schedule.gain_mm_per_mm[1]"]], [-1e300])
    _refused(driver, driver.slave.exitInitializationMode, "schedule.gain_mm_per_mm[1]")
    driver.close()


@pytest.mark.parametrize("name, change", [
    ("gain", {"gain_mm_per_mm": (-15.4, 1e308, -10.5)}), ("opening_ref", None),
])  # fmt: skip
def test_export_refuses_a_parameter_that_would_overflow_the_level(tmp_path, name, change):
    plant = PLANTS["fopdt"]()
    if change is None:
        plant, expected = replace(plant, opening_ref_mm=1e308), "opening_ref_mm"
    else:
        values = dict(plant.schedule.values, **change)
        plant = replace(plant, schedule=Schedule(plant.schedule.flow_m3h, values))
        expected = "schedule.gain_mm_per_mm[2]"
    for backend in ("c", "python"):
        with pytest.raises(ExportError, match=expected.replace("[", r"\[")):
            export_fmu(plant, tmp_path / "m.fmu", backend=backend, model_name="m",
                       provenance={})  # fmt: skip
    assert not list(tmp_path.iterdir())  # nothing left behind


def test_a_diverging_model_is_stopped_when_its_level_stops_being_finite(start):
    driver = start("arx_unstable", opening_mm=25.0)
    # a 5 mm move from the equilibrium doubles every sample: 2**900 * 5 mm is still a double,
    # 2**1100 * 5 mm is not
    driver.step(1.2 * 900, 30.0, 50.0)
    assert np.isfinite(driver.level()) and abs(driver.level()) > 1e250
    _refused(driver, lambda: driver.step(1.2 * 200, 30.0, 50.0), "level_3F_mm", "not finite")


# -- the validity envelope ---------------------------------------------------------------------


def _warnings(driver) -> list[str]:
    return [m for status, m in driver.messages if status == 1]


@pytest.mark.parametrize("steps, expected", [
    ([(50.0, 50.0)], "opening_mm 50 outside the model's validity 10..40 mm; "
                     "results are extrapolated"),
    ([(20.0, 100.0)], "flow_m3h 100 outside the model's validity 30..85 m3/h; "
                      "results are extrapolated"),
])  # fmt: skip
def test_leaving_the_envelope_warns_once_naming_the_input_and_its_range(start, steps, expected):
    driver = start("fopdt")
    assert _warnings(driver) == []
    for opening_mm, flow_m3h in steps:
        driver.step(1.0, opening_mm, flow_m3h)
    assert _warnings(driver) == [expected]
    for opening_mm, flow_m3h in ((5.0, 20.0), (45.0, 90.0), (20.0, 10.0)):
        driver.step(1.0, opening_mm, flow_m3h)
    assert len(_warnings(driver)) == 1


def test_the_level_leaving_the_envelope_warns_once(start):
    driver = start("fopdt")
    driver.step(300.0, 40.0, 50.0)  # level_ref 300 - 12 * 20 mm: below 150 mm after ~5 T
    assert driver.level() < 150.0
    (warning,) = _warnings(driver)
    assert warning.startswith("level_3F_mm ")
    assert warning.endswith(" outside the model's validity 150..450 mm; results are extrapolated")


def test_a_state_restores_whether_the_warning_was_given(start):
    driver = start("fopdt")
    state = driver.slave.getFMUstate()
    driver.step(1.0, 50.0, 50.0)
    driver.slave.setFMUstate(state)
    driver.time_s = 0.0
    driver.step(1.0, 50.0, 50.0)
    assert len(_warnings(driver)) == 2  # the restored state had not warned yet
    driver.slave.freeFMUstate(state)


@pytest.mark.parametrize("validity, words", [
    ({"flow_m3h": [90.0, 30.0]}, "provenance.validity.flow_m3h"),
    ({"level_mm": ["1); exit(1", 2]}, "provenance.validity.level_mm"),
    ({"opening_mm": [float("nan"), 1.0]}, "provenance.validity.opening_mm"),
    ([1, 2], "provenance.validity must be an object"),
])  # fmt: skip
def test_export_refuses_a_malformed_envelope(tmp_path, validity, words):
    with pytest.raises(ExportError, match=words.replace(".", r"\.")):
        export_fmu(PLANTS["fopdt"](), tmp_path / "m.fmu", backend="c", model_name="m",
                   provenance={"validity": validity})  # fmt: skip
