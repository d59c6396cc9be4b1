"""The FMI cross-check package: an importer following its README reproduces the reference."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from fmu_support import compiler  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / "models"


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open() as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


@pytest.mark.parametrize("name", ["fopdt_3F", "physical_3F", "arx_3F"])
def test_an_importer_reproduces_the_reference_from_the_package(tmp_path, name):
    if compiler() is None:
        pytest.skip("no C compiler on this machine")
    done = subprocess.run(
        [sys.executable, "-m", "gatetwin", "export", str(MODELS / f"{name}.json"),
         "--backend", "c", "--out", str(tmp_path / "m.fmu"), "--cross-check",
         str(tmp_path / "xc")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "xc" / name
    opt = dict(line.split(", ") for line in (folder / f"{name}_ref.opt").read_text().splitlines())
    header, inputs = _read(folder / f"{name}_in.csv")
    ref_header, ref = _read(folder / f"{name}_ref.csv")
    signals = np.zeros(len(inputs), dtype=[(h, float) for h in header])
    for i, h in enumerate(header):
        signals[h] = inputs[:, i]
    result = simulate_fmu(
        str(folder / f"{name}.fmu"), start_time=float(opt["StartTime"]),
        stop_time=float(opt["StopTime"]), output_interval=float(opt["StepSize"]),
        input=signals, output=[ref_header[1]], validate=False,
    )  # fmt: skip
    # fmpy holds each input over the step that starts at its time, as the reference does
    got = np.interp(ref[:, 0], result["time"], result[ref_header[1]])
    assert np.max(np.abs(got - ref[:, 1]) / np.abs(ref[:, 1])) <= float(opt["RelTol"])
