"""The redundancy rule for a gauge's drift (gatetwin.mpc.gauge_drift): no rise on a clean
flume record it was not calibrated on, a drift of 0.01 mm/s of one gauge flagged within its
bound, the pool's own changes (the flume's unseen inflow, seen by every gauge) not taken for
a drift, and `gatetwin observe --reference-gauges`."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gatetwin.diagnosis.onset import ONSET_EFFECTS, detection
from gatetwin.errors import ControlError
from gatetwin.flume.experiments import run_scenario
from gatetwin.flume.scenario import with_inflow
from gatetwin.mpc.gauge_drift import (
    THRESHOLD_MM_PER_S,
    WINDOW_SAMPLES,
    GaugeDriftMonitor,
    gauge_difference,
)
from observer_cases import ROOT, flume_scenario

GAUGE = "3F"
#: The diagnosis suite's drift (0.6 mm/min).
DRIFT_MM_PER_S = ONSET_EFFECTS["sensor_drift"]["rate_mm_per_s"]
#: Once a whole window has drifted, the fitted slope is the drift's rate, 0.01 mm/s, twice
#: the threshold; the slope's noise SD is ~0.0005 mm/s (see the module), so the flag is up
#: by then: bound one window, 480 s.
DRIFT_BOUND_S = WINDOW_SAMPLES * 1.2


_scenario = flume_scenario


def _run(scenario):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rec = run_scenario(scenario)
    levels = {g: np.asarray(v, dtype=float) for g, v in rec.levels_mm.items()}
    return np.asarray(rec.time_s, dtype=float), levels


@pytest.fixture(scope="module")
def record():
    """A clean flume record: six random gate moves at 50 m3/h (1120 s), every gauge."""
    return _run(_scenario())


def _others(levels):
    return [v for g, v in levels.items() if g != GAUGE]


def test_no_rise_on_a_clean_flume_record(record):
    t, levels = record
    assert len(levels) >= 3  # the pool's gauges: 3F and at least two others
    out = GaugeDriftMonitor().run(levels[GAUGE], _others(levels))
    assert not out["gauge_drift"].any()
    assert np.isnan(out["gauge_slope_mm_per_s"][: WINDOW_SAMPLES - 1]).all()
    assert np.nanmax(np.abs(out["gauge_slope_mm_per_s"])) > 0.0


def test_a_drift_of_the_observed_gauge_is_flagged_within_its_bound(record):
    t, levels = record
    onset = int(np.searchsorted(t, 0.3 * t[-1]))
    drifted = levels[GAUGE] + DRIFT_MM_PER_S * np.maximum(t - t[onset], 0.0)
    out = GaugeDriftMonitor().run(drifted, _others(levels))
    found = detection(t, out["gauge_drift"], onset)
    assert found.false_alarms == 0
    assert found.delay_s <= DRIFT_BOUND_S, f"flagged after {found.delay_s} s"
    # the fitted slope approaches the drift's rate once a whole window has drifted
    last = out["gauge_slope_mm_per_s"][-1]
    assert abs(last - DRIFT_MM_PER_S) < 0.5 * THRESHOLD_MM_PER_S


def test_the_pools_own_inflow_is_not_taken_for_a_drift(record):
    """The flume with 5 m3/h more from 40 % of the record on: every gauge rises alike."""
    t, _ = record
    start = float(t[int(0.4 * t.size)])
    _, levels = _run(with_inflow(_scenario(), start, 5.0))
    clean = record[1][GAUGE]
    assert np.max(levels[GAUGE] - clean) > 10.0  # the inflow is there
    out = GaugeDriftMonitor().run(levels[GAUGE], _others(levels))
    assert not out["gauge_drift"].any()


def test_one_sample_at_a_time_equals_the_record_at_once(record):
    _, levels = record
    others = _others(levels)
    n = WINDOW_SAMPLES + 50
    at_once = GaugeDriftMonitor().run(levels[GAUGE][:n], [o[:n] for o in others])
    monitor = GaugeDriftMonitor()
    steps = [monitor.step(levels[GAUGE][k], [o[k] for o in others]) for k in range(n)]
    slopes = np.array([s for s, _ in steps])
    # the same weights over the same values, summed in another order: round-off of
    # ~1e-16 of the window's terms (differences of ~100 mm times weights of ~1e-5 per s)
    np.testing.assert_allclose(slopes, at_once["gauge_slope_mm_per_s"], rtol=0, atol=1e-12)
    assert [f for _, f in steps] == list(at_once["gauge_drift"] > 0.5)


def test_refusals():
    with pytest.raises(ControlError, match="window_samples"):
        GaugeDriftMonitor(window_samples=2)
    with pytest.raises(ControlError, match="threshold"):
        GaugeDriftMonitor(threshold_mm_per_s=0.0)
    with pytest.raises(ControlError, match="other gauge"):
        gauge_difference(np.zeros(5), [])
    with pytest.raises(ControlError, match="one length"):
        gauge_difference(np.zeros(5), [np.zeros(4)])
    with pytest.raises(ControlError, match="other gauge"):
        GaugeDriftMonitor().step(1.0, [])


# ~40 s; the rule's arithmetic is held in the default run by the FMU tests of
# test_observer_drift_fmu.py
@pytest.mark.slow
def test_observe_adds_the_rule_with_reference_gauges(tmp_path, capsys):
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.cli import main
    from gatetwin.records import read_record

    path = bundled_records_dir() / "Erandom60.csv"
    out = tmp_path / "est.csv"
    model = str(ROOT / "models/physical_3F.json")
    others = ["1D", "2E", "4G", "5H"]
    assert main(["observe", model, str(path), "--gauge", GAUGE, "--out", str(out),
                 "--without-effects", "--reference-gauges", *others]) == 0  # fmt: skip
    table = np.genfromtxt(out, delimiter=",", names=True)
    rec = read_record(path)
    ref = GaugeDriftMonitor().run(rec.levels_mm[GAUGE], [rec.levels_mm[g] for g in others])
    # written with 10 significant digits
    np.testing.assert_allclose(table["gauge_slope_mm_per_s"], ref["gauge_slope_mm_per_s"],
                               rtol=1e-9, atol=1e-12)  # fmt: skip
    assert not table["gauge_drift"].any()  # a clean bundled record
    assert not (table["anomaly_kind"] == 4).any()
    capsys.readouterr()
    bad = tmp_path / "bad.csv"
    assert main(["observe", model, str(path), "--gauge", GAUGE, "--out", str(bad),
                 "--without-effects", "--reference-gauges", "1D", "9Z"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "no level column for gauge 9Z" in err and len(err.strip().splitlines()) == 1
    assert not bad.exists()
    assert main(["observe", model, str(path), "--gauge", GAUGE, "--out", str(bad),
                 "--without-effects", "--reference-gauges", GAUGE]) == 2  # fmt: skip
    assert "lists the observed gauge" in capsys.readouterr().err
    assert not bad.exists()
