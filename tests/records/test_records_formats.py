"""One record, many containers: CSV through Arrow or the diagnosing parser, Parquet, pandas.

Invariant: the same samples give the same :class:`Record` whichever way they arrive.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gatetwin.errors import GatetwinError, RecordError
from gatetwin.records import ReadLimits, Record, read_record

HEADER = "time_s,opening_mm,state,flow_m3h,level_3F_mm,level_5H_mm"
SIDECAR = {"sample_period_s": 1.2, "gauges": {"3F": 1.1, "5H": 0.2}, "condition": "A"}


def _rows() -> list[str]:
    """Two holds around a step, with empty openings while moving and a missing level."""
    rows = []
    for k in range(140):
        state, opening = ("hold", 15.0) if k < 65 else ("open", None) if k < 70 else ("hold", 20.0)
        level = 300.0 - 0.01 * k - (0.0 if k < 70 else 40.0)
        cell = "" if opening is None else f"{opening:g}"
        level_cell = "" if k == 100 else f"{level:.2f}"
        rows.append(f"{k * 1.2:.1f},{cell},{state},29.5,{level_cell},{level + 6:.2f}")
    return rows


def _write(folder: Path, rows: list[str], name: str = "rec.csv") -> Path:
    path = folder / name
    path.write_text("\n".join([HEADER, *rows]) + "\n", encoding="utf-8")
    path.with_suffix(".json").write_text(json.dumps(SIDECAR), encoding="utf-8")
    return path


def _same(a: Record, b: Record) -> None:
    for name in ("time_s", "opening_mm", "hold", "flow_m3h"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.gauges == b.gauges
    for gauge in a.gauges:
        np.testing.assert_array_equal(a.levels_mm[gauge], b.levels_mm[gauge])
    assert (a.test, a.sample_period_s, a.holds, a.steps) == (b.test, b.sample_period_s,
                                                              b.holds, b.steps)  # fmt: skip
    assert a.gauges_m == b.gauges_m


def test_arrow_and_diagnosing_parser_agree(tmp_path: Path) -> None:
    fast = read_record(_write(tmp_path, _rows()))
    # Quotes send a file to the diagnosing parser; CRLF and padding change nothing.
    quoted = [",".join(f'"{c}"' if j == 2 else f" {c}" for j, c in enumerate(r.split(",")))
              for r in _rows()]  # fmt: skip
    path = tmp_path / "slow.csv"
    path.write_bytes(("\r\n".join([HEADER, *quoted]) + "\r\n").encode())
    path.with_suffix(".json").write_text(json.dumps(SIDECAR), encoding="utf-8")
    _same(fast, read_record(path))
    assert np.isnan(fast.levels_mm["3F"][100])


def test_path_like_and_str_read_the_same(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows())
    _same(read_record(str(path)), read_record(os.fspath(path)))
    with pytest.raises(RecordError, match="expected a file path or a DataFrame"):
        read_record(42)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- Parquet


def _parquet(folder: Path, table: pa.Table, name: str = "rec.parquet") -> Path:
    path = folder / name
    pq.write_table(table, path)
    path.with_suffix(".json").write_text(json.dumps(SIDECAR), encoding="utf-8")
    return path


def _arrow_table(record: Record) -> pa.Table:
    return pa.table({
        "time_s": record.time_s, "opening_mm": record.opening_mm,
        "state": np.where(record.hold, "hold", "open"), "flow_m3h": record.flow_m3h,
        "level_3F_mm": record.levels_mm["3F"], "level_5H_mm": record.levels_mm["5H"],
    })  # fmt: skip


def test_parquet_record_equals_csv_record(tmp_path: Path) -> None:
    csv_record = read_record(_write(tmp_path, _rows()))
    path = _parquet(tmp_path, _arrow_table(csv_record))
    parquet_record = read_record(path)
    _same(csv_record, parquet_record)
    assert parquet_record.metadata["condition"] == "A"
    assert len(parquet_record.sha256) == 64


def test_parquet_checks_are_the_csv_checks(tmp_path: Path) -> None:
    table = _arrow_table(read_record(_write(tmp_path, _rows())))
    time_s = table.column("time_s").to_pylist()
    time_s[10] = time_s[9]
    bad = table.set_column(0, "time_s", pa.array(time_s))
    with pytest.raises(RecordError, match=r"bad.parquet: row 11: column 'time_s': duplicated"):
        read_record(_parquet(tmp_path, bad, "bad.parquet"))
    flow = table.column("flow_m3h").to_pylist()
    flow[5] = float("inf")
    inf = table.set_column(3, "flow_m3h", pa.array(flow))
    with pytest.raises(RecordError, match=r"row 6: column 'flow_m3h': inf is not a finite"):
        read_record(_parquet(tmp_path, inf, "inf.parquet"))
    text = table.set_column(3, "flow_m3h", pa.array(["29.5"] * table.num_rows))
    with pytest.raises(RecordError, match=r"column 'flow_m3h': values of type string"):
        read_record(_parquet(tmp_path, text, "text.parquet"))


def test_broken_or_oversized_parquet_is_refused(tmp_path: Path) -> None:
    junk = tmp_path / "junk.parquet"
    junk.write_bytes(b"PAR1" + bytes(range(256)) * 4)
    with pytest.raises(RecordError, match="junk.parquet: not a readable Parquet file"):
        read_record(junk)
    # A million constant rows compress to a few kB but decode to 48 MB.
    n = 1_000_000
    table = pa.table(
        {
            "time_s": np.arange(n, dtype=float),
            "opening_mm": np.full(n, 15.0),
            "state": ["hold"] * n,
            "flow_m3h": np.full(n, 29.5),
            "level_3F_mm": np.full(n, 300.0),
            "level_5H_mm": np.full(n, 306.0),
        }
    )
    path = _parquet(tmp_path, table)
    limit = 10 * path.stat().st_size
    with pytest.raises(RecordError, match="rec.parquet: 48000000 bytes of data decoded"):
        read_record(path, limits=ReadLimits(max_bytes=limit))


# --------------------------------------------------------------------------- pandas


def test_pandas_round_trip(tmp_path: Path) -> None:
    pytest.importorskip("pandas")
    record = read_record(_write(tmp_path, _rows()))
    frame = record.to_pandas()
    assert list(frame.columns) == HEADER.split(",")
    again = Record.from_pandas(frame, sample_period_s=1.2, gauges=SIDECAR["gauges"])
    _same(record, again)
    via_reader = read_record(frame.assign(extra="ignored"))
    np.testing.assert_array_equal(via_reader.levels_mm["5H"], record.levels_mm["5H"])


def test_from_pandas_refuses_what_read_record_refuses() -> None:
    pandas = pytest.importorskip("pandas")
    frame = pandas.DataFrame({
        "time_s": [0.0, 1.2, 2.4], "opening_mm": [15.0, 15.0, 15.0],
        "state": ["hold", "hold", "parked"], "flow_m3h": [29.5] * 3,
        "level_3F_mm": [300.0] * 3,
    })  # fmt: skip
    with pytest.raises(RecordError, match=r"<DataFrame>: row 3: column 'state': unknown state"):
        Record.from_pandas(frame)
    frame["state"] = "hold"
    frame["flow_m3h"] = ["29.5", "x", "29.5"]
    with pytest.raises(RecordError, match="column 'flow_m3h'"):
        Record.from_pandas(frame)
    frame["flow_m3h"] = 29.5
    with pytest.raises(RecordError, match="column 'level_<G>_mm': missing"):
        Record.from_pandas(frame.drop(columns="level_3F_mm"))


def test_to_pandas_without_pandas_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    record = read_record(_write(tmp_path, _rows()))
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(GatetwinError, match="needs pandas, which is not installed"):
        record.to_pandas()
