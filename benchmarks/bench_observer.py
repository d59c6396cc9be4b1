"""The observer FMU beside the gate: detection delays of hidden effects, false alarms, speed.

Builds the observer FMU of ``models/fopdt_3F.json`` (its FOPDT alone, effect blocks dropped;
the default horizon, noise levels and anomaly settings) and runs it through fmpy over

* every bundled record as logged (clean: any rise of the anomaly flag is a false alarm);
* five bundled records with moves (C, D, Emoves35, Emoves75, Erandom60) with each effect of
  :data:`gatetwin.diagnosis.onset.ONSET_EFFECTS` switched on at the first gate move after 40 %
  of the record ("flume": the record keeps its own noise and model mismatch);
* the same five input series with the level simulated by the observer's own model plus white
  noise of the observer's measurement SD, then the same effects ("model": a record the model
  explains, so the innovation's statistics are the filter's own);
* row ``flume_inflow``: the five flume bases run again through the virtual flume (same
  scenario, same seed) with 5 m³/h more inflow from the onset on than the logged discharge
  (the flume's own physics instead of the truth plant's response; "overtops" where the
  scenario with it would overtop the flume).

Then the envelope observer FMU of ``models/physical_3F.json`` (``gatetwin export-observer``
on a physical model: re-linearised at every sample, with the slow rule; thresholds calibrated
on flume records that are not bundled by ``benchmarks/calibrate_observer.py``) over the same
clean records and flume bases, its largest difference from the Python envelope observer on
record C, and the time each takes there.

Last, the envelope observer FMU with the pool's other gauges as references (``gatetwin
export-observer ... --reference-gauges 1D 2E 4G 5H``: the gauge-drift rule of
:mod:`gatetwin.mpc.gauge_drift` in C, ``anomaly_kind`` 4 where it alone holds) over the same
clean records and bases. An effect of the pool (all but ``sensor_drift``) changes every
gauge's level alike, so each reference gauge gets the change it makes at 3F; the drift is the
gauge's own; ``flume_inflow`` is the flume's every gauge with the inflow.

Prints the rises of the flag on the clean records (with the largest run outside the band and
the largest CUSUM, against the thresholds), the detection delay (s from the onset to the
flag, the rule that raised it: f fast, p persistent, s slow, d gauge drift; "-" never within
the record) per effect
and base, the false alarms, and the time the FMU and the Python observer take per record
(ratio measured in this run). ``--band``, ``--run-samples``, ``--cusum-slack`` and
``--cusum-threshold`` override the defaults. ``--timing-only`` runs only the times over
record C (each observer ``--repeats`` times, the median kept); ``--save`` keeps them in
``docs/results/observer.json`` for the observer page.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.bundled import bundled_records_dir
from gatetwin.diagnosis.onset import ONSET_EFFECTS, detection, first_move_after, with_onset
from gatetwin.errors import FlumeError
from gatetwin.flume.experiments import reference_scenarios, run_scenario
from gatetwin.flume.scenario import with_inflow
from gatetwin.fmu.observer_fmu import export_observer, run_observer_fmu
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.gauge_drift import DRIFT_KIND
from gatetwin.mpc.observer_codegen import LIMITS
from gatetwin.mpc.online import (
    ENVELOPE_ANOMALY,
    MONITORING,
    AnomalySettings,
    OnlineObserver,
    measured_inputs,
)
from gatetwin.plant.simulate import simulate
from gatetwin.records import read_record

ROOT = Path(__file__).resolve().parents[1]
BASES = ("C", "D", "Emoves35", "Emoves75", "Erandom60")
#: The pool's other gauges, references of the gauge-drift rule.
REFERENCES = ("1D", "2E", "4G", "5H")
SEED = 20


def _records() -> dict[str, tuple[np.ndarray, ...]]:
    out = {}
    for path in sorted(bundled_records_dir().glob("*.csv")):
        if path.stem != "static":
            record = read_record(path)
            out[path.stem] = (record.time_s, *measured_inputs(record, "3F"),
                              record.metadata.get("role", ""))  # fmt: skip
            _REFERENCE_LEVELS[path.stem] = {g: measured_inputs(record, g)[0] for g in REFERENCES}
    return out


#: Each bundled record's levels at the reference gauges (filled by :func:`_records`).
_REFERENCE_LEVELS: dict[str, dict[str, np.ndarray]] = {}


def _flume_inflow(bases: dict, gauges: tuple[str, ...] = ("3F",)) -> dict[str, Any]:
    """Each base's level at 3F when the flume itself gets 5 m³/h more from the onset on
    (the bundled scenario run again with the same seed; the logged discharge is the base's);
    with more ``gauges``, a dict of each's level."""
    scenarios = {s.name: s for s in reference_scenarios()}
    out = {}
    for name, (t, _, e, _) in bases.items():
        onset = first_move_after(t, e)
        scn = with_inflow(scenarios[name], (onset - 0.5) * SAMPLE_PERIOD_S,
                          ONSET_EFFECTS["unmeasured_inflow"]["flow_m3h"])  # fmt: skip
        try:
            levels = run_scenario(scn).levels_mm
            out[name] = (levels["3F"] if gauges == ("3F",)
                         else {g: np.asarray(levels[g], dtype=float) for g in gauges})  # fmt: skip
        except FlumeError:  # the inflow would overtop the flume: no such record
            out[name] = None
    return out


def _delays(run, plant, bases: dict, physical: dict | None = None) -> dict[str, list[str]]:
    """``run(level, opening, flow)`` gives the observer's outputs; ``physical``, each base's
    level with the flume's own unseen inflow (row ``flume_inflow``). ``run`` is also told the
    base and the effect (``name=``, ``effect=``), which the references' run needs."""
    table: dict[str, list[str]] = {}
    effects = [*ONSET_EFFECTS, *(["flume_inflow"] if physical else [])]
    for name, (t, y, e, q) in bases.items():
        onset = first_move_after(t, e)
        for effect in effects:
            if effect == "flume_inflow":
                level = physical[name]
                if level is None:
                    table.setdefault(effect, []).append("overtops")
                    continue
            else:
                level = with_onset(plant, t, y, e, q, effect, onset)
            out = run(level, e, q, name=name, effect=effect)
            found = detection(t, out["anomaly"], onset)
            cell = "-"
            if not np.isnan(found.delay_s):
                at = onset + int(np.flatnonzero(out["anomaly"][onset:] > 0.5)[0])
                cell = f"{found.delay_s:.1f} {'fpsd'[int(out['anomaly_kind'][at]) - 1]}"
            if found.false_alarms:
                cell += f" ({found.false_alarms} FA)"
            table.setdefault(effect, []).append(cell)
    return table


def _print_table(title: str, table: dict[str, list[str]]) -> None:
    print(f"\n{title}: detection delay, s")
    print(f"| effect | {' | '.join(BASES)} |")
    print("|---" * (len(BASES) + 1) + "|")
    for effect, cells in table.items():
        print(f"| {effect} | {' | '.join(cells)} |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--band", type=float, default=AnomalySettings().band_sigma)
    parser.add_argument("--run-samples", type=int, default=AnomalySettings().run_samples)
    parser.add_argument("--cusum-slack", type=float,
                        default=AnomalySettings().cusum_slack_sigma)  # fmt: skip
    parser.add_argument("--cusum-threshold", type=float,
                        default=AnomalySettings().cusum_threshold)  # fmt: skip
    parser.add_argument("--repeats", type=int, default=3,
                        help="runs over record C per observer for the times (median)")  # fmt: skip
    parser.add_argument("--timing-only", action="store_true",
                        help="only the times over record C, no delays or false alarms")  # fmt: skip
    parser.add_argument("--save", action="store_true",
                        help="keep the times in docs/results/observer.json")  # fmt: skip
    args = parser.parse_args(argv)
    settings = AnomalySettings(args.band, args.run_samples, args.cusum_slack,
                               args.cusum_threshold)  # fmt: skip
    warnings.simplefilter("ignore")  # the flume records pass the schedule's discharge range
    plant = dataclasses.replace(read_model_file(ROOT / "models/fopdt_3F.json").plant, effects=())
    records = _records()
    if not args.timing_only:
        _delays_and_false_alarms(records, plant, settings, args)
    data = _times_on_record_c(records["C"], plant, settings, args.repeats)
    print("\n" + report(data))
    if args.save:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from results import save

        print(save("observer", data, "python benchmarks/bench_observer.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


def _median_time(func, repeats: int) -> tuple[float, Any]:
    """Median wall time of ``repeats`` calls, s, and the last result."""
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = func()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def _times_on_record_c(record: tuple, plant, settings: AnomalySettings, repeats: int) -> dict:
    """The schedule's and the envelope's observer over record C: FMU via fmpy and Python."""
    t, y, e, q, _ = record
    params = {f"anomaly_{n}": v for n, v in zip(LIMITS, settings.limits(), strict=True)}
    with tempfile.TemporaryDirectory() as tmp:
        fmu = export_observer(plant, Path(tmp) / "observer.fmu")
        env_fmu = export_observer(_physical(), Path(tmp) / "envelope.fmu")
        fmu_s, _ = _median_time(lambda: run_observer_fmu(fmu, y, e, q, params), repeats)
        env_fmu_s, got = _median_time(lambda: run_observer_fmu(env_fmu, y, e, q), repeats)
    py_s, _ = _median_time(lambda: OnlineObserver(plant, anomaly=settings).run(y, e, q), repeats)
    env_s, ref = _median_time(lambda: OnlineObserver(_physical()).run(y, e, q), repeats)
    worst = max(float(np.max(np.abs(got[k] - ref[k]))) for k in got)
    return {"samples": int(t.size), "repeats": repeats, "schedule_fmu_s": fmu_s,
            "schedule_python_s": py_s, "envelope_fmu_s": env_fmu_s, "envelope_python_s": env_s,
            "envelope_largest_output_difference": worst}  # fmt: skip


def report(data: dict) -> str:
    """The times over record C as Markdown (printed, and the observer page's block)."""
    sched, env = data["schedule_python_s"], data["envelope_python_s"]
    rows = [("schedule observer FMU, through fmpy", data["schedule_fmu_s"], ""),
            ("schedule observer, Python (`OnlineObserver`)", sched,
             f"{sched / data['schedule_fmu_s']:.1f}× its FMU"),
            ("envelope observer FMU, through fmpy", data["envelope_fmu_s"], ""),
            ("envelope observer, Python (two filters and a tangent a sample)", env,
             f"{env / data['envelope_fmu_s']:.1f}× its FMU, {env / sched:.1f}× the schedule's"
             " Python observer")]  # fmt: skip
    lines = [f"| over record C ({data['samples']} samples) | s | |", "|---|---|---|"]
    lines += [f"| {label} | {seconds:.3f} | {note} |" for label, seconds, note in rows]
    return "\n".join(lines) + (
        f"\n\nMedian of {data['repeats']} runs each, in one process; the envelope FMU's "
        f"outputs differ from the Python envelope observer's by at most "
        f"{data['envelope_largest_output_difference']:.1e}.\n"
    )


def _delays_and_false_alarms(records: dict, plant, settings: AnomalySettings, args) -> None:
    """The observers' false alarms on the clean records and detection delays on the bases."""
    params = {f"anomaly_{n}": v for n, v in zip(LIMITS, settings.limits(), strict=True)}
    with tempfile.TemporaryDirectory() as tmp:
        fmu = export_observer(plant, Path(tmp) / "observer.fmu")
        print(f"observer FMU of fopdt_3F (effects dropped), {settings}, noise {MONITORING}")
        print(
            "\nclean records: rises of the anomaly flag, longest run outside the band "
            f"(flag at {args.run_samples}), largest CUSUM (flag at {args.cusum_threshold:g})"
        )
        hours = 0.0
        for name, (t, y, e, q, role) in records.items():
            out = run_observer_fmu(fmu, y, e, q, params)
            found = detection(t, out["anomaly"], None)
            cusum = max(out["cusum_high"].max(), out["cusum_low"].max())
            hours += (t[-1] - t[0] + t[1] - t[0]) / 3600.0
            print(
                f"  {name:10s} {role:10s} {t.size:5d} samples  {found.false_alarms}  "
                f"run {int(out['anomaly_samples'].max())}  CUSUM {cusum:.1f}"
            )
        print(f"  {hours:.2f} h of clean records")
        flume = {n: records[n][:4] for n in BASES}
        fmu_run = lambda y, e, q, **_: run_observer_fmu(fmu, y, e, q, params)  # noqa: E731
        physical = _flume_inflow(flume)
        _print_table("flume (bundled records)", _delays(fmu_run, plant, flume, physical))
        truth = dataclasses.replace(plant, envelope=None)
        rng = np.random.default_rng(SEED)
        model = {}
        for n, (t, _, e, q) in flume.items():
            noise = MONITORING.measurement_sd_mm * rng.standard_normal(t.size)
            model[n] = (t, simulate(truth, t, e, q) + noise, e, q)
        _print_table("model (the observer's model + white noise)",
                     _delays(fmu_run, truth, model))  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        env_fmu = export_observer(_physical(), Path(tmp) / "envelope.fmu")
        _envelope(records, plant, physical, env_fmu)
    with tempfile.TemporaryDirectory() as tmp:
        ref_fmu = export_observer(_physical(), Path(tmp) / "references.fmu",
                                  reference_gauges=REFERENCES)  # fmt: skip
        _with_references(records, plant, ref_fmu)


def _physical():
    plant = read_model_file(ROOT / "models/physical_3F.json").plant
    return dataclasses.replace(plant, effects=())


def _envelope(records: dict, truth, inflow: dict, fmu: Path) -> None:
    """The envelope observer's FMU over the clean records and the flume bases."""
    print(f"\nenvelope observer FMU of physical_3F (effects dropped), {ENVELOPE_ANOMALY}")
    print("clean records: rises, longest run (flag at "
          f"{ENVELOPE_ANOMALY.run_samples}), CUSUM (flag at "
          f"{ENVELOPE_ANOMALY.cusum_threshold:g}), slow CUSUM (flag at "
          f"{ENVELOPE_ANOMALY.slow_threshold:g})")  # fmt: skip
    total = 0
    for name, (t, y, e, q, role) in records.items():
        out = run_observer_fmu(fmu, y, e, q)
        found = detection(t, out["anomaly"], None)
        total += found.false_alarms
        cusum = max(out["cusum_high"].max(), out["cusum_low"].max())
        print(f"  {name:10s} {role:10s} {found.false_alarms}  run "
              f"{int(out['anomaly_samples'].max())}  CUSUM {cusum:.1f}  slow CUSUM "
              f"{out['slow_cusum'].max():.1f}")  # fmt: skip
    print(f"  false alarms on the clean bundled records: {total}")
    flume = {n: records[n][:4] for n in BASES}
    envelope_run = lambda y, e, q, **_: run_observer_fmu(fmu, y, e, q)  # noqa: E731
    _print_table("envelope observer FMU, flume (bundled records)",
                 _delays(envelope_run, truth, flume, inflow))  # fmt: skip


def _with_references(records: dict, truth, fmu: Path) -> None:
    """The envelope observer FMU with the gauge-drift rule over the clean records and the
    flume bases (each reference gauge given the change an effect of the pool makes at 3F)."""
    print(f"\nenvelope observer FMU of physical_3F with reference gauges {', '.join(REFERENCES)}")
    print("clean records: rises of the anomaly flag, of the gauge-drift flag, largest |slope| "
          "(mm/s)")  # fmt: skip
    total = 0
    for name, (t, y, e, q, role) in records.items():
        out = run_observer_fmu(fmu, y, e, q, reference_levels_mm=_REFERENCE_LEVELS[name])
        rises = detection(t, out["anomaly"], None).false_alarms
        drift = detection(t, out["gauge_drift"], None).false_alarms
        total += rises
        print(f"  {name:10s} {role:10s} {rises}  {drift}  "
              f"{np.abs(out['gauge_slope_mm_per_s']).max():.4f}")  # fmt: skip
    print(f"  false alarms on the clean bundled records: {total}")
    flume = {n: records[n][:4] for n in BASES}
    inflow = _flume_inflow(flume, ("3F", *REFERENCES))

    def run(level, e, q, *, name, effect):
        if effect == "flume_inflow":
            refs = {g: inflow[name][g] for g in REFERENCES}
        elif effect == "sensor_drift":  # the gauge's own
            refs = _REFERENCE_LEVELS[name]
        else:  # the pool's: every gauge changes alike
            change = level - flume[name][1]
            refs = {g: v + change for g, v in _REFERENCE_LEVELS[name].items()}
        return run_observer_fmu(fmu, level, e, q, reference_levels_mm=refs)

    physical = {n: (None if v is None else v["3F"]) for n, v in inflow.items()}
    table = _delays(run, truth, flume, physical)
    _print_table(f"envelope observer FMU with reference gauges (kind {DRIFT_KIND} = d), flume "
                 "(bundled records)", table)  # fmt: skip


if __name__ == "__main__":
    main()
