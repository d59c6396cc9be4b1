"""The noise floor against the truth: each bundled record's floor fit next to the fit the
flume's noise-free level scores (what a perfect model reaches), per gauge.

    python benchmarks/bench_noise_floor.py

Prints, per record and gauge, floor − truth in fit points for the floor as
:func:`gatetwin.noise.record_noise_floor` computes it (corrected for correlated noise) and for
the plain pool ``r'r / (m - 3)`` it corrects, then the mean and range of both, over all cells
and over the PRBS records C and D (short holds).
"""

from __future__ import annotations

import numpy as np

from gatetwin.bundled import bundled_records_dir
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.experiments import reference_scenarios
from gatetwin.flume.simulate import run_flume, spin_up
from gatetwin.noise import hold_openings, plain_pooled_sd, record_noise_floor, steady_stretches
from gatetwin.records import read_record
from gatetwin.validation import free_run_metrics, noise_floor_fit_percent

GAUGES = ("1D", "2E", "3F", "4G", "5H")


def main() -> None:
    cfg = FlumeConfig()
    rows = []
    print("| record | " + " | ".join(f"{g} truth / corrected / plain" for g in GAUGES) + " |")
    print("|---" * (len(GAUGES) + 1) + "|")
    for scn in reference_scenarios():
        cmd, flow = scn.sampled(cfg.sample_period_s)
        run = run_flume(cfg, cmd, flow, state=spin_up(cfg, flow[0], cmd[0]))
        rec = read_record(bundled_records_dir() / f"{scn.name}.csv")
        hold = np.asarray(rec.hold, bool)
        stretches = steady_stretches(rec.time_s, hold, hold_openings(rec), rec.flow_m3h,
                                     rec.sample_period_s)  # fmt: skip
        cells = []
        for g in GAUGES:
            y = np.asarray(rec.levels_mm[g], float)
            truth = free_run_metrics(y, run.depth_mm[g] + cfg.gauge_datum_mm.get(g, 0.0))
            floor = noise_floor_fit_percent(record_noise_floor(rec, g).sigma_mm, y)[0]
            plain = noise_floor_fit_percent(plain_pooled_sd(rec.time_s, y, stretches), y)[0]
            rows.append((scn.name, floor - truth.fit_percent, plain - truth.fit_percent))
            cells.append(f"{truth.fit_percent:.1f} / {floor - truth.fit_percent:+.1f} / "
                         f"{plain - truth.fit_percent:+.1f}")  # fmt: skip
        print(f"| {scn.name} | " + " | ".join(cells) + " |")
    print("\n(floor − truth, fit points)")
    for label, keep in (("all cells", lambda n: True), ("C and D", lambda n: n in ("C", "D"))):
        err = np.array([(c, p) for n, c, p in rows if keep(n)])
        for i, name in enumerate(("corrected", "plain")):
            print(
                f"{label:9s} {name:9s}: mean {np.mean(err[:, i]):+.2f}, "
                f"range {np.min(err[:, i]):+.1f} .. {np.max(err[:, i]):+.1f}, "
                f"mean |error| {np.mean(np.abs(err[:, i])):.2f} ({err.shape[0]} cells)"
            )


if __name__ == "__main__":
    main()
