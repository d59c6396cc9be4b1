"""How large a slowed gate's mark on the level is, against the envelope model's own mismatch.

The diagnosis suite's ``slowed_gate`` (:data:`gatetwin.diagnosis.onset.ONSET_EFFECTS`: the gate
follows its commands at 0.1 mm/s) changes the level only while the gate lags its command:
after a move of ``dE`` mm, for ``dE / 0.1`` s. Its mark is the difference of two simulations
of the truth plant (``models/fopdt_3F.json``, as ``benchmarks/bench_observer.py``) added to
the record. For each flume base (the five bundled records with moves) this prints

* the moves after the onset (first gate move after 40 % of the record) and the largest;
* the mark: its largest size (mm) and how long it stays above the gauge's noise SD;
* the envelope observer's innovation on the clean record over the same span: its RMS and its
  largest size (mm), i.e. the model's mismatch plus noise there;
* the ratio of the mark's peak to that RMS, and the innovation's change the mark makes
  (largest |innovation with the effect - innovation without|, mm);
* the observer's disturbance estimate (mm of opening): the largest change the mark makes to
  it, and its own range on the clean record over the same span.

usage: PYTHONPATH=src python benchmarks/slowed_gate.py
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from gatetwin.bundled import bundled_records_dir
from gatetwin.diagnosis.onset import ONSET_EFFECTS, first_move_after, with_onset
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.online import MONITORING, OnlineObserver, measured_inputs
from gatetwin.records import read_record

ROOT = Path(__file__).resolve().parents[1]
BASES = ("C", "D", "Emoves35", "Emoves75", "Erandom60")


def main() -> None:
    warnings.simplefilter("ignore")
    truth = dataclasses.replace(read_model_file(ROOT / "models/fopdt_3F.json").plant, effects=())
    physical = dataclasses.replace(read_model_file(ROOT / "models/physical_3F.json").plant,
                                   effects=())  # fmt: skip
    noise = MONITORING.measurement_sd_mm
    rate = ONSET_EFFECTS["slowed_gate"]["rate_mm_per_s"]
    print(f"slowed gate at {rate} mm/s; truth fopdt_3F; envelope observer of physical_3F; "
          f"gauge noise SD {noise} mm (the observer's)")  # fmt: skip
    print(
        "| base | moves after onset | largest move (mm) | mark peak (mm) | mark > noise SD (s) "
        "| innovation RMS / max, clean (mm) | peak / RMS | largest innovation change (mm) "
        "| largest disturbance change / clean range (mm of opening) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name in BASES:
        record = read_record(bundled_records_dir() / f"{name}.csv")
        t = np.asarray(record.time_s, dtype=float)
        y, e, q = measured_inputs(record, "3F")
        onset = first_move_after(t, e)
        moves = np.abs(np.diff(e[onset - 1 :]))
        moves = moves[moves > 0.0]
        mark = with_onset(truth, t, y, e, q, "slowed_gate", onset) - y
        above = float(np.sum(np.abs(mark) > noise) * (t[1] - t[0]))
        clean_out = OnlineObserver(physical).run(y, e, q)
        hit_out = OnlineObserver(physical).run(y + mark, e, q)
        clean, hit = clean_out["innovation_mm"][onset:], hit_out["innovation_mm"][onset:]
        d_clean = clean_out["disturbance_mm"][onset:]
        d_change = np.abs(hit_out["disturbance_mm"][onset:] - d_clean).max()
        rms = float(np.sqrt(np.mean(clean**2)))
        peak = float(np.abs(mark).max())
        print(f"| {name} | {moves.size} | {moves.max():.1f} | {peak:.2f} | {above:.0f} | "
              f"{rms:.2f} / {np.abs(clean).max():.2f} | {peak / rms:.2f} | "
              f"{np.abs(hit - clean).max():.2f} | {d_change:.2f} / "
              f"{np.ptp(d_clean):.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
