"""Peak memory of identifying a month-long 1 Hz routine history from Parquet.

Generates one district gate's routine history (operator schedule) over ``--days`` days at
1 Hz with the virtual flume (about 2.6e6 rows for 30 days), writes it as Parquet next to
its sidecar, then measures in fresh child processes, side by side:

* ``gatetwin routine HISTORY.parquet --json OUT.json`` — read, check, find the informative
  windows, fit them (the whole job);
* the bare reference: ``pyarrow.parquet.read_table`` of the same file alone.

Peak memory is each child's ``ru_maxrss``; the job's is printed next to the 1 GiB budget of
a worker and as a ratio to the bare read.

usage: python benchmarks/bench_month.py [--days 30] [--keep DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

BUDGET_MIB = 1024.0


def generate(folder: Path, days: float) -> Path:
    """The history as Parquet (+ sidecar); returns the Parquet path."""
    import pyarrow.csv
    import pyarrow.parquet

    from gatetwin.fleet.district import GAUGE, GAUGE_DISTANCE_M, TARGET_LEVEL_MM, district_gates
    from gatetwin.fleet.routine import base_flow_m3h, routine_flume
    from gatetwin.flume.routine import RoutineSettings, routine_history

    truth = district_gates(1, seed=0)[0]
    cfg = routine_flume(truth).with_(sample_period_s=1.0)
    settings = replace(RoutineSettings(days=days), control="schedule")
    sidecar = {"gate": truth.gate, "gauges": {GAUGE: GAUGE_DISTANCE_M}}
    rec, _ = routine_history(cfg, truth.logger_config(), settings,
                             base_flow_m3h=base_flow_m3h(truth),
                             target_level_mm=0.5 * sum(TARGET_LEVEL_MM), gauge=GAUGE,
                             seed=truth.seed, sidecar=sidecar)  # fmt: skip
    csv = rec.write(folder / "month.csv")
    table = pyarrow.csv.read_csv(csv)
    out = folder / "month.parquet"
    pyarrow.parquet.write_table(table, out)
    csv.unlink()  # the sidecar month.json serves the Parquet file
    return out


#: Runs its arguments as a child and prints that child's peak resident KiB: a fresh wrapper
#: per measurement, so RUSAGE_CHILDREN holds that one command alone.
WRAPPER = ("import resource, subprocess, sys; done = subprocess.run(sys.argv[1:]); "
           "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
           "sys.exit(done.returncode)")  # fmt: skip


def child_peak_mib(command: list[str]) -> tuple[float, float]:
    """(peak resident MiB, seconds) of ``command`` in a child process."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", WRAPPER, *command], capture_output=True,
                          text=True, check=False)  # fmt: skip
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command[:4])} failed: {done.stderr[-500:]}")
    return float(done.stdout.split()[-1]) / 1024.0, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=30.0)
    parser.add_argument("--keep", metavar="DIR", help="write the history here and keep it")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep) if args.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        start = time.perf_counter()
        path = generate(folder, args.days)
        made = time.perf_counter() - start
        import pyarrow.parquet

        rows = pyarrow.parquet.ParquetFile(path).metadata.num_rows
        size = path.stat().st_size / 2**20
        print(f"{args.days:g} days at 1 Hz: {rows:,} rows, Parquet {size:.1f} MiB "
              f"(generated in {made:.0f} s)")  # fmt: skip
        bare, bare_s = child_peak_mib([sys.executable, "-c",
                                       "import sys, pyarrow.parquet as pq; "
                                       "pq.read_table(sys.argv[1])", str(path)])  # fmt: skip
        job, job_s = child_peak_mib([sys.executable, "-m", "gatetwin", "routine", str(path),
                                     "--json", str(folder / "routine.json")])  # fmt: skip
        print(f"bare pyarrow read_table     peak {bare:8.0f} MiB   {bare_s:6.1f} s")
        print(f"gatetwin routine (whole job) peak {job:8.0f} MiB   {job_s:6.1f} s   "
              f"{job / bare:.2f}x the bare read; budget {BUDGET_MIB:.0f} MiB: "
              f"{'within' if job <= BUDGET_MIB else 'OVER'}")  # fmt: skip


if __name__ == "__main__":
    main()
