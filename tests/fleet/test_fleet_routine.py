"""``gatetwin models`` over gates whose records are routine operation histories."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.fleet.district import district_gates
from gatetwin.fleet.routine import write_routine_gate
from gatetwin.flume.routine import RoutineSettings
from gatetwin.identification.routine import identify_routine
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


def test_a_gate_folder_that_cannot_be_written_fails_that_gate_only(routine_gates, tmp_path,
                                                                   capsys) -> None:  # fmt: skip
    """A gate's place under ``--out`` taken by a file (a folder that cannot be written, even
    by root): that gate is failed with the reason, the file is left as it was, and the
    summary is still written (exit 1: a gate failed)."""
    moved, _ = district_gates(2, seed=11)
    out = tmp_path / "fleet"
    out.mkdir()
    (out / moved.gate).write_text("not a folder")
    assert main(["models", "--records", str(routine_gates), "--out", str(out),
                 "--workers", "1"]) == 1  # fmt: skip
    doc = json.loads((out / "fleet.json").read_text())
    entry = next(g for g in doc["gates"] if g["gate"] == moved.gate)
    assert entry["status"] == "failed" and "cannot be written" in entry["error"]
    assert (out / moved.gate).read_text() == "not a folder"
    assert "1 failed" in capsys.readouterr().out


def test_routine_gates_on_a_pool_give_the_serial_summary(routine_gates, tmp_path) -> None:
    for workers in ("1", "2"):
        assert main(["models", "--records", str(routine_gates), "--out",
                     str(tmp_path / workers), "--workers", workers]) == 0  # fmt: skip
    docs = [json.loads((tmp_path / w / "fleet.json").read_text()) for w in ("1", "2")]
    assert docs[0]["gates"] == docs[1]["gates"]


def _sidecar_for(source: Path, target: Path) -> None:
    """``source``'s sidecar for ``target``, its ``gate`` the name of ``target``'s folder."""
    side = json.loads(source.with_suffix(".json").read_text())
    side["gate"] = target.parent.name
    target.with_suffix(".json").write_text(json.dumps(side))


def _as_parquet(csv: Path, out: Path) -> Path:
    """``csv`` (a routine history) as ``out`` in Parquet, its sidecar beside it."""
    import pyarrow.csv
    import pyarrow.parquet

    out.parent.mkdir(parents=True, exist_ok=True)
    pyarrow.parquet.write_table(pyarrow.csv.read_csv(csv), out)
    _sidecar_for(csv, out)
    return out


def _as_day_files(parquet: Path, folder: Path, parts: int) -> Path:
    """The history ``parquet`` cut into ``parts`` files in ``folder``, next to the
    folder's own sidecar ``FOLDER.json``."""
    import pyarrow.parquet

    table = pyarrow.parquet.read_table(parquet)
    folder.mkdir(parents=True)
    size = -(-table.num_rows // parts)
    for k in range(parts):
        pyarrow.parquet.write_table(table.slice(k * size, size), folder / f"day{k}.parquet")
    _sidecar_for(parquet, folder)
    return folder


def _routine_cli(path: Path, out: Path, *extra: str) -> dict:
    assert main(["routine", str(path), "--json", str(out), *extra]) == 0
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def parquet_gates(routine_gates, tmp_path_factory) -> Path:
    """The moved gate's history twice over in Parquet: ``pq/routine.parquet`` (one file)
    and ``days/routine/`` (three day files and ``routine.json`` beside the folder)."""
    moved = district_gates(2, seed=11)[0]
    out = tmp_path_factory.mktemp("parquet_fleet")
    pq = _as_parquet(routine_gates / moved.gate / "routine.csv", out / "pq" / "routine.parquet")
    _as_day_files(pq, out / "days" / "routine", 3)
    return out


def test_parquet_histories_in_a_fleet_give_gatetwin_routines_model(
        parquet_gates, tmp_path, monkeypatch) -> None:  # fmt: skip
    # 301 MiB leaves one MiB beyond the libraries' 300: the smallest chunk (3,600 rows, an
    # hour at 1 Hz) and so about ten chunks over this half-day history; the result must not
    # depend on the chunking, so equality is exact
    from gatetwin.identification import routine_chunks

    scans = []
    scan = routine_chunks.scan_routine_history

    def spy(path, *args, chunk_rows):
        scans.append((Path(path).name, chunk_rows))
        return scan(path, *args, chunk_rows=chunk_rows)

    monkeypatch.setattr(routine_chunks, "scan_routine_history", spy)
    out = tmp_path / "fleet"
    assert main(["models", "--records", str(parquet_gates), "--out", str(out), "--workers",
                 "1", "--max-memory", "301"]) == 0  # fmt: skip
    doc = json.loads((out / "fleet.json").read_text())
    assert [g["gate"] for g in doc["gates"]] == ["days", "pq"]
    assert (doc["n_ok"], doc["n_failed"]) == (2, 0)
    assert sorted(scans) == [("routine", 3600), ("routine.parquet", 3600)]
    monkeypatch.undo()
    pq = (parquet_gates / "pq" / "routine.parquet").resolve()
    days = (parquet_gates / "days" / "routine").resolve()
    whole = _routine_cli(pq, tmp_path / "whole.json")
    chunked = _routine_cli(pq, tmp_path / "chunked.json", "--max-memory", "301")
    assert chunked == whole and whole["n_windows"] > 0
    n_samples = read_record(pq, test="routine").n_samples
    written = json.loads((out / "pq" / "routine_routine.json").read_text())
    assert written == {**whole, "n_samples": n_samples}
    in_days = json.loads((out / "days" / "routine_routine.json").read_text())
    from_folder = _routine_cli(days, tmp_path / "days.json")
    assert in_days == {**from_folder, "n_samples": n_samples}
    assert {k: v for k, v in from_folder.items() if k != "record"} == {
        k: v for k, v in whole.items() if k != "record"}  # fmt: skip
    for entry in doc["gates"]:
        assert entry["samples"] == n_samples and entry["fopdt_source"] == "routine"


def test_fleet_refuses_a_budget_below_the_libraries_and_two_histories_of_one_name(
        parquet_gates, routine_gates, tmp_path, capsys) -> None:  # fmt: skip
    out = tmp_path / "fleet"
    assert main(["models", "--records", str(parquet_gates), "--out", str(out),
                 "--max-memory", "200"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-memory" in err[0] and not out.exists()
    twice = tmp_path / "twice" / "gate"
    shutil.copytree(parquet_gates / "pq", twice)
    moved = district_gates(2, seed=11)[0]
    shutil.copy(routine_gates / moved.gate / "routine.csv", twice)
    assert main(["models", "--records", str(twice.parent), "--out", str(out),
                 "--workers", "1"]) == 1  # fmt: skip
    doc = json.loads((out / "fleet.json").read_text())
    assert doc["n_failed"] == 1 and "a second routine history named 'routine'" in json.dumps(doc)


@pytest.mark.parametrize("budget", ["inf", "1e308", "nan", "-inf"])
def test_a_budget_no_machine_has_is_refused_in_one_line(budget, tmp_path, capsys) -> None:
    """Infinity, NaN and numbers past an exbibyte are mistakes, refused by ``models`` and
    ``routine`` before anything is read (formerly an OverflowError traceback)."""
    out = tmp_path / "fleet"
    assert main(["models", "--out", str(out), f"--max-memory={budget}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-memory" in err[0] and "memory budget" in err[0]
    assert not out.exists()
    record = bundled_records_dir() / "A.csv"
    json_out = tmp_path / "routine.json"
    assert main(["routine", str(record), "--json", str(json_out), f"--max-memory={budget}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "memory budget" in err[0] and not json_out.exists()
