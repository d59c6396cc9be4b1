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
  0.02 and 0.05 mm/s from the onset on (:func:`gatetwin.diagnosis.onset.with_onset`), after
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

from bench_observer import BASES
from calibrate_observer import GAUGE, MARGIN, ROOT, _held, scenarios
from gatetwin.bundled import bundled_records_dir
from gatetwin.diagnosis.onset import first_move_after, with_onset
from gatetwin.flume.experiments import run_scenario
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.gauge_drift import (
    THRESHOLD_MM_PER_S,
    WINDOW_SAMPLES,
    GaugeDriftMonitor,
    gauge_difference,
    slope_weights,
)
from gatetwin.mpc.online import OnlineObserver, measured_inputs
from gatetwin.records import read_record

RATES_MM_PER_S = (0.01, 0.02, 0.05)


def largest_slope(series: np.ndarray, window: int, start: int = 0) -> float:
    """Largest |least-squares slope| (mm/s) of ``series`` over windows of ``window`` samples
    that end at or after ``start``."""
    segments = np.lib.stride_tricks.sliding_window_view(series, window)
    slopes = segments @ slope_weights(window, SAMPLE_PERIOD_S)
    first = max(0, start - window + 1)
    return float(np.max(np.abs(slopes[first:]))) if slopes[first:].size else 0.0


def _others(levels: dict[str, np.ndarray]) -> list[np.ndarray]:
    return [np.asarray(v, dtype=float) for g, v in levels.items() if g != GAUGE]


def _table(title: str, series: dict[str, list], windows: list[int]) -> list[float]:
    """Print one table; return the calibration records' largest slope per window."""
    print(f"\n{title}: largest |slope|, mm/s, over a window of")
    print(f"| records | {' | '.join(f'{w * SAMPLE_PERIOD_S:.0f} s' for w in windows)} |")
    print("|---" * (1 + len(windows)) + "|")
    cal = [max(largest_slope(d, w) for d in series["calibration"]) for w in windows]
    print(f"| calibration, clean | {' | '.join(f'{c:.4f}' for c in cal)} |")
    bundled = [max(largest_slope(d, w) for d in series["bundled"]) for w in windows]
    print(f"| bundled, clean | {' | '.join(f'{c:.4f}' for c in bundled)} |")
    for (base, rate), (d, onset) in series["drifted"]:
        cells = []
        for w, limit in zip(windows, cal, strict=True):
            s = largest_slope(d, w, start=onset)
            cells.append(f"{s:.4f}{' *' if s > limit else ''}")
        print(f"| {base}, drift {rate:g} mm/s | {' | '.join(cells)} |")
    return cal


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--windows", type=int, nargs="+", default=[150, 250, 400, 600])
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # discharges beyond the schedule's knots: clamped
    plant = dataclasses.replace(read_model_file(ROOT / "models/physical_3F.json").plant,
                                effects=())  # fmt: skip
    truth = read_model_file(ROOT / "models/fopdt_3F.json").plant
    observed = {"calibration": [], "bundled": [], "drifted": []}
    redundant = {"calibration": [], "bundled": [], "drifted": []}
    for scn in scenarios():
        rec = run_scenario(scn)
        y = rec.levels_mm[GAUGE]
        out = OnlineObserver(plant).run(y, _held(rec.opening_mm), rec.flow_m3h)
        observed["calibration"].append(out["disturbance_mm"])
        redundant["calibration"].append(gauge_difference(y, _others(rec.levels_mm)))
    for path in sorted(bundled_records_dir().glob("*.csv")):
        if path.stem == "static":
            continue
        record = read_record(path)
        t = np.asarray(record.time_s, dtype=float)
        y, e, q = measured_inputs(record, GAUGE)
        others = _others(record.levels_mm)
        observed["bundled"].append(OnlineObserver(plant).run(y, e, q)["disturbance_mm"])
        redundant["bundled"].append(gauge_difference(y, others))
        if path.stem not in BASES:
            continue
        onset = first_move_after(t, e)
        for rate in RATES_MM_PER_S:
            level = with_onset(truth, t, y, e, q, "sensor_drift", onset, rate_mm_per_s=rate)
            key = (path.stem, rate)
            observed["drifted"].append(
                (key, (OnlineObserver(plant).run(level, e, q)["disturbance_mm"], onset))
            )
            redundant["drifted"].append((key, (gauge_difference(level, others), onset)))
    _table("1. the envelope observer's disturbance estimate (physical_3F, effects dropped), "
           "gauge 3F", observed, args.windows)  # fmt: skip
    cal = _table(f"2. gauge {GAUGE} minus the mean of the pool's other gauges", redundant,
                 args.windows)  # fmt: skip
    print("\n* above the calibration records' largest: a slope rule could flag it there")
    print("called for (1.25 x the calibration records' largest), gauge difference: "
          + ", ".join(f"{MARGIN * c:.4f} mm/s over {w * SAMPLE_PERIOD_S:.0f} s"
                      for w, c in zip(args.windows, cal, strict=True)))  # fmt: skip
    print(f"gatetwin.mpc.gauge_drift: {THRESHOLD_MM_PER_S} mm/s over "
          f"{WINDOW_SAMPLES * SAMPLE_PERIOD_S:.0f} s")  # fmt: skip
    _rule_table(redundant)


def _rule_table(redundant: dict[str, list]) -> None:
    """The rule of gatetwin.mpc.gauge_drift as shipped (:class:`GaugeDriftMonitor`): rises on
    the clean records, delay from the onset to the flag on the drifted bases."""

    def flag(d: np.ndarray) -> np.ndarray:
        # d is already the difference: the monitor on d against a zero "other gauge"
        return GaugeDriftMonitor().run(d, [np.zeros_like(d)])["gauge_drift"] > 0.5

    def count(d: np.ndarray) -> int:
        return int(np.sum(np.diff(np.r_[False, flag(d)].astype(int)) > 0))

    rises = {kind: sum(count(d) for d in redundant[kind]) for kind in ("calibration", "bundled")}
    print(f"\n3. the shipped rule: rises on clean records: calibration {rises['calibration']}, "
          f"bundled {rises['bundled']}; delay from the onset to the flag, s:")  # fmt: skip
    cells = []
    for (base, rate), (d, onset) in redundant["drifted"]:
        up = np.flatnonzero(flag(d)[onset:])
        cells.append(f"{base} {rate:g} mm/s: {up[0] * SAMPLE_PERIOD_S:.0f}" if up.size
                     else f"{base} {rate:g} mm/s: -")  # fmt: skip
    print("   " + "; ".join(cells))


if __name__ == "__main__":
    main()
