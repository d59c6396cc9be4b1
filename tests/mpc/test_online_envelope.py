"""The envelope observer (gatetwin.mpc.online.OnlineObserver with a physical plant): no rise
on a clean flume record it was not calibrated on, and detection of an unseen inflow, a gate
fault and a fast sensor drift appearing on such a record."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from gatetwin.diagnosis.onset import detection, with_onset
from gatetwin.errors import ControlError, FlumeError
from gatetwin.flume.experiments import run_scenario
from gatetwin.flume.scenario import with_inflow
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.online import ENVELOPE_ANOMALY, OUTPUTS, AnomalySettings, OnlineObserver
from observer_cases import ROOT, envelope_plant, flume_scenario, held_opening

#: An unseen inflow of 5 m3/h raises the level like the pool's step response (time constants
#: 40-75 s at gauge 3F); the slow rule's CUSUM gains about one SD per sample once the level
#: effect exceeds its filter's random walk, so 75 (its threshold) is reached within about one
#: more time constant. Bound: three of the slowest time constants, 225 s.
INFLOW_BOUND_S = 225.0
#: A gate stuck at its last position on a move of 4-17 mm leaves the level short of the
#: model's by the gain times the move, as an unseen inflow does: the same bound.
GATE_FAULT_BOUND_S = INFLOW_BOUND_S
#: A sensor drift of 0.05 mm/s (3 mm/min) outruns the slow filter's disturbance walk
#: (2 µm of opening per sample, 0.02-0.06 mm of level) and biases its innovation; bound: the
#: time the drift takes to move the reading 24 mm (eight minutes), about the pool's level
#: change for 5 mm of gate. Slower drifts (0.01 mm/s) are not seen (see the module).
DRIFT_RATE_MM_PER_S = 0.05
DRIFT_BOUND_S = 480.0


@pytest.fixture(scope="module")
def plant():
    return envelope_plant()


_scenario = flume_scenario


@pytest.fixture(scope="module")
def record():
    """A clean flume record: six random gate moves at 50 m3/h (1120 s), gauge 3F."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rec = run_scenario(_scenario())
    e = held_opening(np.asarray(rec.opening_mm, dtype=float))
    return rec.time_s, rec.levels_mm["3F"], e, rec.flow_m3h


def _onset(t: np.ndarray, e: np.ndarray) -> int:
    """The first gate move after 40 % of the record (a gate fault appears at once)."""
    moves = np.flatnonzero((t[1:] >= 0.4 * t[-1]) & (np.diff(e) != 0.0)) + 1
    return int(moves[0])


def test_no_rise_on_a_clean_flume_record(plant, record):
    t, y, e, q = record
    out = OnlineObserver(plant).run(y, e, q)
    assert detection(t, out["anomaly"], None).false_alarms == 0
    assert np.ptp(out["innovation_mm"]) > 1.0  # the record moves the observer
    assert set(OUTPUTS) < set(out)


@pytest.mark.parametrize(
    ("effect", "parameters", "bound_s"),
    [("unmeasured_inflow", {}, INFLOW_BOUND_S),
     ("stuck_gate", {}, GATE_FAULT_BOUND_S),
     ("sensor_drift", {"rate_mm_per_s": DRIFT_RATE_MM_PER_S}, DRIFT_BOUND_S)],
)  # fmt: skip
def test_a_hidden_effect_is_flagged_within_its_bound(plant, record, effect, parameters, bound_s):
    t, y, e, q = record
    onset = _onset(t, e)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        level = with_onset(plant, t, y, e, q, effect, onset, **parameters)
    out = OnlineObserver(plant).run(level, e, q)
    found = detection(t, out["anomaly"], onset)
    assert found.false_alarms == 0
    assert found.delay_s <= bound_s, f"{effect}: flagged after {found.delay_s} s"


def test_the_flumes_own_unseen_inflow_is_flagged_within_its_bound(plant, record):
    """The flume run again with 5 m3/h more from the onset on; the logged discharge is the
    clean run's (the same seed: the same logger noise)."""
    t, _, e, q = record
    onset = _onset(t, e)
    scn = with_inflow(_scenario(), (onset - 0.5) * 1.2, 5.0)
    assert scn.flow_m3h == ((0.0, 50.0), ((onset - 0.5) * 1.2, 55.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        level = run_scenario(scn).levels_mm["3F"]
    out = OnlineObserver(plant).run(level, e, q)
    found = detection(t, out["anomaly"], onset)
    assert found.false_alarms == 0
    assert found.delay_s <= INFLOW_BOUND_S, f"flagged after {found.delay_s} s"


def test_an_inflow_outside_the_scenario_is_refused():
    with pytest.raises(FlumeError, match="inflow start"):
        with_inflow(_scenario(), 0.0, 5.0)


def test_the_schedule_observer_is_unchanged_by_the_envelope_option():
    """An FOPDT is observed on its schedule unless asked; the slow rule is the envelope's."""
    plant = dataclasses.replace(read_model_file(ROOT / "models/fopdt_3F.json").plant, effects=())
    obs = OnlineObserver(plant)
    assert obs.linearisation == "schedule" and obs.anomaly == AnomalySettings()
    out = obs.run(np.full(20, 300.0), np.full(20, 30.0), np.full(20, 55.0))
    assert "slow_cusum" not in out


def test_the_envelope_observer_takes_its_own_settings(plant):
    obs = OnlineObserver(plant)
    assert obs.linearisation == "envelope" and obs.anomaly == ENVELOPE_ANOMALY


def test_refusals(plant):
    fopdt = dataclasses.replace(read_model_file(ROOT / "models/fopdt_3F.json").plant, effects=(),
                                envelope=None)  # fmt: skip
    with pytest.raises(ControlError, match="linearisation"):
        OnlineObserver(plant, linearisation="tangent")
    with pytest.raises(ControlError, match="envelope observer needs"):
        OnlineObserver(fopdt, linearisation="envelope")
    with pytest.raises(ControlError, match="scheduled FOPDT"):
        OnlineObserver(plant, linearisation="schedule")
    with pytest.raises(ControlError, match="slow_threshold"):
        AnomalySettings(slow_threshold=float("nan"))


def test_observe_writes_the_python_observers_estimates(plant, tmp_path, capsys):
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.cli import main
    from gatetwin.mpc.online import measured_inputs
    from gatetwin.records import read_record

    path = bundled_records_dir() / "Q55.csv"
    out = tmp_path / "est.csv"
    model = str(ROOT / "models/physical_3F.json")
    assert main(["observe", model, str(path), "--gauge", "3F", "--out", str(out),
                 "--without-effects"]) == 0  # fmt: skip
    table = np.genfromtxt(out, delimiter=",", names=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = OnlineObserver(plant).run(*measured_inputs(read_record(path), "3F"))
    for key in (*OUTPUTS, "slow_cusum"):  # written with 10 significant digits
        np.testing.assert_allclose(table[key], ref[key], rtol=1e-9, atol=1e-9, err_msg=key)
    assert "envelope observer" in capsys.readouterr().out


def test_observe_refuses_a_missing_gauge_without_writing(tmp_path, capsys):
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.cli import main

    out = tmp_path / "est.csv"
    model = str(ROOT / "models/physical_3F.json")
    assert main(["observe", model, str(bundled_records_dir() / "Q55.csv"), "--gauge", "9Z",
                 "--out", str(out), "--without-effects"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "no level column for gauge 9Z" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
