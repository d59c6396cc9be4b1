"""The observer FMUs with reference gauges: the gauge-drift rule (gatetwin.mpc.gauge_drift)
generated into C beside either observer equals the Python rule on a flume record outside the
bundled and calibration sets, flags the diagnosis suite's drift within its bound, stays down
on the clean record, and refuses bad references, parameters and inputs."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from gatetwin.diagnosis.onset import ONSET_EFFECTS, detection
from gatetwin.errors import ExportError
from gatetwin.flume.experiments import run_scenario
from gatetwin.fmu.observer_fmu import export_observer, run_observer_fmu
from gatetwin.mpc.gauge_drift import DRIFT_KIND, WINDOW_SAMPLES, with_gauge_rule
from gatetwin.mpc.online import OnlineObserver
from gatetwin.plant.model import FopdtPlant
from observer_cases import ROOT, envelope_plant, flume_scenario, held_opening

GAUGE = "3F"
REFERENCES = ("1D", "2E", "4G", "5H")
DRIFT_MM_PER_S = ONSET_EFFECTS["sensor_drift"]["rate_mm_per_s"]
#: One window: once it has drifted whole the slope is the drift's rate, twice the threshold
#: (tests/mpc/test_gauge_drift.py, the same bound for the Python rule).
DRIFT_BOUND_S = WINDOW_SAMPLES * 1.2
#: The FMU's arithmetic is generated from the Python rule and observer; the observer's
#: outputs carry round-off of the filters' ~1e-13 mm (test_observer_envelope_fmu.py), the
#: slope that of a sum of 400 products of ~100 mm by weights of ~1e-5 /s (~1e-15 mm/s).
TOL = 1e-9


@pytest.fixture(scope="module")
def record():
    """The flume record (seed 1301, 1120 s): time, the observer's inputs, every gauge."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rec = run_scenario(flume_scenario())
    levels = {g: np.asarray(v, dtype=float) for g, v in rec.levels_mm.items()}
    e = held_opening(np.asarray(rec.opening_mm, dtype=float))
    return np.asarray(rec.time_s, dtype=float), levels, e, np.asarray(rec.flow_m3h, dtype=float)


@pytest.fixture(scope="module")
def envelope_fmu(tmp_path_factory):
    out = tmp_path_factory.mktemp("drift") / "envelope_drift.fmu"
    return export_observer(envelope_plant(), out, reference_gauges=REFERENCES)


def _drifted(record):
    t, levels, e, q = record
    onset = int(np.searchsorted(t, 0.3 * t[-1]))
    y = levels[GAUGE] + DRIFT_MM_PER_S * np.maximum(t - t[onset], 0.0)
    return onset, y


def _python(plant, linearisation, y, levels, e, q):
    observer = OnlineObserver(plant, linearisation=linearisation)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        out = observer.run(y, e, q)
    return with_gauge_rule(out, y, [levels[g] for g in REFERENCES])


def _compare(fmu_out, ref, window):
    for name, got in fmu_out.items():
        want = np.asarray(ref[name], dtype=float)
        if name == "gauge_slope_mm_per_s":  # the FMU gives 0 until the window is full
            assert not got[: window - 1].any()
            got, want = got[window - 1 :], want[window - 1 :]
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL, err_msg=name)


def test_envelope_fmu_equals_python_and_flags_the_drift(record, envelope_fmu):
    t, levels, e, q = record
    onset, y = _drifted(record)
    refs = {g: levels[g] for g in REFERENCES}
    got = run_observer_fmu(envelope_fmu, y, e, q, reference_levels_mm=refs)
    ref = _python(envelope_plant(), "envelope", y, levels, e, q)
    _compare(got, ref, WINDOW_SAMPLES)
    found = detection(t, got["gauge_drift"], onset)
    assert found.false_alarms == 0
    assert found.delay_s <= DRIFT_BOUND_S, f"flagged after {found.delay_s} s"
    # the anomaly flag is up wherever the rule is, with kind 4 where the rule alone holds
    assert (got["anomaly"][got["gauge_drift"] > 0.5] == 1.0).all()
    assert (got["anomaly_kind"] == DRIFT_KIND).any()


def test_no_drift_flag_on_the_clean_record(record, envelope_fmu):
    t, levels, e, q = record
    got = run_observer_fmu(envelope_fmu, levels[GAUGE], e, q,
                           reference_levels_mm={g: levels[g] for g in REFERENCES})  # fmt: skip
    assert not got["gauge_drift"].any()
    assert not (got["anomaly_kind"] == DRIFT_KIND).any()
    assert np.abs(got["gauge_slope_mm_per_s"][WINDOW_SAMPLES:]).max() > 0.0


def test_schedule_fmu_under_fmi3_equals_python(record, tmp_path):
    from gatetwin.modelfile import read_model_file

    plant = read_model_file(ROOT / "models/fopdt_3F.json").plant
    assert isinstance(plant, FopdtPlant)
    t, levels, e, q = record
    onset, y = _drifted(record)
    fmu = export_observer(plant, tmp_path / "schedule_drift.fmu", without_effects=True,
                          fmi_version="3.0", reference_gauges=REFERENCES[:2])  # fmt: skip
    refs = {g: levels[g] for g in REFERENCES[:2]}
    got = run_observer_fmu(fmu, y, e, q, reference_levels_mm=refs)
    observer = OnlineObserver(dataclasses.replace(plant, effects=()), linearisation="schedule")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        est = observer.run(y, e, q)
    ref = with_gauge_rule(est, y, list(refs.values()))
    _compare(got, ref, WINDOW_SAMPLES)
    assert detection(t, got["gauge_drift"], onset).delay_s <= DRIFT_BOUND_S


def test_a_threshold_parameter_moves_the_flag(record, envelope_fmu):
    """The fixed parameter gauge_drift_threshold_mm_per_s is the rule's threshold: at twice
    the largest slope the drift reaches on this record the flag never rises."""
    t, levels, e, q = record
    _, y = _drifted(record)
    refs = {g: levels[g] for g in REFERENCES}
    first = run_observer_fmu(envelope_fmu, y, e, q, reference_levels_mm=refs)
    high = 2.0 * np.abs(first["gauge_slope_mm_per_s"]).max()
    got = run_observer_fmu(envelope_fmu, y, e, q, reference_levels_mm=refs,
                           parameters={"gauge_drift_threshold_mm_per_s": high})  # fmt: skip
    assert not got["gauge_drift"].any()
    np.testing.assert_array_equal(got["gauge_slope_mm_per_s"], first["gauge_slope_mm_per_s"])


@pytest.mark.parametrize("references, match", [
    (("3F",), "repeat"), (("1D", "1D"), "repeat"), (("1D", "x<y"), "not a gauge name"),
    ("1D", "sequence"),
])  # fmt: skip
def test_export_refuses_bad_references(tmp_path, references, match):
    out = tmp_path / "x.fmu"
    with pytest.raises(ExportError, match=match):
        export_observer(envelope_plant(), out, reference_gauges=references)
    assert not out.exists()


def _initialised(fmu, folder, params):
    from fmpy import extract

    from fmu_support import open_fmu

    driver = open_fmu(extract(str(fmu), str(folder)))
    driver.slave.setupExperiment(startTime=0.0)
    driver.slave.enterInitializationMode()
    for name, value in params.items():
        driver.slave.setReal([driver.vr[name]], [value])
    return driver


def test_a_bad_threshold_is_refused_at_initialisation_with_a_logged_reason(envelope_fmu,
                                                                           tmp_path):  # fmt: skip
    from fmpy.fmi1 import FMICallException

    driver = _initialised(envelope_fmu, tmp_path, {"gauge_drift_threshold_mm_per_s": 0.0})
    try:
        with pytest.raises(FMICallException):
            driver.slave.exitInitializationMode()
        assert any("gauge_drift_threshold_mm_per_s" in m for _, m in driver.messages)
    finally:
        driver.slave.freeInstance()


def test_a_missing_reference_level_is_refused_with_a_logged_reason(envelope_fmu, tmp_path):
    from fmpy.fmi1 import FMICallException

    driver = _initialised(envelope_fmu, tmp_path, {})
    try:
        driver.slave.exitInitializationMode()
        with pytest.raises(FMICallException):  # refused where it is set
            driver.slave.setReal([driver.vr["level_2E_mm"]], [float("nan")])
        assert any("level_2E_mm" in m for _, m in driver.messages), driver.messages
    finally:
        driver.slave.freeInstance()


def test_a_restored_state_replays_the_rule(record, envelope_fmu, tmp_path):
    """The rule's window and count travel in the FMU state."""
    t, levels, e, q = record
    driver = _initialised(envelope_fmu, tmp_path, {})
    slave, vr = driver.slave, driver.vr
    inputs = [vr[n] for n in ("level_3F_mm", "opening_mm", "flow_m3h")]
    inputs += [vr[f"level_{g}_mm"] for g in REFERENCES]
    slopes = [vr["gauge_slope_mm_per_s"], vr["gauge_drift"]]

    def run(first, n):
        rows = []
        for k in range(first, first + n):
            values = [levels[GAUGE][k], e[k], q[k], *(levels[g][k] for g in REFERENCES)]
            slave.setReal(inputs, values)
            slave.doStep(currentCommunicationPoint=k * 1.2, communicationStepSize=1.2)
            rows.append(slave.getReal(slopes))
        return rows

    try:
        slave.exitInitializationMode()
        run(0, WINDOW_SAMPLES)
        state = slave.getFMUstate()
        first = run(WINDOW_SAMPLES, 10)
        slave.setFMUstate(state)
        assert run(WINDOW_SAMPLES, 10) == first
        assert any(row[0] != 0.0 for row in first)
        slave.freeFMUstate(state)
    finally:
        slave.freeInstance()


def test_export_observer_cli_writes_the_reference_inputs(tmp_path):
    from fmpy import read_model_description

    from gatetwin.cli import main

    out = tmp_path / "obs.fmu"
    assert main(["export-observer", str(ROOT / "models/physical_3F.json"), "--without-effects",
                 "--out", str(out), "--reference-gauges", "1D", "5H"]) == 0  # fmt: skip
    md = read_model_description(str(out))
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    assert inputs == {"level_3F_mm", "level_1D_mm", "level_5H_mm", "opening_mm", "flow_m3h"}
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    assert {"gauge_slope_mm_per_s", "gauge_drift"} <= outputs
    assert validate_fmu(str(out)) == []
