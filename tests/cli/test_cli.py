"""The command line: ``gatetwin check`` on good input, and the error wrapper."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gatetwin.cli import build_parser, main

DATA = Path(__file__).resolve().parents[1] / "data"
sys.path.insert(0, str(DATA))
import make_malformed  # noqa: E402


@pytest.fixture()
def good_record(tmp_path: Path) -> Path:
    path = tmp_path / "A.csv"
    path.write_text(make_malformed.to_text(make_malformed.base_rows()), encoding="utf-8")
    path.with_suffix(".json").write_text(
        json.dumps({"condition": "A", "gauges": {"3F": 1.1, "5H": 0.2}}), encoding="utf-8"
    )
    return path


def test_check_prints_findings_and_writes_json(
    good_record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out" / "check.json"
    assert main(["check", str(good_record), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "step (detected from the data)" in text
    assert "3F (1.1 m)" in text
    assert "15 → 20 mm, Δe = +5 mm" in text
    summary = json.loads(out.read_text(encoding="utf-8"))
    assert summary["test"] == "step"
    assert summary["steps"][0]["index"] == 60
    assert summary["metadata"]["condition"] == "A"


def test_check_test_option(good_record: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(good_record), "--test", "free"]) == 0
    assert "free (from --test)" in capsys.readouterr().out


def test_check_static_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "static.csv"
    path.write_text(make_malformed.static_text(), encoding="utf-8")
    out = tmp_path / "static.json"
    assert main(["check", str(path), "--json", str(out)]) == 0
    assert "points   3" in capsys.readouterr().out
    assert json.loads(out.read_text(encoding="utf-8"))["kind"] == "static"


def test_error_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(tmp_path / "none.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gatetwin: error: ")


def test_usage_error_exits_2() -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["check", "x.csv", "--test", "ramp"])
    assert exc.value.code == 2


def test_python_dash_m_runs(good_record: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "gatetwin", "check", str(good_record)],
        capture_output=True,
        text=True,
        encoding="utf-8",
        check=False,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "record   " in result.stdout


def test_a_reader_that_stops_early_ends_the_command_without_a_message(good_record: Path) -> None:
    """``gatetwin check … | head -0``: the pipe is closed before the command writes; it stops
    as a shell's command ended by SIGPIPE does (status 141), with nothing on stderr."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # buffered output
    child = subprocess.Popen([sys.executable, "-m", "gatetwin", "check", str(good_record)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)  # fmt: skip
    child.stdout.close()  # long before the interpreter has imported gatetwin
    _, err = child.communicate(timeout=120)
    assert (child.returncode, err.decode()) == (141, "")
