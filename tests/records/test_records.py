"""Reading, checking and segmenting records (gatetwin.records)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from gatetwin.errors import RecordError
from gatetwin.records import (
    Record,
    detect_table_kind,
    read_record,
    read_static_table,
    record_from_arrays,
)

HEADER = "time_s,opening_mm,state,flow_m3h,level_3F_mm,level_5H_mm"


def _rows(segments: list[tuple[str, float | None, int]], period: float = 1.2) -> list[str]:
    """CSV rows for ``(state, opening, count)`` segments; level falls 15 mm per mm of opening."""
    rows, t = [], 0.0
    for state, opening, count in segments:
        for _ in range(count):
            cell = "" if opening is None else f"{opening:g}"
            level = 1000.0 - 15.0 * (opening if opening is not None else 0.0)
            rows.append(f"{t:.2f},{cell},{state},29.5,{level:.1f},{level + 6:.1f}")
            t += period
    return rows


def _write(
    tmp_path: Path,
    rows: list[str],
    name: str = "rec.csv",
    header: str = HEADER,
    sidecar: dict | None = None,
) -> Path:
    path = tmp_path / name
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    if sidecar is not None:
        path.with_suffix(".json").write_text(json.dumps(sidecar), encoding="utf-8")
    return path


STEP = [("hold", 15.0, 60), ("open", None, 3), ("hold", 20.0, 60)]


def _arrays(segments: list[tuple[str, float | None, int]], period: float = 1.2) -> dict:
    opening = np.concatenate([np.full(n, np.nan if e is None else e) for _, e, n in segments])
    hold = np.concatenate([np.full(n, s == "hold") for s, _, n in segments])
    n = opening.size
    level = 1000.0 - 15.0 * np.nan_to_num(opening)
    return {
        "time_s": np.arange(n) * period,
        "opening_mm": opening,
        "hold": hold,
        "flow_m3h": np.full(n, 29.5),
        "levels_mm": {"3F": level, "5H": level + 6.0},
    }


# --------------------------------------------------------------------------- step record


def test_step_record_segments_and_onset(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows(STEP)))
    assert [(h.start, h.stop, h.opening_mm) for h in record.holds] == [
        (0, 60, 15.0),
        (63, 123, 20.0),
    ]
    (step,) = record.steps
    assert step.index == 60
    assert step.time_s == pytest.approx(72.0)
    assert not record.hold[step.index]  # the first open sample
    assert step.delta_e_mm == pytest.approx(5.0)
    assert (record.test, record.test_source) == ("step", "detected")
    assert record.gauges == ("3F", "5H")
    assert record.sample_period_s == pytest.approx(1.2)
    assert record.n_samples == 123


def test_record_arrays_are_read_only(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows(STEP)))
    for values in (
        record.time_s,
        record.opening_mm,
        record.hold,
        record.flow_m3h,
        *record.levels_mm.values(),
    ):
        with pytest.raises(ValueError):
            values[0] = 1


def test_sha256_is_of_the_csv_bytes(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(STEP))
    assert read_record(path).sha256 == hashlib.sha256(path.read_bytes()).hexdigest()


def test_missing_opening_in_open_samples_stays_nan(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows(STEP)))
    assert np.isnan(record.opening_mm[60:63]).all()
    assert np.isfinite(record.opening_mm[record.hold]).all()


def test_empty_hold_opening_is_filled_from_its_segment(tmp_path: Path) -> None:
    rows = _rows(STEP)
    rows[10] = rows[10].replace(",15,hold,", ",,hold,")
    record = read_record(_write(tmp_path, rows))
    assert record.opening_mm[10] == 15.0
    assert record.opening_filled is not None
    assert np.flatnonzero(record.opening_filled).tolist() == [10]
    assert len(record.holds) == 2


# --------------------------------------------------------------------------- splits


def test_hold_segments_split_at_a_logging_gap(tmp_path: Path) -> None:
    rows = _rows([("hold", 15.0, 100)])
    shifted = []
    for k, row in enumerate(rows):
        t, rest = row.split(",", 1)
        shifted.append(f"{float(t) + (30.0 if k >= 50 else 0.0):.2f},{rest}")
    record = read_record(_write(tmp_path, shifted))
    assert [(h.start, h.stop) for h in record.holds] == [(0, 50), (50, 100)]
    assert record.steps == ()
    assert (record.test, record.test_source) == ("free", "detected")
    for h in record.holds:  # no segment bridges the gap
        assert np.all(np.diff(record.time_s[h.slice]) < 1.5 * record.sample_period_s)


def test_hold_segments_split_at_an_opening_change(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows([("hold", 15.0, 50), ("hold", 16.0, 50)])))
    assert [(h.start, h.stop, h.opening_mm) for h in record.holds] == [
        (0, 50, 15.0),
        (50, 100, 16.0),
    ]
    (step,) = record.steps
    assert step.index == 50
    assert step.delta_e_mm == pytest.approx(1.0)


def test_opening_jitter_below_resolution_does_not_split(tmp_path: Path) -> None:
    rows = _rows([("hold", 15.0, 50), ("hold", 15.5, 50)])
    record = read_record(_write(tmp_path, rows))
    assert len(record.holds) == 1
    assert record.steps == ()


def test_step_inside_a_logging_gap_is_not_a_step(tmp_path: Path) -> None:
    data = _arrays([("hold", 15.0, 50), ("hold", 20.0, 50)])
    data["time_s"] = data["time_s"] + np.where(np.arange(100) >= 50, 60.0, 0.0)
    record = record_from_arrays(**data)
    assert len(record.holds) == 2
    assert record.steps == ()
    assert record.unobserved_steps == 1
    with pytest.raises(RecordError, match="inside logging gaps"):
        record_from_arrays(**data, test="step")


# --------------------------------------------------------------------------- test type


def test_detects_free_and_prbs(tmp_path: Path) -> None:
    free = read_record(_write(tmp_path, _rows([("hold", 20.0, 80)]), "free.csv"))
    assert (free.test, free.test_source) == ("free", "detected")
    segments: list[tuple[str, float | None, int]] = []
    for e in (35.0, 45.0, 35.0, 25.0, 35.0, 45.0):
        segments += [("hold", e, 15), ("open", None, 2)]
    prbs = read_record(_write(tmp_path, _rows(segments), "prbs.csv"))
    assert (prbs.test, prbs.test_source) == ("prbs", "detected")
    assert len(prbs.steps) == 5
    assert [s.delta_e_mm for s in prbs.steps] == [10.0, -10.0, -10.0, 10.0, 10.0]


def test_sidecar_overrides_detection_and_option_overrides_sidecar(tmp_path: Path) -> None:
    sidecar = {"test": "free", "sample_period_s": 1.25, "gauges": {"3F": 1.1, "1D": 3.0}}
    path = _write(tmp_path, _rows(STEP), sidecar=sidecar)
    record = read_record(path)
    assert (record.test, record.test_source) == ("free", "sidecar")
    assert record.sample_period_s == 1.25
    assert record.gauges_m == {"3F": 1.1}  # 1D is not in the record
    assert record.metadata["gauges"]["1D"] == 3.0
    record = read_record(path, test="step")
    assert (record.test, record.test_source) == ("step", "option")


def test_bad_test_option_is_refused(tmp_path: Path) -> None:
    with pytest.raises(RecordError, match="expected 'step', 'prbs', 'free' or 'routine'"):
        read_record(_write(tmp_path, _rows(STEP)), test="ramp")


def test_step_test_needs_40_samples_each_side() -> None:
    short = [("hold", 15.0, 39), ("open", None, 3), ("hold", 20.0, 60)]
    assert record_from_arrays(**_arrays(short)).test == "free"
    with pytest.raises(RecordError, match=r"sample 39: .* 39 valid samples"):
        record_from_arrays(**_arrays(short), test="step")
    enough = [("hold", 15.0, 40), ("open", None, 3), ("hold", 20.0, 40)]
    assert record_from_arrays(**_arrays(enough), test="step").test == "step"


def test_prbs_test_needs_steps_and_usable_samples() -> None:
    with pytest.raises(RecordError, match="found 1 step"):
        record_from_arrays(**_arrays(STEP), test="prbs")
    segments: list[tuple[str, float | None, int]] = [
        ("hold", 35.0, 12),
        ("open", None, 1),
        ("hold", 45.0, 12),
        ("open", None, 1),
        ("hold", 35.0, 12),
    ]
    record = record_from_arrays(**_arrays(segments), test="prbs")  # 3 × (12 − 2) = 30
    assert len(record.steps) == 2


# --------------------------------------------------------------------------- formats


def test_extra_columns_crlf_bom_and_quotes_are_accepted(tmp_path: Path) -> None:
    header = HEADER + ",level_3F_sd_mm,comment"
    rows = [row.replace(",hold,", ',"hold",') + ",0.3,x" for row in _rows(STEP)]
    text = "\r\n".join([header, *rows]) + "\r\n\r\n"
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    record = read_record(path)
    assert record.gauges == ("3F", "5H")
    assert len(record.steps) == 1


def test_record_from_arrays_matches_read_record(tmp_path: Path) -> None:
    from_file = read_record(_write(tmp_path, _rows(STEP)))
    from_arrays = record_from_arrays(**_arrays(STEP))
    assert from_arrays.holds == from_file.holds
    assert [s.index for s in from_arrays.steps] == [s.index for s in from_file.steps]
    assert from_arrays.path == "" and from_arrays.sha256 == ""
    assert isinstance(from_arrays, Record)
    assert not from_arrays.time_s.flags.writeable


def test_record_from_arrays_names_samples() -> None:
    data = _arrays(STEP)
    data["time_s"][7] = data["time_s"][6]
    with pytest.raises(RecordError, match=r"^<arrays>: sample 7: column 'time_s': duplicated"):
        record_from_arrays(**data)
    data = _arrays(STEP)
    data["flow_m3h"][:] = np.nan
    with pytest.raises(RecordError, match=r"^synthetic: column 'flow_m3h': every cell is empty"):
        record_from_arrays(**data, path="synthetic")


def test_an_empty_discharge_cell_holds_the_last_logged_one() -> None:
    """The record format: empty cells are missing values. A flow meter's dropout is held
    from the last logged discharge (the first logged one before any), and the record says
    where (``flow_filled``, and the summary's count)."""
    data = _arrays(STEP)
    logged = data["flow_m3h"].copy()
    data["flow_m3h"][[0, 1, 7, 8, 9]] = np.nan
    record = record_from_arrays(**data, path="synthetic")
    expected = logged.copy()
    expected[[0, 1]] = logged[2]
    expected[[7, 8, 9]] = logged[6]
    assert np.array_equal(record.flow_m3h, expected)
    assert np.flatnonzero(record.flow_filled).tolist() == [0, 1, 7, 8, 9]
    assert record.summary()["flow_filled_samples"] == 5


def test_record_from_arrays_metadata_and_options() -> None:
    record = record_from_arrays(
        **_arrays(STEP),
        sample_period_s=1.2,
        gauges_m={"3F": 1.1},
        metadata={"condition": "A", "test": "free"},
    )
    assert (record.test, record.test_source) == ("free", "sidecar")
    assert record.gauges_m == {"3F": 1.1}
    assert record.metadata["condition"] == "A"


def test_summary_is_strict_json(tmp_path: Path) -> None:
    summary = read_record(_write(tmp_path, _rows(STEP))).summary()
    text = json.dumps(summary, allow_nan=False)
    assert json.loads(text)["steps"][0]["delta_e_mm"] == 5.0


def test_static_table(tmp_path: Path) -> None:
    path = tmp_path / "static.csv"
    path.write_text(
        "flow_m3h,opening_mm,level_3F_mm,level_3F_sd_mm,level_5H_mm\n"
        "26.3,15,241.0,0.4,247.5\n26.3,20,161.5,0.5,\n68.1,30,310.0,0.6,316.0\n",
        encoding="utf-8",
    )
    assert detect_table_kind(path) == "static"
    table = read_static_table(path)
    assert table.n_points == 3
    assert table.gauges == ("3F", "5H")
    assert table.flow_m3h.tolist() == [26.3, 26.3, 68.1]
    assert table.level_sd_mm["3F"].tolist() == [0.4, 0.5, 0.6]
    assert "5H" not in table.level_sd_mm
    assert np.isnan(table.levels_mm["5H"][1])
    assert not table.opening_mm.flags.writeable
    assert table.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()


def test_detect_table_kind_of_a_record(tmp_path: Path) -> None:
    assert detect_table_kind(_write(tmp_path, _rows(STEP))) == "record"
    assert detect_table_kind(tmp_path / "missing.csv") == "record"
    # a time series whose time column is misnamed is still a record (refused for time_s)
    misnamed = _write(tmp_path, _rows(STEP), "t.csv", HEADER.replace("time_s", "time", 1))
    assert detect_table_kind(misnamed) == "record"
    with pytest.raises(RecordError, match="column 'time_s': missing"):
        read_record(misnamed)


def test_sidecar_with_nan_constant_is_refused(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(STEP))
    path.with_suffix(".json").write_text('{"condition": NaN}', encoding="utf-8")
    with pytest.raises(RecordError, match=r"rec\.json: sidecar is not valid JSON \(NaN"):
        read_record(path)


def test_sidecar_period_far_from_the_data_is_refused(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows(STEP, period=5.0), sidecar={"sample_period_s": 1.2})
    with pytest.raises(RecordError, match="median time step is 5 s"):
        read_record(path)


def test_sidecar_period_twice_the_datas_is_refused(tmp_path: Path) -> None:
    """A logger at 30 s whose sidecar says 60 s: read as 60 s, every time constant and
    horizon sized from the period would be off by two."""
    path = _write(tmp_path, _rows(STEP, period=30.0), sidecar={"sample_period_s": 60.0})
    with pytest.raises(RecordError, match=r"sample period 60 s \(sidecar field "
                       r"'sample_period_s'\) but the median time step is 30 s"):  # fmt: skip
        read_record(path)
