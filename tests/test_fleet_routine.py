"""``gatetwin models`` over gates whose records are routine operation histories."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gatetwin.cli import main
from gatetwin.fleet.district import district_gates
from gatetwin.fleet.routine import write_routine_gate
from gatetwin.flume.routine import RoutineSettings
from gatetwin.identify.routine import identify_routine
from gatetwin.records import read_record


@pytest.fixture(scope="module")
def routine_gates(tmp_path_factory) -> Path:
    """Two gates logged in routine operation: one moved by its operator for half a day, one
    held still (no move, so no informative window)."""
    out = tmp_path_factory.mktemp("routine_fleet")
    moved, still = district_gates(2, seed=11)
    write_routine_gate(moved, out / moved.gate, RoutineSettings(days=0.5, control="schedule"))
    write_routine_gate(still, out / still.gate,
                       RoutineSettings(days=0.1, hold_s=(1e6, 2e6), gaps=0))  # fmt: skip
    return out


def test_routine_gates_get_their_fopdt_and_a_still_gate_is_reported(routine_gates, tmp_path,
                                                                    capsys) -> None:  # fmt: skip
    moved, still = district_gates(2, seed=11)
    out = tmp_path / "fleet"
    assert main(["models", "--records", str(routine_gates), "--out", str(out),
                 "--workers", "1"]) == 0  # fmt: skip
    assert "1 without an informative window" in capsys.readouterr().out
    doc = json.loads((out / "fleet.json").read_text())
    assert (doc["n_ok"], doc["n_no_window"], doc["n_failed"]) == (1, 1, 0)
    entry, quiet = doc["gates"]
    record = read_record(routine_gates / moved.gate / "routine.csv")
    expected = identify_routine(record).to_dict()
    assert entry["status"] == "ok" and entry["fopdt_source"] == "routine"
    assert entry["families"] == ["fopdt"] and entry["samples"] == record.n_samples
    line = entry["routine"]["routine"]
    assert line["n_windows"] == expected["n_windows"] > 0
    assert line["gain_mm_per_mm"] == expected["overall"]["gain_mm_per_mm"]
    written = json.loads((out / moved.gate / "routine_routine.json").read_text())
    assert written == {**expected, "n_samples": record.n_samples}
    assert quiet["status"] == "no_window" and "no informative window" in quiet["error"]
    assert quiet["routine"]["routine"]["n_windows"] == 0
    assert not (out / still.gate).exists()
    markdown = (out / "fleet.md").read_text()
    assert "FOPDT from routine history" in markdown
    assert "1 without an informative window" in markdown


def test_routine_gates_on_a_pool_give_the_serial_summary(routine_gates, tmp_path) -> None:
    for workers in ("1", "2"):
        assert main(["models", "--records", str(routine_gates), "--out",
                     str(tmp_path / workers), "--workers", workers]) == 0  # fmt: skip
    docs = [json.loads((tmp_path / w / "fleet.json").read_text()) for w in ("1", "2")]
    assert docs[0]["gates"] == docs[1]["gates"]
