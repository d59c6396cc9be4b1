"""Property: ``gatetwin check`` refuses any malformed record in one line, exit 2, no output.

Hypothesis breaks a valid record in one of several ways that each make it malformed by
the data format (a cell outside the number grammar, a magnitude beyond physics, a missing
cell, time out of order, an unknown state word, a NUL byte) and runs the command in
process. The default run tries a fixed, small number of examples (a few seconds); the
``slow`` variant tries many more.
"""

from __future__ import annotations

import string
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gatetwin.cli import main

HEADER = "time_s,opening_mm,state,flow_m3h,level_3F_mm"
NUMERIC = (0, 1, 3, 4)
#: Characters a number of the format may contain; a cell with anything else is malformed.
NUMBER_CHARS = set(string.digits + ".eE+- \t")


def _rows() -> list[list[str]]:
    rows = []
    for k in range(130):
        state, opening = ("hold", "15") if k < 60 else ("open", "") if k < 65 else ("hold", "20")
        rows.append([f"{k * 1.2:.1f}", opening, state, "29.5", "300.0" if k < 65 else "250.0"])
    return rows


def _not_a_number(text: str) -> bool:
    # white space alone ("\r" before the newline, say) leaves an empty cell, a missing value
    # the format allows: not malformed
    return bool(text.strip()) and any(ch not in NUMBER_CHARS for ch in text)


def _not_a_state(text: str) -> bool:
    return text.strip().lower() not in ("hold", "open")


@st.composite
def malformed(draw: st.DrawFn) -> bytes:
    """The bytes of a record broken in one way."""
    rows = _rows()
    k = draw(st.integers(0, len(rows) - 1))
    kind = draw(st.sampled_from(["text", "magnitude", "missing", "order", "state", "nul"]))
    if kind == "text":
        rows[k][draw(st.sampled_from(NUMERIC))] = draw(st.text(min_size=1).filter(_not_a_number))
    elif kind == "magnitude":
        value = draw(st.floats(min_value=1e10 * 1.01, max_value=1e308))
        rows[k][draw(st.sampled_from(NUMERIC))] = repr(value)
    elif kind == "missing":
        del rows[k][draw(st.integers(0, len(rows[k]) - 1))]
    elif kind == "order":
        j = draw(st.integers(0, len(rows) - 1).filter(lambda j: j != k))
        rows[k][0], rows[j][0] = rows[j][0], rows[k][0]
    elif kind == "state":
        rows[k][2] = draw(st.text(min_size=1).filter(_not_a_state))
    else:
        rows[k][draw(st.integers(0, 4))] += "\x00"
    text = "\n".join([HEADER, *(",".join(r) for r in rows)]) + "\n"
    return text.encode("utf-8")


def _refused_in_one_line(data: bytes, capsys: pytest.CaptureFixture[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "rec.csv"
        path.write_bytes(data)
        out = folder / "out.json"
        code = main(["check", str(path), "--json", str(out)])
        captured = capsys.readouterr()
        lines = captured.err.splitlines()
        assert code == 2, captured.out[-200:]
        assert len(lines) == 1 and lines[0].startswith(f"gatetwin: error: {path}"), lines
        assert sorted(p.name for p in folder.iterdir()) == ["rec.csv"]


def test_the_unbroken_record_passes(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    path.write_text("\n".join([HEADER, *(",".join(r) for r in _rows())]) + "\n", "utf-8")
    assert main(["check", str(path), "--json", str(tmp_path / "out.json")]) == 0
    capsys.readouterr()


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=malformed())
def test_malformed_records_are_refused(data: bytes, capsys: pytest.CaptureFixture[str]) -> None:
    _refused_in_one_line(data, capsys)


@pytest.mark.slow
@settings(max_examples=1000, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=malformed())
def test_many_malformed_records_are_refused(
    data: bytes, capsys: pytest.CaptureFixture[str]
) -> None:
    _refused_in_one_line(data, capsys)
