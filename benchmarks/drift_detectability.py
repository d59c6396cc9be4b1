"""How small a gauge drift the envelope observer's disturbance estimate can tell from clean
operation: the slope of the estimate, against what clean records give.

A drifting gauge reads as a disturbance that grows at the drift's rate; the model's own
mismatch moves the same estimate after every gate move or discharge change. This script
fits a straight line to the envelope observer's ``disturbance_mm`` over a sliding window of
``W`` samples and takes the largest |slope| (mm/s):

* on the clean calibration records of ``benchmarks/calibrate_observer.py`` (seeds 901-909,
  not bundled): what a rule on the slope would have to tolerate;
* on the 15 clean bundled records;
* on the five bundled bases of ``benchmarks/bench_observer.py`` with a gauge drift of 0.01,
  0.02 and 0.05 mm/s from the onset on (:func:`gatetwin.diagnose.onset.with_onset`), after
  the onset.

A slope rule sees a drift only where the drifted record's slope exceeds the clean ones'
largest. Measures; asserts nothing.

    PYTHONPATH=src python benchmarks/drift_detectability.py [--windows 150 250 400 600]
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import numpy as np

from bench_observer import BASES, _records
from calibrate_observer import GAUGE, ROOT, _held, scenarios
from gatetwin.diagnose.onset import first_move_after, with_onset
from gatetwin.flume.experiments import run_scenario
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.online import OnlineObserver

RATES_MM_PER_S = (0.01, 0.02, 0.05)


def largest_slope(disturbance_mm: np.ndarray, window: int, start: int = 0) -> float:
    """Largest |least-squares slope| (mm/s) of ``disturbance_mm`` over windows of ``window``
    samples that end at or after ``start``."""
    x = np.arange(window) * SAMPLE_PERIOD_S
    x -= x.mean()
    segments = np.lib.stride_tricks.sliding_window_view(disturbance_mm, window)
    slopes = (segments - segments.mean(axis=1, keepdims=True)) @ x / (x @ x)
    first = max(0, start - window + 1)
    return float(np.max(np.abs(slopes[first:]))) if slopes[first:].size else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--windows", type=int, nargs="+", default=[150, 250, 400, 600])
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # discharges beyond the schedule's knots: clamped
    plant = dataclasses.replace(read_model_file(ROOT / "models/physical_3F.json").plant,
                                effects=())  # fmt: skip
    truth = read_model_file(ROOT / "models/fopdt_3F.json").plant
    clean_cal, clean_bundled, drifted = [], [], {}
    for scn in scenarios():
        rec = run_scenario(scn)
        out = OnlineObserver(plant).run(rec.levels_mm[GAUGE], _held(rec.opening_mm),
                                        rec.flow_m3h)  # fmt: skip
        clean_cal.append(out["disturbance_mm"])
    for name, (t, y, e, q, _) in _records().items():
        clean_bundled.append(OnlineObserver(plant).run(y, e, q)["disturbance_mm"])
        if name in BASES:
            onset = first_move_after(t, e)
            for rate in RATES_MM_PER_S:
                level = with_onset(truth, t, y, e, q, "sensor_drift", onset,
                                   rate_mm_per_s=rate)  # fmt: skip
                drifted[(name, rate)] = (OnlineObserver(plant).run(level, e, q)["disturbance_mm"],
                                         onset)  # fmt: skip
    print("envelope observer of physical_3F (effects dropped), gauge 3F: largest |slope| of the "
          "disturbance estimate, mm/s, over a window of")  # fmt: skip
    windows = args.windows
    print(f"| records | {' | '.join(f'{w * SAMPLE_PERIOD_S:.0f} s' for w in windows)} |")
    print("|---" * (1 + len(windows)) + "|")
    cal = [max(largest_slope(d, w) for d in clean_cal) for w in windows]
    print(f"| calibration, clean | {' | '.join(f'{c:.4f}' for c in cal)} |")
    bundled = [max(largest_slope(d, w) for d in clean_bundled) for w in windows]
    print(f"| bundled, clean | {' | '.join(f'{c:.4f}' for c in bundled)} |")
    for (base, rate), (d, onset) in drifted.items():
        cells = []
        for w, limit in zip(windows, cal, strict=True):
            s = largest_slope(d, w, start=onset)
            cells.append(f"{s:.4f}{' *' if s > limit else ''}")
        print(f"| {base}, drift {rate:g} mm/s | {' | '.join(cells)} |")
    print("\n* above the calibration records' largest: a slope rule could flag it there")


if __name__ == "__main__":
    main()
