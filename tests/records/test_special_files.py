"""Every file gatetwin reads from a user must be a regular file: a FIFO (which would block the
reader forever) or a device (``/dev/zero``: endless bytes) given as a model file, an SSP
package, an FMU or a SWMM model is refused at once in one line naming it, with a non-zero
exit and nothing written. And a gate may not take the name of a fleet summary file.

The commands given a special file run in a child process with a timeout, so that a
regression hangs the child, not the test run.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main

#: A refusal reads no byte, so it takes what starting Python and gatetwin take; a hang is
#: what this catches.
TIMEOUT_S = 120


def _gatetwin(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gatetwin", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=TIMEOUT_S)  # fmt: skip


def _refused(run: subprocess.CompletedProcess[str], name: str, kind: str) -> None:
    lines = run.stderr.strip().splitlines()
    assert run.returncode != 0
    assert len(lines) == 1, run.stderr
    assert name in lines[0] and kind in lines[0] and "not a regular file" in lines[0]
    assert "Traceback" not in run.stderr


def _commands(special: str, out: Path) -> dict[str, list[str]]:
    record = str(bundled_records_dir() / "A.csv")
    return {
        "model file": ["export", special, "--backend", "c", "--out", str(out / "m.fmu")],
        "SSP package": ["simulate-ssp", special, "--out", str(out / "run.csv")],
        "FMU": ["validate", special, record, "--json", str(out / "v.json")],
    }


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this platform")
@pytest.mark.parametrize("what", ["model file", "SSP package", "FMU"])
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path, what):
    fifo = tmp_path / "input"
    os.mkfifo(fifo)
    out = tmp_path / "out"
    out.mkdir()
    run = _gatetwin(*_commands(str(fifo), out)[what], cwd=tmp_path)
    _refused(run, str(fifo), "FIFO")
    assert not any(out.iterdir())


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero on this platform")
@pytest.mark.parametrize("what", ["model file", "SSP package", "FMU"])
def test_an_endless_device_is_refused_without_reading_it(tmp_path, what):
    out = tmp_path / "out"
    out.mkdir()
    run = _gatetwin(*_commands("/dev/zero", out)[what], cwd=tmp_path)
    _refused(run, "/dev/zero", "character device")
    assert not any(out.iterdir())


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this platform")
def test_a_fifo_as_the_swmm_model_is_refused(tmp_path):
    pytest.importorskip("pyswmm", reason="the SWMM plant needs the swmm extra (pyswmm)")
    fifo = tmp_path / "canal.inp"
    os.mkfifo(fifo)
    run = _gatetwin("swmm", "experiment", str(fifo), "--gate", "G", "--gauges", "A=0",
                    "--inflow", "A", "--design", "step", "--out", str(tmp_path / "out"),
                    cwd=tmp_path)  # fmt: skip
    _refused(run, str(fifo), "FIFO")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("gate", ["fleet.json", "fleet.md", "FLEET.PNG", "Fleet.html"])
def test_a_gate_named_like_a_fleet_summary_file_is_refused_before_any_work(tmp_path, gate,
                                                                          capsys):  # fmt: skip
    """The summary files sit beside the gate folders; a gate of the same name (compared
    case-blind, as some file systems compare) would collide with one of them."""
    records = bundled_records_dir()
    for name in (gate, "g1"):
        folder = tmp_path / "gates" / name
        folder.mkdir(parents=True)
        for suffix in (".csv", ".json"):
            (folder / f"A{suffix}").write_bytes((records / f"A{suffix}").read_bytes())
    out = tmp_path / "out"
    code = main(["models", "--records", str(tmp_path / "gates"), "--out", str(out),
                 "--workers", "1"])  # fmt: skip
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code != 0 and len(lines) == 1, err
    assert repr(gate) in lines[0] and "fleet summary file" in lines[0]
    assert not out.exists()
