"""Fleet throughput, memory per worker, and the projected time of a year-long district.

    python benchmarks/bench_fleet.py [--gates 1000] [--workers 2] [--days 30]
                                     [--history MONTH.parquet] [--project-gates 300]
                                     [--project-days 365] [--project-workers 2 8 32]
                                     [--throughput-only] [--project-district 1000]
                                     [--routine-days D]

Three measurements in one run:

1. Throughput. Generates ``--gates`` district gates (``gatetwin.fleet.write_district``:
   step tests and a static table each), identifies them with ``gatetwin models`` on 1
   process and on ``--workers``, side by side, and prints gates/s, records/s and logged
   samples/s of each and the scaling ratio (speed-up over the workers); then what one
   gate costs (generation, identification) and the projected wall time of this same
   measurement on ``--project-district`` gates (generation, serial run and pool run, each
   linear in the gates). ``--throughput-only`` stops here. With ``--routine-days D`` the
   district's gates are light instead: each one routine operation history of ``D`` days
   (``gatetwin flume --district N --routine mixed --days D``: logged every 1.2 s, every
   fourth gate under a level controller), whose job is ``gatetwin routine``'s
   identification (move windows, an FOPDT per window, the schedule on Q), no step tests,
   no physical fit.
2. Memory per worker. One gate's routine history over ``--days`` days at 1 Hz (generated
   as ``bench_month.py`` does, or ``--history``) identified by ``gatetwin routine`` in a
   fresh child process, the whole history at once and chunk by chunk
   (``--max-memory``), each child's peak resident memory; the chunked child's rows/s is
   the routine identification rate of one worker.
3. Projection. ``--project-gates`` gates × ``--project-days`` days at 1 Hz on N workers,
   from the rate of (2) and the scaling of ``--workers`` chunked routine jobs run at once
   (the step-test district of (1) is dominated by each worker's start-up, not by reading
   histories); the assumptions are printed with it.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from bench_month import child_peak_mib, generate
from gatetwin.fleet import FleetSettings, run_fleet, write_district

#: Memory cap given to the chunked routine job of a worker, MiB.
WORKER_MEMORY_MIB = 400.0


def _records(district: Path) -> tuple[int, int]:
    """Record files (step tests and static tables, or routine histories) and logged samples
    of the time series: their data lines (the generator writes one header line and no
    comments; counting lines, not reading the records, keeps 1,000 gates' count in
    seconds)."""
    files = sorted(district.rglob("*.csv"))
    samples = sum(p.read_bytes().count(b"\n") - 1 for p in files if "static" not in p.name)
    return len(files), samples


def throughput(gates: int, workers: int, tmp: Path,
               routine_days: float | None = None) -> tuple[dict[int, float], float]:  # fmt: skip
    """Wall time of ``gatetwin models`` over the district with 1 and ``workers`` processes,
    and the district's generation time."""
    from gatetwin.fleet.routine import write_routine_district

    district = tmp / "district"
    start = time.perf_counter()
    if routine_days is None:
        write_district(gates, district, seed=1, workers=workers)
    else:
        write_routine_district(gates, district, seed=1, control="mixed", days=routine_days,
                               workers=workers)  # fmt: skip
    generated_s = time.perf_counter() - start
    n_files, samples = _records(district)
    times: dict[int, float] = {}
    failed: dict[int, list[str]] = {}
    for n in (1, workers):
        start = time.perf_counter()
        doc = run_fleet([str(district)], tmp / f"out{n}", FleetSettings(workers=n))
        times[n] = time.perf_counter() - start
        failed[n] = [g["gate"] for g in doc["gates"] if g["status"] != "ok"]
    kind = "step-test" if routine_days is None else f"{routine_days:g}-day routine history"
    print(f"1. throughput: {gates} {kind} gates, {n_files} record files, {samples:,} logged "
          f"samples "
          f"(generated in {generated_s:.0f} s)")  # fmt: skip
    print("| processes | wall time (s) | gates/s | records/s | samples/s |")
    print("|---|---|---|---|---|")
    for n, seconds in times.items():
        print(f"| {n} | {seconds:.1f} | {gates / seconds:.2f} | {n_files / seconds:.2f} | "
              f"{samples / seconds:,.0f} |")  # fmt: skip
    speedup = times[1] / times[workers]
    print(
        f"scaling: {speedup:.2f}x with {workers} processes ({speedup / workers:.2f} of "
        f"linear); gates not ok (failed, or no informative window) {failed[1]} (same in "
        f"both: {failed[1] == failed[workers]})"
    )
    return times, generated_s


def gate_cost(gates: int, workers: int, times: dict[int, float], generated_s: float,
              project: int, routine_days: float | None = None) -> None:  # fmt: skip
    """What one gate costs, and this measurement's wall time on ``project`` gates."""
    from gatetwin.fleet.district import (
        FIT_FLOWS_M3H,
        POST_STEP_S,
        PRE_STEP_S,
        STATIC_OFFSETS_MM,
        STATIC_SAMPLES,
        district_gates,
        expected_samples,
    )

    n_steps = len(FIT_FLOWS_M3H) + 1
    per_step = expected_samples(district_gates(1)[0]) // n_steps
    if routine_days is not None:
        print(f"   one gate: a routine history of {routine_days:g} day(s) "
              f"(up to {routine_days * 86400 / 1.2:,.0f} samples at 1.2 s, fewer where the "
              "logger dropped out); its job: the history's "
              "move windows screened, an FOPDT fitted per informative window, the schedule "
              "on Q")  # fmt: skip
    else:
        print(f"   one gate: {n_steps} step tests of {PRE_STEP_S + POST_STEP_S:g} s "
              f"({per_step} samples each, {len(FIT_FLOWS_M3H)} fitted, 1 held out) and a "
              f"static table of up to {len(FIT_FLOWS_M3H) * len(STATIC_OFFSETS_MM)} points "
              f"of {STATIC_SAMPLES} samples; its job: an FOPDT per step, the physical "
              "model's least-squares fit over every record, the FOPDT schedule, held-out "
              "free runs")  # fmt: skip
    cost = {"generation": generated_s / gates, "serial": times[1] / gates,
            f"{workers} processes": times[workers] / gates}  # fmt: skip
    print("   per gate: " + ", ".join(f"{k} {v:.2f} s" for k, v in cost.items()))
    total = project * sum(cost.values())
    print(f"   projected for {project} gates (linear in the gates): "
          + ", ".join(f"{k} {project * v / 60:.1f} min" for k, v in cost.items())
          + f"; {total / 60:.1f} min in all")  # fmt: skip


def added_worker(times: dict[int, float], workers: int) -> float:
    """What each worker beyond the first adds, as a fraction of one worker's rate: 0 to 1
    (a ratio above linear says the serial run was slowed by other load, not that workers
    scale better than linearly)."""
    if workers <= 1:
        return 1.0
    return min(1.0, max(0.0, (times[1] / times[workers] - 1.0) / (workers - 1)))


def memory(history: Path, tmp: Path) -> tuple[int, float]:
    """Peak memory of the whole and the chunked routine job; (rows, chunked rows/s)."""
    import pyarrow.parquet

    rows = pyarrow.parquet.ParquetFile(history).metadata.num_rows
    base = [sys.executable, "-m", "gatetwin", "routine", str(history)]
    whole, whole_s = child_peak_mib([*base, "--json", str(tmp / "whole.json")])
    cap = f"{WORKER_MEMORY_MIB:g}"
    chunked, chunked_s = child_peak_mib([*base, "--json", str(tmp / "chunked.json"),
                                         "--max-memory", cap])  # fmt: skip
    same = (tmp / "whole.json").read_bytes() == (tmp / "chunked.json").read_bytes()
    print(f"2. memory per worker: {rows:,} rows at 1 Hz ({rows / 86400:.1f} days)")
    print(f"   whole history      peak {whole:6.0f} MiB  {whole_s:6.1f} s  "
          f"{rows / whole_s:,.0f} rows/s")  # fmt: skip
    print(f"   --max-memory {cap}  peak {chunked:6.0f} MiB  {chunked_s:6.1f} s  "
          f"{rows / chunked_s:,.0f} rows/s  (same JSON: {same})")  # fmt: skip
    return rows, rows / chunked_s


def routine_scaling(history: Path, workers: int, tmp: Path) -> float:
    """What each worker beyond the first adds on the routine workload itself: ``workers``
    chunked routine jobs at once against one alone (wall times), as a fraction of one."""
    import subprocess

    def command(k: int) -> list[str]:
        return [sys.executable, "-m", "gatetwin", "routine", str(history), "--json",
                str(tmp / f"par{k}.json"), "--max-memory", f"{WORKER_MEMORY_MIB:g}"]  # fmt: skip

    start = time.perf_counter()
    subprocess.run(command(0), check=True, capture_output=True)
    alone_s = time.perf_counter() - start
    start = time.perf_counter()
    children = [subprocess.Popen(command(k), stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL) for k in range(workers)]  # fmt: skip
    if any(child.wait() != 0 for child in children):
        raise RuntimeError("a routine job failed")
    together_s = time.perf_counter() - start
    speedup = workers * alone_s / together_s
    added = min(1.0, max(0.0, (speedup - 1.0) / (workers - 1))) if workers > 1 else 1.0
    print(f"   {workers} routine jobs at once: {together_s:.1f} s against {alone_s:.1f} s "
          f"alone: {speedup:.2f}x the rows/s of one (each worker beyond the first adds "
          f"{added:.2f} of one)")  # fmt: skip
    return added


def projection(rate_rows_s: float, scaling: float, gates: int, days: float,
               workers: list[int]) -> None:  # fmt: skip
    """Projected wall time of a district's year of 1 Hz histories."""
    samples = gates * days * 86400.0  # 1 Hz
    print(f"3. projection: {gates} gates x {days:g} days at 1 Hz = {samples:.3g} samples")
    print(
        "   assumptions: one routine history per gate, read chunk by chunk within "
        f"{WORKER_MEMORY_MIB:g} MiB a worker; each worker identifies {rate_rows_s:,.0f} "
        "rows/s (measured in 2 on one gate's month, the bench's operator schedule: one "
        "move every 15 min-4 h); each worker beyond the first adds the fraction of one "
        f"worker's rate measured in 2 with routine jobs at once ({scaling:.2f}; beyond "
        "the measured workers, the same fraction on as many cores); local Parquet read, "
        "no network or scheduler overhead, worker start-up (a few seconds) neglected"
    )
    print("| workers | projected wall time |")
    print("|---|---|")
    for n in workers:
        rate = rate_rows_s * (1.0 + (n - 1) * scaling)
        seconds = samples / rate
        print(f"| {n} | {seconds / 3600:.1f} h ({seconds / 86400:.2f} days) |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gates", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--days", type=float, default=30.0)
    parser.add_argument("--history", metavar="FILE.parquet",
                        help="a month-long 1 Hz history (with its sidecar) to measure "
                        "instead of generating one")  # fmt: skip
    parser.add_argument("--project-gates", type=int, default=300)
    parser.add_argument("--project-days", type=float, default=365.0)
    parser.add_argument("--project-workers", type=int, nargs="+", default=[2, 8, 32])
    parser.add_argument("--project-district", type=int, default=1000,
                        help="gates to project the throughput measurement to")  # fmt: skip
    parser.add_argument("--throughput-only", action="store_true",
                        help="measure the throughput (1.) alone")  # fmt: skip
    parser.add_argument("--routine-days", type=float, metavar="D",
                        help="throughput on light gates: one routine history of D days "
                        "each instead of step tests")  # fmt: skip
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        times, generated_s = throughput(args.gates, args.workers, tmp, args.routine_days)
        gate_cost(args.gates, args.workers, times, generated_s, args.project_district,
                  args.routine_days)  # fmt: skip
        if args.throughput_only:
            return
        history = Path(args.history) if args.history else generate(tmp, args.days)
        _, rate = memory(history, tmp)
        added = routine_scaling(history, args.workers, tmp)
    print(
        f"   (gatetwin models above: each worker beyond the first added "
        f"{added_worker(times, args.workers):.2f} of one on the step-test district)"
    )
    projection(rate, added, args.project_gates, args.project_days, args.project_workers)


if __name__ == "__main__":
    main()
