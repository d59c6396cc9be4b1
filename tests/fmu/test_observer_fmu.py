"""The observer FMU (gatetwin.fmu.observer_fmu) against its Python rendering
(gatetwin.mpc.online.OnlineObserver), its refusals, and online detection of hidden effects
(gatetwin.diagnosis.onset) on bundled records."""

from __future__ import annotations

import dataclasses
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.diagnosis.onset import OnsetError, detection, first_move_after, with_onset
from gatetwin.errors import ControlError, ExportError
from gatetwin.fmu.observer_fmu import export_observer, run_observer_fmu
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.online import (
    MONITORING,
    OUTPUTS,
    AnomalySettings,
    OnlineObserver,
    measured_inputs,
)
from gatetwin.plant.model import FLOW_RANGE_M3H
from gatetwin.plant.simulate import simulate
from gatetwin.records import read_record
from observer_cases import TOL, observer_steps

ROOT = Path(__file__).resolve().parents[2]

#: Detection bound for a gate fault: half the shortest time constant of the pool at gauge 3F
#: (43-75 s in fopdt_3F), i.e. before the level has gone 40 % of its way to the new rest.
GATE_FAULT_BOUND_S = 21.5
#: Detection bound for an unseen inflow on the observer's own model: the run length (4 samples).
#: The schedule's level moves with the discharge at once (level_ref(Q + 5 m3/h) - level_ref(Q):
#: some 35 mm, 35 noise SDs), a step the persistent rule sees within a sample or two.
INFLOW_BOUND_S = 4.8


@pytest.fixture(scope="module")
def plant():
    return dataclasses.replace(read_model_file(ROOT / "models/fopdt_3F.json").plant, effects=())


@pytest.fixture(scope="module")
def fmu(plant, tmp_path_factory):
    return export_observer(plant, tmp_path_factory.mktemp("obs") / "observer.fmu")


def _inputs(name: str):
    record = read_record(bundled_records_dir() / f"{name}.csv")
    return (record.time_s, *measured_inputs(record, "3F"))


@pytest.mark.parametrize("name", ["C", "Q55", "Eboth"])
def test_fmu_equals_the_python_observer_on_a_bundled_record(plant, fmu, name):
    """C: PRBS moves; Q55: a step; Eboth: discharge changes (the model re-rendered)."""
    _, y, e, q = _inputs(name)
    got = run_observer_fmu(fmu, y, e, q)
    ref = OnlineObserver(plant).run(y, e, q)
    for key in OUTPUTS:
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=TOL, err_msg=key)
    assert np.ptp(ref["innovation_mm"]) > 1.0  # the record moves the observer


def test_a_scheduled_dead_time_is_followed_across_discharges(plant, tmp_path):
    """Dead times of 0.5-3.6 s (0-3 whole samples plus a fraction), re-rendered at every
    measured discharge of Eboth (45-75 m3/h): the register's symbolic placement in C."""
    from gatetwin.plant.model import Schedule

    s = plant.schedule
    delays = (0.5, 1.0, 1.5, 2.4, 3.0, 3.6)
    slow = dataclasses.replace(
        plant, schedule=Schedule(s.flow_m3h, {**s.values, "dead_time_s": delays})
    )
    fmu = export_observer(slow, tmp_path / "delayed.fmu")
    _, y, e, q = _inputs("Eboth")
    got = run_observer_fmu(fmu, y, e, q)
    ref = OnlineObserver(slow).run(y, e, q)
    for key in OUTPUTS:
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=TOL, err_msg=key)


def test_a_saved_state_replays_the_same_samples(fmu):
    _, y, e, q = _inputs("C")
    slave, vr = _slave(fmu)
    slave.exitInitializationMode()

    def run(first: int) -> list[list[float]]:
        return observer_steps(slave, vr, OUTPUTS, y, e, q, first)

    run(0)
    state = slave.getFMUstate()
    first = run(20)
    slave.setFMUstate(state)
    again = run(20)
    slave.freeFMUstate(state)
    slave.freeInstance()
    assert first == again and first[0] != first[-1]


@pytest.mark.parametrize(("name", "value"), [("level_3F_mm", float("nan")),
                                             ("flow_m3h", 2.0 * FLOW_RANGE_M3H[1])])  # fmt: skip
def test_a_bad_measurement_is_refused(fmu, name, value):
    """By the glue when it is set (not finite) or by the observer at the step (a discharge
    outside the plants' range)."""
    from fmpy.fmi1 import FMICallException

    slave, vr = _slave(fmu)
    slave.exitInitializationMode()
    with pytest.raises(FMICallException):
        slave.setReal([vr[name]], [value])
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.2)
    slave.freeInstance()


def test_fmu_passes_fmpy_validation_and_carries_its_sources(fmu):
    assert validate_fmu(str(fmu)) == []
    names = zipfile.ZipFile(fmu).namelist()
    assert {"sources/observer.c", "sources/observer_generated.c", "sources/model_config.h",
            "resources/observer.json"} <= set(names)  # fmt: skip


def test_parameters_set_in_initialisation_are_the_ones_used(plant, fmu):
    """horizon_s = 0: the forecast is the filtered level (at a steady discharge: the model's
    level offset follows the measured one); band and run from the master."""
    _, y, e, q = _inputs("C")
    q = np.full(q.size, np.median(q))
    params = {"horizon_s": 0.0, "anomaly_band_sigma": 1.5, "anomaly_run_samples": 2.0,
              "anomaly_cusum_slack_sigma": 0.5, "anomaly_cusum_threshold": 4.0}  # fmt: skip
    got = run_observer_fmu(fmu, y, e, q, params)
    np.testing.assert_allclose(got["predicted_level_mm"], got["filtered_level_mm"], rtol=0,
                               atol=TOL)  # fmt: skip
    anomaly = AnomalySettings(1.5, 2, 0.5, 4.0)
    ref = OnlineObserver(plant, horizon_s=0.0, anomaly=anomaly).run(y, e, q)
    for key in ("anomaly", "anomaly_kind", "cusum_high", "cusum_low"):
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=TOL, err_msg=key)
    # a band and a threshold this narrow are passed on the flume's record, by both rules
    assert {1.0, 2.0} <= set(got["anomaly_kind"])


def test_anomaly_is_the_run_outside_the_scaled_band_or_the_cusum(fmu):
    _, y, e, q = _inputs("Erandom60")
    a = AnomalySettings()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = run_observer_fmu(fmu, y, e, q)
    outside = np.abs(got["innovation_normalised"]) > a.band_sigma * got["innovation_scale"]
    expected = np.zeros(y.size)
    for k in range(y.size):
        expected[k] = (expected[k - 1] + 1 if k else 1) if outside[k] else 0
    np.testing.assert_array_equal(got["anomaly_samples"], expected)
    fast = expected >= a.run_samples
    persistent = np.maximum(got["cusum_high"], got["cusum_low"]) >= a.cusum_threshold
    np.testing.assert_array_equal(got["anomaly_kind"], np.where(fast, 1.0, 2.0 * persistent))
    np.testing.assert_array_equal(got["anomaly"], (fast | persistent).astype(float))
    assert np.all(got["innovation_scale"] >= 1.0) and got["innovation_scale"].max() > 1.0
    assert expected.max() >= 1 and got["cusum_high"].max() > 0 and got["cusum_low"].max() > 0


def _slave(fmu, params=None):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)), instanceName="t",
                      modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
    slave.instantiate(loggingOn=False)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    for name, value in (params or {}).items():
        slave.setReal([vr[name]], [value])
    slave.setReal([vr["level_3F_mm"], vr["opening_mm"], vr["flow_m3h"]], [250.0, 30.0, 50.0])
    return slave, vr


def test_a_step_of_whole_samples_takes_the_held_inputs_for_each(plant, fmu):
    slave, vr = _slave(fmu)
    slave.exitInitializationMode()
    slave.setReal([vr["level_3F_mm"]], [256.0])
    slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=3 * 1.2)
    got = slave.getReal([vr[n] for n in OUTPUTS])
    slave.freeInstance()
    obs = OnlineObserver(plant)
    obs.reset(30.0, 250.0, 50.0)
    for _ in range(3):
        ref = obs.step(256.0, 30.0, 50.0)
    np.testing.assert_allclose(got, ref.values(), rtol=0, atol=TOL)


def test_a_step_beyond_the_sample_budget_is_refused(fmu):
    """The longest step is taken; one sample more is refused (not worked through)."""
    from fmpy.fmi1 import FMICallException

    from gatetwin.fmu.observer_config import MAX_SAMPLES_PER_STEP

    slave, vr = _slave(fmu)
    slave.exitInitializationMode()
    slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=MAX_SAMPLES_PER_STEP * 1.2)
    assert np.all(np.isfinite(slave.getReal([vr[n] for n in OUTPUTS])))
    with pytest.raises(FMICallException):
        slave.doStep(currentCommunicationPoint=MAX_SAMPLES_PER_STEP * 1.2,
                     communicationStepSize=(MAX_SAMPLES_PER_STEP + 1) * 1.2)  # fmt: skip
    slave.freeInstance()


def test_a_step_not_a_whole_number_of_samples_is_refused(fmu):
    from fmpy.fmi1 import FMICallException

    slave, _ = _slave(fmu)
    slave.exitInitializationMode()
    with pytest.raises(FMICallException):
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
    slave.freeInstance()


@pytest.mark.parametrize(("name", "value"), [("horizon_s", 61.0), ("anomaly_band_sigma", 0.0),
                                             ("anomaly_run_samples", 2.5),
                                             ("anomaly_cusum_slack_sigma", -0.5),
                                             ("anomaly_cusum_threshold", 0.0)])  # fmt: skip
def test_bad_parameters_are_refused_at_initialisation(fmu, name, value):
    from fmpy.fmi1 import FMICallException

    slave, _ = _slave(fmu, {name: value})
    with pytest.raises(FMICallException):
        slave.exitInitializationMode()
    slave.freeInstance()


def test_export_refuses_what_the_observer_does_not_cover(tmp_path):
    with pytest.raises(ExportError, match="effect blocks"):
        export_observer(ROOT / "models/fopdt_3F.json", tmp_path / "o.fmu")
    with pytest.raises(ExportError, match="scheduled FOPDT"):
        export_observer(ROOT / "models/arx_3F.json", tmp_path / "o.fmu", without_effects=True)
    with pytest.raises(ExportError, match="whole multiple"):
        export_observer(ROOT / "models/fopdt_3F.json", tmp_path / "o.fmu", horizon_s=1.0,
                        without_effects=True)  # fmt: skip
    with pytest.raises(ControlError, match="run_samples"):
        AnomalySettings(run_samples=0)
    with pytest.raises(ControlError, match="cusum_slack_sigma"):
        AnomalySettings(cusum_slack_sigma=float("nan"))
    with pytest.raises(ControlError, match="scale_window_samples"):
        AnomalySettings(scale_window_samples=0)
    assert list(tmp_path.iterdir()) == []


def test_cli_exports_and_refuses_in_one_line(tmp_path, capsys):
    model = str(ROOT / "models/fopdt_3F.json")
    out = tmp_path / "obs.fmu"
    assert main(["export-observer", model, "--out", str(out), "--horizon", "12"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--without-effects" in err
    assert not out.exists()
    assert main(["export-observer", model, "--out", str(out), "--without-effects",
                 "--cusum-threshold", "0"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cusum_threshold" in err
    assert not out.exists()
    assert main(["export-observer", model, "--out", str(out), "--horizon", "12",
                 "--without-effects", "--run-samples", "6", "--cusum-slack", "0.75",
                 "--cusum-threshold", "20"]) == 0  # fmt: skip
    from fmpy import read_model_description

    starts = {v.name: v.start for v in read_model_description(str(out)).modelVariables}
    assert float(starts["horizon_s"]) == 12.0 and float(starts["anomaly_run_samples"]) == 6.0
    assert float(starts["anomaly_cusum_slack_sigma"]) == 0.75
    assert float(starts["anomaly_cusum_threshold"]) == 20.0


@pytest.fixture(scope="module")
def fmu3(plant, tmp_path_factory):
    return export_observer(plant, tmp_path_factory.mktemp("obs3") / "observer.fmu",
                           fmi_version="3.0")  # fmt: skip


def test_the_fmi3_fmu_passes_fmpy_validation(fmu3):
    assert validate_fmu(str(fmu3)) == []


def test_fmi3_and_fmi2_observers_give_identical_outputs(fmu, fmu3):
    """Eboth's discharge changes re-render the model; a 40 mm level offset from the middle
    on drives the innovation out of the band, so the anomaly outputs move too. The same
    component compiled with the same flags under two glues: equal to the bit."""
    _, y, e, q = _inputs("Eboth")
    y = y + np.where(np.arange(y.size) >= y.size // 2, 40.0, 0.0)
    two = run_observer_fmu(fmu, y, e, q)
    three = run_observer_fmu(fmu3, y, e, q)
    for key in OUTPUTS:
        assert np.all(np.isfinite(three[key])), key
        assert np.array_equal(three[key], two[key]), key
    assert np.max(two["anomaly"]) == 1.0 and np.ptp(two["innovation_mm"]) > 1.0


def test_cli_exports_fmi3(tmp_path):
    from fmpy import read_model_description

    out = tmp_path / "obs3.fmu"
    assert main(["export-observer", str(ROOT / "models/fopdt_3F.json"), "--out", str(out),
                 "--without-effects", "--fmi", "3"]) == 0  # fmt: skip
    md = read_model_description(str(out))
    assert md.fmiVersion == "3.0"
    assert set(OUTPUTS) <= {v.name for v in md.modelVariables if v.causality == "output"}


@pytest.mark.parametrize("name", sorted(p.stem for p in bundled_records_dir().glob("*.csv")
                                         if p.stem != "static"))  # fmt: skip
def test_the_flag_stays_down_on_every_clean_bundled_record(fmu, name):
    """Fit, held-out and the wide-range validation records (a discharge stepping across the
    schedule, moves across the envelope): the linear schedule's mismatch alone must not raise
    the flag by either rule."""
    t, y, e, q = _inputs(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = run_observer_fmu(fmu, y, e, q)
    assert detection(t, out["anomaly"], None).false_alarms == 0
    assert np.ptp(out["innovation_mm"]) > 1.0  # the observer did see the record


def _model_record(plant, base: str, effect: str):
    """A record the model explains (its own response plus white noise of the observer's
    measurement SD) and the same with ``effect`` from the first move after 40 %."""
    t, _, e, q = _inputs(base)
    truth = dataclasses.replace(plant, envelope=None)
    rng = np.random.default_rng(7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        y = simulate(truth, t, e, q) + MONITORING.measurement_sd_mm * rng.standard_normal(t.size)
        onset = first_move_after(t, e)
        return t, y, with_onset(truth, t, y, e, q, effect, onset), e, q, onset


@pytest.mark.parametrize(("base", "effect"), [
    ("C", "stuck_gate"), ("Emoves75", "stuck_gate"), ("Emoves75", "slowed_gate"),
    ("Erandom60", "stuck_gate"), ("Erandom60", "slowed_gate")])  # fmt: skip
def test_a_gate_fault_at_a_move_is_flagged_within_half_a_time_constant(plant, fmu, base,
                                                                       effect):  # fmt: skip
    """The flag stays down before the onset and rises soon after it. (A gate slowed to
    0.1 mm/s on C's 10 mm PRBS move is on the edge: 19 s or several minutes, by the noise.)"""
    t, y, level, e, q, onset = _model_record(plant, base, effect)
    clean = detection(t, run_observer_fmu(fmu, y, e, q)["anomaly"], None)
    found = detection(t, run_observer_fmu(fmu, level, e, q)["anomaly"], onset)
    assert clean.false_alarms == 0 and found.false_alarms == 0
    assert found.delay_s <= GATE_FAULT_BOUND_S


@pytest.mark.parametrize("base", ["C", "Emoves35"])
def test_an_unseen_inflow_is_flagged_by_the_persistent_rule(plant, fmu, base):
    t, y, level, e, q, onset = _model_record(plant, base, "unmeasured_inflow")
    out = run_observer_fmu(fmu, level, e, q)
    found = detection(t, out["anomaly"], onset)
    assert found.false_alarms == 0 and found.delay_s <= INFLOW_BOUND_S
    first = onset + int(np.flatnonzero(out["anomaly"][onset:])[0])
    assert out["anomaly_kind"][first] == 2.0


def test_effects_start_at_the_onset_and_bad_requests_are_refused(plant):
    t, y, e, q = _inputs("C")
    onset = first_move_after(t, e)
    for effect in ("sensor_drift", "stuck_gate", "unmeasured_inflow"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            level = with_onset(plant, t, y, e, q, effect, onset)
        np.testing.assert_array_equal(level[:onset], y[:onset])
        assert np.max(np.abs(level[onset:] - y[onset:])) > 5.0  # material: > 5 noise SDs
    with pytest.raises(OnsetError, match="unknown effect"):
        with_onset(plant, t, y, e, q, "gremlins", onset)
    with pytest.raises(OnsetError, match="no parameter"):
        with_onset(plant, t, y, e, q, "sensor_drift", onset, speed=1.0)
    with pytest.raises(OnsetError, match="onset"):
        with_onset(plant, t, y, e, q, "sensor_drift", 0)
