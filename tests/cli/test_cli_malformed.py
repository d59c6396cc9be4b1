"""Every malformed record is refused by ``gatetwin check`` with one clear line.

For each file of ``tests/data/malformed/`` (made by ``tests/data/make_malformed.py``) the
command must exit non-zero, print exactly one line on stderr naming the file and the place
at fault, print no traceback, and leave no ``--json`` output behind.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

MALFORMED = Path(__file__).resolve().parents[1] / "data" / "malformed"

#: What each refusal must say (all substrings must appear in the message).
EXPECTED: dict[str, list[str]] = {
    "empty.csv": ["empty file"],
    "header_only.csv": ["header only", "no data rows"],
    "missing_state_column.csv": ["column 'state'", "missing"],
    "missing_level_column.csv": ["column 'level_<G>_mm'", "missing"],
    "duplicate_column.csv": ["column 'level_3F_mm'", "twice"],
    "text_in_level.csv": ["row 7", "column 'level_3F_mm'", "'231.6mm'", "not a number"],
    "text_in_time.csv": ["row 9", "column 'time_s'", "not a number"],
    "time_backwards.csv": ["row 20", "column 'time_s'", "time goes backwards"],
    "duplicated_time.csv": ["row 30", "column 'time_s'", "duplicated time"],
    "unknown_state.csv": ["row 12", "column 'state'", "unknown state 'moving'"],
    "empty_state.csv": ["row 15", "column 'state'", "empty cell"],
    "all_open.csv": ["column 'state'", "no 'hold' samples"],
    "semicolon.csv": ["row 1", "';'", "expected comma-separated"],
    "decimal_comma.csv": ["row 2", "10 fields", "expected 6"],
    "binary_garbage.csv": ["row 2", "NUL byte", "expected UTF-8"],
    "not_utf8.csv": ["row 4", "0xb5", "expected UTF-8"],
    "utf16.csv": ["row 1", "NUL byte", "expected UTF-8"],
    "levels_in_metres.csv": ["column 'level_3F_mm'", "looks like metres; expected mm"],
    "level_out_of_range.csv": ["row 40", "column 'level_5H_mm'", "500000 mm", "outside"],
    "nan_literal.csv": ["row 10", "column 'level_3F_mm'", "'nan'", "not a finite number"],
    "inf_literal.csv": ["row 11", "column 'flow_m3h'", "'inf'", "not a finite number"],
    "ragged_row.csv": ["row 25", "5 fields", "expected 6"],
    "blank_line_inside.csv": ["row 30", "empty line"],
    "quoted_newline.csv": ["row 5", "quoted field"],
    "negative_flow.csv": ["row 33", "column 'flow_m3h'", "negative"],
    "negative_opening.csv": ["row 8", "column 'opening_mm'", "negative"],
    "empty_time.csv": ["row 16", "column 'time_s'", "empty cell"],
    "empty_flow.csv": ["column 'flow_m3h'", "every cell is empty"],
    "hold_without_opening.csv": ["row 65 to row 124", "column 'opening_mm'"],
    "step_without_step.csv": ["column 'opening_mm'", "test 'step' (from the sidecar)", "no step"],
    "too_few_samples_step.csv": ["row 22", "20 valid samples", "≥ 40"],
    "prbs_too_short.csv": ["column 'opening_mm'", "3 step(s)", "24 usable", "≥ 30"],
    "bad_sidecar.csv": ["bad_sidecar.json", "sidecar", "not valid JSON", "line 2"],
    "bad_test_word.csv": ["bad_test_word.json", "sidecar field 'test'", "'ramp'"],
    "bad_sample_period.csv": ["bad_sample_period.json", "sidecar field 'sample_period_s'"],
    "sidecar_not_object.csv": ["sidecar_not_object.json", "sidecar", "JSON list"],
    "static_text_in_flow.csv": ["row 3", "column 'flow_m3h'", "'approx 26'"],
    "static_levels_in_metres.csv": ["column 'level_3F_mm'", "looks like metres"],
}

FILES = sorted(p.name for p in MALFORMED.glob("*.csv"))


def _check(path: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gatetwin", "check", str(path), "--json", str(out)],
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=120,
        check=False,
    )


def test_every_file_has_an_expectation() -> None:
    assert len(FILES) >= 18
    assert set(FILES) == set(EXPECTED)


@pytest.mark.parametrize("name", FILES)
def test_malformed_file_is_refused_in_one_line(name: str, tmp_path: Path) -> None:
    out = tmp_path / "out.json"
    result = _check(MALFORMED / name, out)
    assert result.returncode != 0
    assert "Traceback" not in result.stderr + result.stdout
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].strip(), result.stderr
    message = lines[0]
    assert message.startswith("gatetwin: error: ")
    assert Path(name).stem in message
    assert any(word in message for word in ("row", "column", "sidecar", "file")), message
    for expected in EXPECTED[name]:
        assert expected in message, f"{expected!r} not in {message!r}"
    assert not out.exists()


def test_missing_file_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out.json"
    result = _check(tmp_path / "nowhere.csv", out)
    assert result.returncode != 0
    lines = result.stderr.splitlines()
    assert len(lines) == 1
    assert "nowhere.csv" in lines[0] and "no such file" in lines[0]
    assert "Traceback" not in result.stderr
    assert not out.exists()
