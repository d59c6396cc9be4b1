"""The scripts in examples/ run as a user runs them: in an empty folder, warnings as errors,
and write what they say they write."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from gatetwin import read_record

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
#: Longest a script may reasonably take on a loaded machine (the slowest runs ~10 s).
TIMEOUT_S = 300


def run_example(name: str, folder: Path) -> str:
    env = {
        **os.environ,
        "MPLBACKEND": "Agg",
        "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run([sys.executable, "-W", "error", str(EXAMPLES / name)], cwd=folder,
                          env=env, capture_output=True, text=True, timeout=TIMEOUT_S)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_every_example_is_short():
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert len(scripts) >= 3
    for name in scripts:
        lines = [ln for ln in (EXAMPLES / name).read_text().splitlines() if ln.strip()]
        assert len(lines) <= 22, f"{name}: {len(lines)} lines; an example stays short"


def test_identify_export_validate(tmp_path):
    out = run_example("identify_export_validate.py", tmp_path)
    assert {"fopdt_3F.json", "fopdt_3F.fmu", "validation.png"} <= {
        p.name for p in tmp_path.iterdir()
    }
    assert re.search(r"\| fopdt_3F\.fmu \| A\.csv \| 3F \|.*\| pass \|", out)


def test_diagnose_record(tmp_path):
    out = run_example("diagnose_record.py", tmp_path)
    named = re.search(r"missing effect '(\w+)'", out)
    assert named, out
    assert re.search(rf"^  {named.group(1)} +score", out, re.MULTILINE) or named.group(1) == "none"
    assert (tmp_path / "Emoves35_3F_diagnosis.png").stat().st_size > 0


def test_flume_scenario(tmp_path):
    out = run_example("flume_scenario.py", tmp_path)
    record = read_record(tmp_path / "my_step.csv")
    assert record.test == "step" and len(record.steps) == 1
    assert (tmp_path / "my_step.png").stat().st_size > 0
    rmse = float(re.search(r"free-run RMSE against the flume: ([\d.]+) mm", out).group(1))
    # the flume's gauge noise at 3F is ~1-2.5 mm SD (README, The virtual flume): a twin of
    # the same record cannot sit much below it, nor, if it is any good, far above it
    assert rmse < 5.0


def test_mpc_on_fmu(tmp_path):
    out = run_example("mpc_on_fmu.py", tmp_path)
    found = re.search(r"set-point ([\d.]+) mm, level ([\d.]+) mm, opening ([\d.]+) mm", out)
    setpoint, level, opening = (float(v) for v in found.groups())
    # 250 samples (300 s, > 4 time constants of B's ~43 s) after the change, on a noise-free
    # twin: the offset-free MPC sits on its set-point within the gauge's 0.1 mm resolution
    assert abs(level - setpoint) < 0.1
    assert 30.0 < opening < 40.0  # a lower level needs a wider gate than B's 30 mm start
