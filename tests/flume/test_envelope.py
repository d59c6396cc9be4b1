"""The validation records across the flume's envelope: what they span, and that no fit uses them.

Reads the bundled records only (no flume run); ``tests/flume/test_flume.py`` regenerates one of
them from its seed.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.flume import FlumeConfig
from gatetwin.flume.envelope import (
    ENVELOPE_FLOW_M3H,
    ENVELOPE_LEVEL_MM,
    ENVELOPE_OPENING_MM,
    envelope_openings_mm,
    envelope_scenarios,
    in_band,
)
from gatetwin.flume.experiments import reference_scenarios
from gatetwin.identification.suite import load_folder
from gatetwin.records import read_record
from gatetwin.records.sidecar import VALIDATION_ROLE

RECORDS = bundled_records_dir()
SCENARIOS = {s.name: s for s in envelope_scenarios()}
#: The flow meter's accuracy, m³/h: a logged discharge may sit this far outside the
#: commanded one.
FLOW_ACCURACY_M3H = 1.0


@pytest.fixture(scope="module")
def records():
    return {name: read_record(RECORDS / f"{name}.csv") for name in SCENARIOS}


def _sidecar(name: str) -> dict:
    return json.loads((RECORDS / f"{name}.json").read_text(encoding="utf-8"))


def test_validation_records_are_exactly_the_envelope_scenarios():
    bundled = {p.stem for p in RECORDS.glob("*.json") if p.stem != "static"}
    validation = {n for n in bundled if _sidecar(n).get("role") == VALIDATION_ROLE}
    assert validation == set(SCENARIOS)
    assert len(SCENARIOS) >= 4


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_sidecar_says_free_validation_and_what_the_scenario_is(name):
    side = _sidecar(name)
    assert side["role"] == VALIDATION_ROLE and side["test"] == "free"
    assert side["condition"] == name and len(side["description"]) > 20
    for key in ("synthetic", "generator", "flume_version", "sample_period_s", "gauges"):
        assert key in side, key
    assert side["synthetic"] is True and side["sample_period_s"] == 1.2


def test_seeds_are_distinct_from_every_other_bundled_record():
    seeds = [s.seed for s in reference_scenarios()] + [110]  # 110: the static table
    assert len(seeds) == len(set(seeds))
    assert all(_sidecar(n)["seed"] == SCENARIOS[n].seed for n in SCENARIOS)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_gauge_stays_in_the_level_band_over_the_whole_record(records, name):
    lo, hi = ENVELOPE_LEVEL_MM
    for gauge, level in records[name].levels_mm.items():
        assert np.all(np.isfinite(level)), gauge
        assert lo <= np.min(level) and np.max(level) <= hi, (gauge, np.min(level), np.max(level))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_each_record_stays_inside_the_envelope(records, name):
    rec = records[name]
    q_lo, q_hi = ENVELOPE_FLOW_M3H
    assert q_lo - FLOW_ACCURACY_M3H <= np.min(rec.flow_m3h)
    assert np.max(rec.flow_m3h) <= q_hi + FLOW_ACCURACY_M3H
    e = rec.opening_mm[rec.hold]
    assert ENVELOPE_OPENING_MM[0] <= np.min(e) and np.max(e) <= ENVELOPE_OPENING_MM[1]


#: Shortest time constant of the flume's levels, s: inputs held for less than this move
#: the level only part of the way to their steady state (the measured levels are checked
#: over the whole record above).
SHORTEST_TIME_CONSTANT_S = 40.0


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_held_input_pair_has_its_steady_levels_in_the_band(name):
    cfg = FlumeConfig()
    opening, flow = SCENARIOS[name].sampled(cfg.sample_period_s)
    change = np.flatnonzero((np.diff(opening) != 0) | (np.diff(flow) != 0)) + 1
    starts, stops = np.r_[0, change], np.r_[change, opening.size]
    held = (stops - starts) * cfg.sample_period_s >= SHORTEST_TIME_CONSTANT_S
    assert np.count_nonzero(held) >= 3
    for k in starts[held]:
        assert in_band(cfg, flow[k], opening[k]), (flow[k], opening[k])


def test_together_the_records_span_the_envelope(records):
    flows = np.concatenate([r.flow_m3h for r in records.values()])
    openings = np.concatenate([r.opening_mm[r.hold] for r in records.values()])
    assert np.min(flows) <= ENVELOPE_FLOW_M3H[0] + FLOW_ACCURACY_M3H
    assert np.max(flows) >= ENVELOPE_FLOW_M3H[1] - FLOW_ACCURACY_M3H
    assert np.min(openings) == ENVELOPE_OPENING_MM[0]
    assert np.max(openings) == ENVELOPE_OPENING_MM[1]


def _flow_levels(name: str) -> int:
    return len({q for _, q in SCENARIOS[name].flow_m3h})


def test_the_suite_has_moves_flow_steps_both_and_a_random_sequence(records):
    moves = [n for n, r in records.items() if len(r.steps) >= 6 and _flow_levels(n) == 1]
    flow_steps = [n for n, r in records.items() if not r.steps and _flow_levels(n) >= 3]
    both = [n for n, r in records.items() if len(r.steps) >= 3 and _flow_levels(n) >= 3]
    assert len(moves) >= 3 and len(flow_steps) >= 2 and len(both) >= 1
    # the random sequence: at least ten moves at Q 60, the wide ones reaching both ends of
    # the openings that keep the levels in the band there (within a quarter of the range)
    random = records["Erandom60"]
    lo, hi = envelope_openings_mm(FlumeConfig(), 60.0)
    e = random.opening_mm[random.hold]
    assert len(random.steps) >= 10
    assert np.min(e) <= lo + 0.25 * (hi - lo) and np.max(e) >= hi - 0.25 * (hi - lo)


def test_in_the_combined_record_gate_moves_fall_inside_the_responses_to_q_changes():
    scn = SCENARIOS["Eboth"]
    q_changes = [t for t, _ in scn.flow_m3h[1:]]
    moves = [t for t, _ in scn.opening_mm[1:]]
    # within 40 s, less than the shortest time constant of the flume
    assert all(min(abs(m - t) for t in q_changes) <= 40.0 for m in moves)


#: Largest drift between the median levels of the last two 30-s windows before a change
#: in a record meant to settle, mm: four SDs of the difference of two such medians (SD
#: ≈ 1.4 mm at the largest surface-fluctuation SD, 2.5 mm, with a 1.5 s correlation time,
#: i.e. ≈ 10 independent samples per window). An unsettled level after a 5–20 mm move
#: drifts by 10–25 mm over 30 s.
SETTLED_DRIFT_MM = 6.0


@pytest.mark.parametrize("name", ["Emoves35", "Emoves75", "EflowLow", "EflowHigh"])
def test_levels_settle_before_each_change(records, name):
    rec, scn = records[name], SCENARIOS[name]
    ends = sorted({t for t, _ in (*scn.flow_m3h[1:], *scn.opening_mm[1:])} | {scn.duration_s})
    for gauge, level in rec.levels_mm.items():
        for t in ends:
            last = np.median(level[(rec.time_s > t - 30.0) & (rec.time_s <= t)])
            before = np.median(level[(rec.time_s > t - 60.0) & (rec.time_s <= t - 30.0)])
            assert abs(last - before) < SETTLED_DRIFT_MM, (gauge, t, last - before)


def test_load_folder_reads_validation_records_and_fits_none():
    ident = load_folder(RECORDS)
    assert set(SCENARIOS) <= set(ident.records)
    assert not set(SCENARIOS) & (set(ident.steps) | set(ident.prbs))


def test_a_validation_record_is_not_identified_whatever_its_test(tmp_path: Path):
    for name in ("A", "static"):
        for ext in (".csv", ".json"):
            shutil.copy(RECORDS / f"{name}{ext}", tmp_path / f"{name}{ext}")
    shutil.copy(RECORDS / "Q55.csv", tmp_path / "V.csv")
    side = {**_sidecar("Q55"), "condition": "V", "role": VALIDATION_ROLE}
    (tmp_path / "V.json").write_text(json.dumps(side), encoding="utf-8")
    assert side["test"] == "step"
    ident = load_folder(tmp_path)
    assert set(ident.records) == {"A", "V"} and set(ident.steps) == {"A"}
