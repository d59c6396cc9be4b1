"""The MPC on plants with effect blocks: augmented against blind, side by side.

For every block of tests/mpc/test_mpc_effects.py (and the input blocks), the same noise-free
closed loop (15 min: a 15 mm set-point step at 60 s, Q 40 → 50 m³/h at 400 s) runs on
the augmented plant twice: under the MPC built from the augmented model and under the MPC
built from the plant without the block. Prints the largest error of the water level over
the last minute, IAE, the largest command move and the command's rate violations, so
that what each block is worth to a controller reads off one table. Nothing is asserted.

usage: python benchmarks/bench_mpc_effects.py
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

# the blocks and the loop of the MPC's effect tests (tests/mpc/), which import the tests'
# shared modules (tests/)
TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(TESTS / "mpc"), str(TESTS)]

from gatetwin.mpc import loop_metrics  # noqa: E402
from gatetwin.plant.effects import effect_dict  # noqa: E402
from test_mpc_effects import LINEAR, _closed_loop  # noqa: E402
from test_mpc_model import fopdt  # noqa: E402

INPUT_BLOCKS = {
    "actuator_rate_limit": [effect_dict("actuator_rate_limit", rate_mm_per_s=0.2)],
    "actuator_backlash": [effect_dict("actuator_backlash", deadband_mm=2.0)],
    "opening_nonlinearity": [effect_dict("opening_nonlinearity", gain_slope_per_mm=-0.03)],
}


def main() -> None:
    print(f"{'plant':22s} {'MPC':10s} {'tail max|e| mm':>14s} {'IAE mm·s':>9s} "
          f"{'max move mm':>11s} {'rate viol.':>10s} {'run s':>6s}")  # fmt: skip
    for name, effects in {**LINEAR, **INPUT_BLOCKS}.items():
        plant = replace(fopdt(), effects=tuple(effects))
        for label, model in (("augmented", plant), ("blind", fopdt())):
            start = time.perf_counter()
            run, _, _ = _closed_loop(model, plant)
            elapsed = time.perf_counter() - start
            m = loop_metrics(run)
            tail = np.max(np.abs(run.level_mm[-50:] - run.setpoint_mm[-50:]))
            moves = np.abs(np.diff(np.concatenate([[run.scenario.opening_mm], run.command_mm])))
            print(f"{name:22s} {label:10s} {tail:14.2e} {m['iae']:9.0f} {moves.max():11.3f} "
                  f"{m['violations_by_kind']['opening_rate']:10d} {elapsed:6.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
