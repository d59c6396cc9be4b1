"""Hostile records are refused in one line: special files, limits, grammar, physics.

Each case is a file a careless logger or a malicious user could hand over; the reader
must refuse it with one line naming the file and, where there is one, the row and column,
without hanging, crashing or echoing a huge cell, and ``gatetwin check`` must leave no
output behind.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from gatetwin.cli import main
from gatetwin.errors import RecordError
from gatetwin.records import ReadLimits, read_record, read_static_table

HEADER = "time_s,opening_mm,state,flow_m3h,level_3F_mm"
#: A message quotes at most 60 characters of a cell; with the file name and the words
#: around it a refusal stays well under this many characters.
MAX_MESSAGE_CHARS = 400


def _rows(n: int = 130, period: float = 1.2) -> list[str]:
    """A valid step record: 60 holds at 15 mm, 5 moving, 65 holds at 20 mm."""
    rows = []
    for k in range(n):
        state, opening = ("hold", "15") if k < 60 else ("open", "") if k < 65 else ("hold", "20")
        level = 300.0 - (0.0 if k < 65 else 50.0)
        rows.append(f"{k * period:.1f},{opening},{state},29.5,{level:.1f}")
    return rows


def _write(folder: Path, rows: list[str], name: str = "rec.csv") -> Path:
    path = folder / name
    path.write_text("\n".join([HEADER, *rows]) + "\n", encoding="utf-8")
    return path


def _check(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    code = main(["check", *args])
    return code, capsys.readouterr().err.splitlines()


def _refused(path: Path, *words: str, **kwargs: object) -> str:
    with pytest.raises(RecordError) as info:
        read_record(path, **kwargs)  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message and len(message) < MAX_MESSAGE_CHARS, message
    assert path.name in message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    return message


def test_the_base_record_is_valid(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows()))
    assert record.test == "step" and len(record.steps) == 1


# --------------------------------------------------------------------------- special files


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_symlink_to_a_device_is_refused(tmp_path: Path, device: str) -> None:
    if not os.path.exists(device):
        pytest.skip(f"{device} missing")
    link = tmp_path / "rec.csv"
    link.symlink_to(device)
    _refused(link, "character device", "not a regular file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_is_refused_without_blocking(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "rec.csv"
    os.mkfifo(fifo)
    out = tmp_path / "out.json"
    code, err = _check([str(fifo), "--json", str(out)], capsys)
    assert code == 2 and len(err) == 1 and "FIFO" in err[0]
    assert not out.exists()


def test_directory_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "rec.csv"
    folder.mkdir()
    _refused(folder, "is a directory")


def test_sidecar_that_is_a_device_is_refused(tmp_path: Path) -> None:
    path = _write(tmp_path, _rows())
    path.with_suffix(".json").symlink_to("/dev/zero")
    with pytest.raises(RecordError, match="rec.json: is a character device"):
        read_record(path)


# --------------------------------------------------------------------------- limits


def test_size_limit_by_keyword_and_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _write(tmp_path, _rows())
    size = path.stat().st_size
    _refused(path, f"{size} bytes", "limit of 1000 bytes", limits=ReadLimits(max_bytes=1000))
    monkeypatch.setenv("GATETWIN_MAX_BYTES", "1000")
    _refused(path, "limit of 1000 bytes")
    monkeypatch.setenv("GATETWIN_MAX_BYTES", str(size))
    assert read_record(path).n_samples == 130


def test_bad_environment_limit_is_refused(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("GATETWIN_MAX_LINE_BYTES", "lots")
    with pytest.raises(RecordError, match="GATETWIN_MAX_LINE_BYTES"):
        read_record(_write(tmp_path, _rows()))


def test_huge_line_without_comma_is_refused_in_one_line(tmp_path: Path) -> None:
    rows = _rows()
    rows[10] = "7" * 3_000_000
    path = _write(tmp_path, rows)
    _refused(path, "row 12", "longer than the limit of 65536 bytes")
    # Allowed past the limit, it is a row of one field, still one short line.
    _refused(path, "row 12", "1 field", limits=ReadLimits(max_line_bytes=10_000_000))


def test_huge_cell_is_not_echoed(tmp_path: Path) -> None:
    rows = _rows()
    rows[20] = rows[20].replace("hold", "h" * 200_000)
    path = _write(tmp_path, rows)
    message = _refused(path, "row 22", "column 'state'",
                       limits=ReadLimits(max_line_bytes=1_000_000))  # fmt: skip
    assert "200000 characters" in message


def test_cli_options_raise_the_limits(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, _rows())
    code, err = _check([str(path), "--max-bytes", "100"], capsys)
    assert code == 2 and len(err) == 1 and "limit of 100 bytes" in err[0]
    code, err = _check([str(path), "--max-line-bytes", "10"], capsys)
    assert code == 2 and len(err) == 1 and "row 1" in err[0]
    code, err = _check([str(path), "--max-bytes", "0"], capsys)
    assert code == 2 and len(err) == 1 and "max_bytes" in err[0]
    code, _ = _check([str(path), "--max-bytes", str(10**6)], capsys)
    assert code == 0


# --------------------------------------------------------------------------- grammar


@pytest.mark.parametrize("cell", ["2_8_2.5", "١٢", "１２", "0x10", "1.5e", "12mm", "1,5", "--1",
                                  "nan", "Infinity", "1e400"])  # fmt: skip
def test_numbers_follow_the_format_grammar(tmp_path: Path, cell: str) -> None:
    rows = _rows()
    parts = rows[30].split(",")
    parts[4] = f'"{cell}"' if "," in cell else cell
    rows[30] = ",".join(parts)
    _refused(_write(tmp_path, rows), "row 32", "column 'level_3F_mm'")


@pytest.mark.parametrize("cell", ["+300", "300.", "3e2", "3.0E+02", " 300 ", ".3e3"])
def test_numbers_of_the_grammar_are_read(tmp_path: Path, cell: str) -> None:
    rows = _rows()
    parts = rows[30].split(",")
    parts[4] = cell
    rows[30] = ",".join(parts)
    record = read_record(_write(tmp_path, rows))
    assert record.levels_mm["3F"][30] == 300.0


# --------------------------------------------------------------------------- physics


@pytest.mark.parametrize(
    ("column", "value", "words"),
    [
        (0, "1e300", ["column 'time_s'", "physical bound"]),
        (0, "-1e300", ["column 'time_s'", "physical bound"]),
        (1, "1e6", ["column 'opening_mm'", "physical bound"]),
        (3, "1e9", ["column 'flow_m3h'", "physical bound"]),
        (4, "1e6", ["column 'level_3F_mm'", "outside the physical range"]),
    ],
)
def test_magnitudes_beyond_physics_are_refused(
    tmp_path: Path, column: int, value: str, words: list[str]
) -> None:
    rows = _rows()
    parts = rows[0].split(",")
    parts[column] = value
    rows[0] = ",".join(parts)
    _refused(_write(tmp_path, rows), "row 2", *words)


def test_a_gap_longer_than_a_day_is_refused(tmp_path: Path) -> None:
    rows = _rows()
    shifted = [f"{float(r.split(',')[0]) + 1e9:.1f}," + r.split(",", 1)[1] for r in rows[80:]]
    _refused(_write(tmp_path, rows[:80] + shifted), "row 82", "gap of", "86400 s")


def test_static_table_bounds(tmp_path: Path) -> None:
    path = tmp_path / "static.csv"
    path.write_text("flow_m3h,opening_mm,level_3F_mm\n20,15,300\n2e9,20,280\n", encoding="utf-8")
    with pytest.raises(RecordError, match="row 3: column 'flow_m3h'"):
        read_static_table(path)


# --------------------------------------------------------------------------- outputs


@pytest.mark.skipif(sys.platform != "linux", reason="/proc is Linux's")
def test_unwritable_destination_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, _rows())
    code, err = _check([str(path), "--json", "/proc/self/gatetwin.json"], capsys)
    assert code == 2 and len(err) == 1 and "cannot write" in err[0]


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="permissions do not bind the superuser")  # fmt: skip
def test_read_only_folder_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, _rows())
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        code, err = _check([str(path), "--json", str(folder / "out.json")], capsys)
    finally:
        folder.chmod(0o755)
    assert code == 2 and len(err) == 1 and "cannot write" in err[0]
    assert list(folder.iterdir()) == []


def test_arrays_stay_float64_and_read_only(tmp_path: Path) -> None:
    record = read_record(_write(tmp_path, _rows()))
    for values in (record.time_s, record.opening_mm, record.flow_m3h, record.levels_mm["3F"]):
        assert values.dtype == np.float64 and not values.flags.writeable


def test_one_bad_cell_among_many_integers_is_found_at_once(tmp_path: Path) -> None:
    # Quotes send the file to the diagnosing parser, whose number pattern must match a
    # cell in one way only; an ambiguous one backtracks exponentially over the chunk.
    rows = [f'{k * 1.2:.1f},15,"hold",29,{300 + k % 7}' for k in range(3000)]
    rows[2990] = rows[2990].replace(",29,", ",2x9,")
    _refused(_write(tmp_path, rows), "row 2992", "column 'flow_m3h'", "'2x9'")
