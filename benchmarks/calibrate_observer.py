"""Thresholds of the envelope observer's anomaly rules, from clean records that are not bundled.

Runs the virtual flume (:mod:`gatetwin.flume`) over clean scenarios with seeds and operating
points of its own (random gate moves at five discharges, gate moves and discharge changes
together, discharge steps with the gate fixed; none of the bundled records' seeds 101-116),
and the envelope observer of ``models/physical_3F.json`` (effects dropped) over each record at
gauge 3F. Prints per record the longest run outside the band, the largest persistent CUSUM and
the largest slow CUSUM, then the thresholds they call for: 1.25 times the largest over all
records (a quarter above what clean operation reached). The bundled clean records are then the
independent check (``benchmarks/bench_observer.py``).

    PYTHONPATH=src python benchmarks/calibrate_observer.py
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings
from pathlib import Path

import numpy as np

from gatetwin.flume.envelope import both_scenario, flow_steps_scenario, random_moves_scenario
from gatetwin.flume.experiments import run_scenario
from gatetwin.flume.scenario import Scenario
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.online import ENVELOPE_ANOMALY, OnlineObserver

ROOT = Path(__file__).resolve().parents[1]
GAUGE = "3F"
#: A quarter above the largest value clean records reached.
MARGIN = 1.25


def scenarios() -> list[Scenario]:
    """The calibration set: 3.4 h of clean flume records, seeds 901-909."""
    out = [random_moves_scenario(f"cal_random{q:g}", q, 900 + k, n_moves=10)
           for k, q in enumerate((35.0, 45.0, 55.0, 65.0, 75.0), start=1)]  # fmt: skip
    out += [dataclasses.replace(both_scenario(f"cal_both{s}", s), seed=s) for s in (906, 907)]
    out += [flow_steps_scenario("cal_flow30", 30.0, [45.0, 60.0, 40.0], 300.0, 908),
            flow_steps_scenario("cal_flow50", 50.0, [60.0, 80.0, 65.0], 300.0, 909)]  # fmt: skip
    return out


def main() -> None:
    warnings.simplefilter("ignore")  # discharges beyond the schedule's knots: clamped
    plant = dataclasses.replace(read_model_file(ROOT / "models/physical_3F.json").plant,
                                effects=())  # fmt: skip
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--move-uncertainty", type=float,
                        default=ENVELOPE_ANOMALY.move_uncertainty)  # fmt: skip
    args = parser.parse_args()
    settings = dataclasses.replace(ENVELOPE_ANOMALY, move_uncertainty=args.move_uncertainty)
    print(f"envelope observer of physical_3F (effects dropped), gauge {GAUGE}, {settings}")
    print("| record | s | flag rises | longest run | CUSUM | slow CUSUM |")
    print("|---|---|---|---|---|---|")
    worst = np.zeros(3)
    hours, start = 0.0, time.perf_counter()
    for scn in scenarios():
        rec = run_scenario(scn)
        y, q = rec.levels_mm[GAUGE], rec.flow_m3h
        e = _held(rec.opening_mm)
        out = OnlineObserver(plant, anomaly=settings).run(y, e, q)
        rises = int(np.sum(np.diff(np.r_[0.0, out["anomaly"]]) > 0.5))
        row = np.array([out["anomaly_samples"].max(),
                        max(out["cusum_high"].max(), out["cusum_low"].max()),
                        out["slow_cusum"].max()])  # fmt: skip
        worst = np.maximum(worst, row)
        span = rec.time_s[-1] - rec.time_s[0]
        hours += span / 3600.0
        print(f"| {scn.name} | {span:.0f} | {rises} | {row[0]:.0f} | {row[1]:.1f} | "
              f"{row[2]:.1f} |")  # fmt: skip
    print(f"\n{hours:.2f} h of clean flume records in {time.perf_counter() - start:.0f} s")
    print(f"largest: run {worst[0]:.0f} (flag at {settings.run_samples}), CUSUM {worst[1]:.1f} "
          f"(threshold {settings.cusum_threshold:g}), slow CUSUM {worst[2]:.1f} (threshold "
          f"{settings.slow_threshold:g})")  # fmt: skip
    print(f"called for: CUSUM threshold {MARGIN * worst[1]:.1f}, slow threshold "
          f"{MARGIN * worst[2]:.1f}")  # fmt: skip


def _held(opening_mm: np.ndarray) -> np.ndarray:
    """The logged opening with the samples of a moving gate given the next known opening."""
    e = np.asarray(opening_mm, dtype=float)
    known = np.flatnonzero(np.isfinite(e))
    after = np.searchsorted(known, np.arange(e.size))
    return e[known[np.minimum(after, known.size - 1)]]


if __name__ == "__main__":
    main()
