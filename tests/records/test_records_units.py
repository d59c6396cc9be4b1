"""Units in column names, canal-scale bounds and the sidecar's gate width and bounds.

Invariant: one record written in any accepted units reads to the same arrays in mm and
m³/h, whichever reader (CSV, Parquet, DataFrame, rating table, chunked history) takes it.
The field record here is canal scale: 10 s sampling, about 2.3 m of water, 20 m³/s,
openings of 0.4 m.
"""

from __future__ import annotations

import json
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gatetwin.cli import main
from gatetwin.errors import RecordError
from gatetwin.records import detect_table_kind, read_record, read_static_table
from gatetwin.records.chunks import iter_chunks, open_history

#: Each value is parsed from decimal text (≤ 1/2 ulp), and scaled once by a factor that is
#: itself rounded (≤ 1/2 ulp each): at most 1.5 ulp apart, so 4 machine epsilons relative.
RTOL = 4 * np.finfo(float).eps
#: Exact decimal factors from the test's own units (mm; l/s for flows) to each accepted one.
SHIFT = {"mm": Decimal(1), "cm": Decimal("0.1"), "m": Decimal("0.001"),
         "ls": Decimal(1), "m3s": Decimal("0.001"), "m3h": Decimal("3.6")}  # fmt: skip
PERIOD_S = 10


def _state(k: int) -> tuple[str, str]:
    """A hold at 400 mm, 3 samples of motion, a hold at 450 mm."""
    return ("hold", "400") if k < 118 else ("open", "") if k < 121 else ("hold", "450")


def _field_samples() -> list[tuple[int, str, str, Decimal, Decimal, Decimal]]:
    """(time, state, opening mm or "", flow l/s, level A mm, level B mm) per sample.

    Flows are whole l/s so that they are exact decimals in m³/h (× 3.6) and m³/s (/ 1000).
    """
    rows = []
    for k in range(240):
        state, opening = _state(k)
        drop = Decimal(0) if k < 121 else Decimal(min(k - 121, 40)) * Decimal("1.5")
        level = Decimal("2301.7") + Decimal(k % 7) / 10 - drop
        rows.append((k * PERIOD_S, state, opening, Decimal(20125 + k % 3), level, level + 38))
    return rows


def _cell(value: Decimal | str, unit: str) -> str:
    if value == "":
        return ""
    return format((Decimal(value) * SHIFT[unit]).normalize(), "f")


def _write(folder: Path, units: tuple[str, str, str, str], name: str = "field.csv",
           sidecar: dict | None = None) -> Path:  # fmt: skip
    opening, flow, level_a, level_b = units
    header = ["time_s", f"opening_{opening}", "state", f"flow_{flow}",
              f"level_A_{level_a}", f"level_B_{level_b}"]  # fmt: skip
    lines = [",".join(header)]
    for t, state, e, q, ha, hb in _field_samples():
        lines.append(",".join([str(t), _cell(e, opening), state, _cell(q, flow),
                               _cell(ha, level_a), _cell(hb, level_b)]))  # fmt: skip
    path = folder / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    if sidecar is not None:
        path.with_suffix(".json").write_text(json.dumps(sidecar), encoding="utf-8")
    return path


def _close(a, b) -> None:
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=0)


def _same(a, b) -> None:
    for name in ("time_s", "opening_mm", "flow_m3h"):
        _close(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.hold, b.hold)
    assert a.gauges == b.gauges
    for gauge in a.gauges:
        _close(a.levels_mm[gauge], b.levels_mm[gauge])
    assert (a.test, a.sample_period_s, len(a.holds), len(a.steps)) == (
        b.test, b.sample_period_s, len(b.holds), len(b.steps))  # fmt: skip


MM = ("mm", "m3h", "mm", "mm")


@pytest.mark.parametrize(
    "units", [("m", "m3s", "m", "m"), ("cm", "ls", "cm", "cm"), ("m", "ls", "mm", "cm")]
)
def test_one_record_in_any_units_reads_the_same(tmp_path: Path, units) -> None:
    reference = read_record(_write(tmp_path, MM, "mm.csv"))
    other = read_record(_write(tmp_path, units, "other.csv"))
    _same(reference, other)
    assert float(np.nanmax(other.levels_mm["A"])) > 2000.0  # canal scale, in mm
    assert other.units["opening"] == units[0] and other.units["flow"] == units[1]
    assert other.units["levels"] == {"A": units[2], "B": units[3]}
    assert other.units["level"] == (units[2] if units[2] == units[3] else "mixed")
    assert reference.units == {"opening": "mm", "flow": "m3h", "level": "mm",
                               "levels": {"A": "mm", "B": "mm"}}  # fmt: skip


def test_parquet_and_dataframe_convert_like_csv(tmp_path: Path) -> None:
    pandas = pytest.importorskip("pandas")
    reference = read_record(_write(tmp_path, MM, "mm.csv"))
    frame = pandas.read_csv(_write(tmp_path, ("m", "m3s", "m", "cm"), "m.csv"))
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), tmp_path / "m.parquet")
    for record in (read_record(tmp_path / "m.parquet"), read_record(frame),
                   type(reference).from_pandas(frame)):  # fmt: skip
        _same(reference, record)
        assert record.units["flow"] == "m3s" and record.units["levels"]["B"] == "cm"


def test_chunked_history_converts_each_file(tmp_path: Path) -> None:
    folder = tmp_path / "history"
    folder.mkdir()
    _write(folder, MM, "day1.csv")
    _write(folder, ("m", "m3s", "m", "m"), "day2.csv")
    first, second = iter_chunks(open_history(folder), rows=1000)
    _close(first.opening_mm, second.opening_mm)
    _close(first.flow_m3h, second.flow_m3h)
    _close(first.levels_mm["A"], second.levels_mm["A"])


def test_chunked_parquet_history_names_an_unknown_unit(tmp_path: Path) -> None:
    pandas = pytest.importorskip("pandas")
    frame = pandas.read_csv(_write(tmp_path, MM)).rename(columns={"level_B_mm": "level_B_ft"})
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), tmp_path / "h.parquet")
    with pytest.raises(RecordError, match="h.parquet: column 'level_B_ft': unknown unit 'ft'"):
        list(iter_chunks(open_history(tmp_path / "h.parquet"), rows=100))


def test_static_table_in_other_units(capsys, tmp_path: Path) -> None:
    mm = tmp_path / "mm.csv"
    mm.write_text("flow_m3h,opening_mm,level_A_mm,level_A_sd_mm\n72000,400,2301.5,3\n"
                  "36000,200,2250,2.5\n", encoding="utf-8")  # fmt: skip
    m = tmp_path / "m.csv"
    m.write_text("flow_m3s,opening_m,level_A_m,level_A_sd_cm\n20,0.4,2.3015,0.3\n"
                 "10,0.2,2.25,0.25\n", encoding="utf-8")  # fmt: skip
    a, b = read_static_table(mm), read_static_table(m)
    for name in ("flow_m3h", "opening_mm"):
        _close(getattr(a, name), getattr(b, name))
    _close(a.levels_mm["A"], b.levels_mm["A"])
    _close(a.level_sd_mm["A"], b.level_sd_mm["A"])
    assert b.units["flow"] == "m3s" and b.summary()["units"]["level"] == "m"
    assert detect_table_kind(m) == detect_table_kind(mm) == "static"


# --------------------------------------------------------------------------- refusals


def _check(path: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gatetwin", "check", str(path), "--json", str(out)],
        capture_output=True, text=True, encoding="utf-8", timeout=120, check=False,
    )  # fmt: skip


def _refused_in_one_line(capsys, path: Path, tmp_path: Path, *words: str) -> None:
    """``gatetwin check`` (in process) exits 2 with one line naming ``words``, no output."""
    out = tmp_path / "out.json"
    capsys.readouterr()
    assert main(["check", str(path), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("gatetwin: error: "), err
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert not out.exists()


def _renamed(tmp_path: Path, old: str, new: str) -> Path:
    path = _write(tmp_path, MM)
    lines = path.read_text(encoding="utf-8").splitlines()
    lines[0] = lines[0].replace(old, new)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_two_units_of_one_quantity_are_refused(tmp_path: Path) -> None:
    path = _write(tmp_path, MM)
    lines = path.read_text(encoding="utf-8").splitlines()
    both = [lines[0] + ",opening_m"] + [f"{row},0.4" for row in lines[1:]]
    path.write_text("\n".join(both) + "\n", encoding="utf-8")
    out = tmp_path / "out.json"
    done = _check(path, out)  # a separate process: exit code and stderr as a user sees them
    assert done.returncode == 2, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("gatetwin: error: "), done.stderr
    for word in ("field.csv", "column 'opening_mm'", "column 'opening_m'", "the same quantity"):
        assert word in lines[0], (word, lines[0])
    assert not out.exists()


def test_two_units_of_one_level_are_refused_from_a_dataframe(tmp_path: Path) -> None:
    pandas = pytest.importorskip("pandas")
    frame = pandas.read_csv(_write(tmp_path, MM))
    frame["level_A_m"] = frame["level_A_mm"] / 1000
    with pytest.raises(RecordError, match="column 'level_A_mm' and column 'level_A_m'"):
        read_record(frame)
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), tmp_path / "d.parquet")
    with pytest.raises(RecordError, match="d.parquet: column 'level_A_mm' and column 'level_A_m'"):
        read_record(tmp_path / "d.parquet")


@pytest.mark.parametrize("name", ["level_A_ft", "level_A_in", "level_A_raw"])
def test_a_level_in_an_unknown_unit_is_named(capsys, tmp_path: Path, name: str) -> None:
    path = _renamed(tmp_path, "level_A_mm", name)
    _refused_in_one_line(capsys, path, tmp_path, f"column '{name}'", "unknown unit", "mm, cm, m")


# --------------------------------------------------------------------------- field scale


def test_field_scale_record_passes_check(capsys, tmp_path: Path) -> None:
    path = _write(tmp_path, ("m", "m3s", "m", "m"), sidecar={"gate_width_m": 2.5})
    out = tmp_path / "out.json"
    assert main(["check", str(path), "--json", str(out)]) == 0
    summary = json.loads(out.read_text(encoding="utf-8"))
    assert summary["sample_period_s"] == PERIOD_S
    assert summary["units"]["opening"] == "m" and summary["units"]["flow"] == "m3s"
    assert summary["gate_width_m"] == 2.5
    assert summary["gauges"][0]["level_mm"]["max"] > 2300
    assert summary["flow_m3h"]["min"] == pytest.approx(20125 * 3.6, rel=RTOL)
    assert len(summary["steps"]) == 1 and summary["steps"][0]["delta_e_mm"] == pytest.approx(50)
    assert "units    opening m, flow m3s" in capsys.readouterr().out


def test_a_minute_log_is_not_refused_for_gaps(tmp_path: Path) -> None:
    path = _write(tmp_path, MM)
    lines = path.read_text(encoding="utf-8").splitlines()
    minute = [lines[0]] + [f"{int(r.split(',')[0]) * 6}," + r.split(",", 1)[1] for r in lines[1:]]
    path.write_text("\n".join(minute) + "\n", encoding="utf-8")
    assert read_record(path).sample_period_s == 60


# --------------------------------------------------------------------------- sidecar


def test_gate_width_reaches_the_record(tmp_path: Path) -> None:
    assert read_record(_write(tmp_path, MM, sidecar={"gate_width_m": 3})).gate_width_m == 3.0
    assert read_record(_write(tmp_path, MM, "bare.csv")).gate_width_m is None


@pytest.mark.parametrize("width", [0, -1.5, "2.5", True, [2], "1e400"])
def test_a_bad_gate_width_is_refused(capsys, tmp_path: Path, width) -> None:
    path = _write(tmp_path, MM, sidecar={})
    text = '{"gate_width_m": 1e400}' if width == "1e400" else json.dumps({"gate_width_m": width})
    path.with_suffix(".json").write_text(text, encoding="utf-8")
    _refused_in_one_line(capsys, path, tmp_path, "field.json", "'gate_width_m'", "positive, finite")


def test_levels_above_a_datum_need_their_bounds_in_the_sidecar(capsys, tmp_path: Path) -> None:
    path = _write(tmp_path, MM)
    lines = path.read_text(encoding="utf-8").splitlines()
    shifted = [lines[0]]
    for row in lines[1:]:  # the same levels as elevations 412 m above a datum
        cells = row.split(",")
        cells[4] = str(Decimal(cells[4]) + 412000)
        shifted.append(",".join(cells))
    path.write_text("\n".join(shifted) + "\n", encoding="utf-8")
    _refused_in_one_line(capsys, path, tmp_path, "column 'level_A_mm'", "physical range")
    path.with_suffix(".json").write_text(json.dumps({"bounds": {"level_m": [0, 450]}}), "utf-8")
    record = read_record(path)
    assert float(np.nanmin(record.levels_mm["A"])) > 412000


def test_sample_period_bounds(capsys, tmp_path: Path) -> None:
    path = _write(tmp_path, MM)
    lines = path.read_text(encoding="utf-8").splitlines()
    slow = [lines[0]] + [f"{int(r.split(',')[0]) * 720}," + r.split(",", 1)[1] for r in lines[1:]]
    path.write_text("\n".join(slow) + "\n", encoding="utf-8")  # a 2 h log
    _refused_in_one_line(capsys, path, tmp_path, "sample period 7200 s", "accepted range")
    path.with_suffix(".json").write_text(
        json.dumps({"bounds": {"sample_period_s": [60, 7200], "gap_max_s": 1e6}}), "utf-8"
    )
    assert read_record(path).sample_period_s == 7200


@pytest.mark.parametrize(
    ("bounds", "word"),
    [
        ({"level_ft": [0, 1]}, "bounds.level_ft"),
        ({"level_m": [5, 1]}, "low < high"),
        ({"level_m": [0, 5], "level_mm": [0, 5000]}, "second bound"),
        ({"gap_max_s": -1}, "bounds.gap_max_s"),
        ([1, 2], "'bounds'"),
    ],
)
def test_bad_bounds_are_refused(capsys, tmp_path: Path, bounds, word: str) -> None:
    path = _write(tmp_path, MM, sidecar={"bounds": bounds})
    _refused_in_one_line(capsys, path, tmp_path, "field.json", word)


def test_a_value_message_names_the_files_column(capsys, tmp_path: Path) -> None:
    path = _write(tmp_path, ("m", "m3s", "m", "m"))
    lines = path.read_text(encoding="utf-8").splitlines()
    cells = lines[5].split(",")
    cells[4] = "250"  # 250 m of water: a level logged in cm under a metre header
    lines[5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    _refused_in_one_line(capsys, path, tmp_path, "row 6", "column 'level_A_m'", "250000 mm")
