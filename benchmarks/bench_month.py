"""Peak memory of identifying a month-long 1 Hz routine history from Parquet, whole and chunked.

Generates one district gate's routine history (operator schedule) over ``--days`` days at
1 Hz with the virtual flume (about 2.6e6 rows for 30 days), writes it as Parquet next to
its sidecar, then measures in fresh child processes, side by side:

* ``gatetwin routine HISTORY.parquet --json OUT.json`` — read the whole history, check,
  find the informative windows, fit them (the whole job);
* ``gatetwin routine HISTORY.parquet --json OUT.json --max-memory MIB`` — the same job read
  a chunk at a time, window by window (its JSON must equal the whole job's);
* the bare reference: ``pyarrow.parquet.read_table`` of the same file alone.

With ``--repeat R`` the generated history is laid end to end R times (times shifted by its
length) into a history R times as long: the same moves again, no new simulation, to show a
history whose whole read exceeds the ``--max-memory`` cap while the chunked job stays
within it.

Peak memory is each child's ``ru_maxrss``; each job's is printed next to the cap and as a
ratio to the bare read.

usage: python benchmarks/bench_month.py [--days 30] [--max-memory 400] [--repeat 1] [--keep DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path


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


def repeated(path: Path, times: int) -> Path:
    """The history at ``path`` laid end to end ``times`` times, written a copy at a time."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet

    if times <= 1:
        return path
    table = pyarrow.parquet.read_table(path)
    time_s = table.column("time_s")
    span = pc.max(time_s).as_py() - pc.min(time_s).as_py() + 1.0
    out = path.with_name(f"{path.stem}_x{times}.parquet")
    with pyarrow.parquet.ParquetWriter(out, table.schema) as writer:
        for k in range(times):
            shifted = pc.add(time_s, pa.scalar(k * span, time_s.type))
            index = table.schema.get_field_index("time_s")
            writer.write_table(table.set_column(index, "time_s", shifted))
    out.with_suffix(".json").write_text(path.with_suffix(".json").read_text())
    return out


def _routine(path: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "gatetwin", "routine", str(path), "--json", str(out), *extra]


def _line(label: str, peak: float, seconds: float, bare: float, cap: float) -> str:
    verdict = "within" if peak <= cap else "OVER"
    return (f"{label:<34} peak {peak:8.0f} MiB  {seconds:6.1f} s  {peak / bare:5.2f}x the "
            f"bare read; cap {cap:.0f} MiB: {verdict}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=30.0)
    parser.add_argument("--max-memory", type=float, default=400.0, metavar="MIB",
                        help="memory cap of a worker for the chunked job, MiB")  # fmt: skip
    parser.add_argument("--repeat", type=int, default=1,
                        help="lay the generated history end to end this many times")  # fmt: skip
    parser.add_argument("--keep", metavar="DIR", help="write the history here and keep it")
    parser.add_argument("--history", metavar="FILE.parquet",
                        help="measure this history (with its sidecar) instead of generating "
                        "one; --days then only labels it")  # fmt: skip
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep) if args.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        start = time.perf_counter()
        source = Path(args.history) if args.history else generate(folder, args.days)
        path = repeated(source, args.repeat)
        made = time.perf_counter() - start
        import pyarrow.parquet

        rows = pyarrow.parquet.ParquetFile(path).metadata.num_rows
        size = path.stat().st_size / 2**20
        print(f"{args.days * args.repeat:g} days at 1 Hz: {rows:,} rows, Parquet {size:.1f} MiB "
              f"(generated in {made:.0f} s)")  # fmt: skip
        bare, bare_s = child_peak_mib([sys.executable, "-c",
                                       "import sys, pyarrow.parquet as pq; "
                                       "pq.read_table(sys.argv[1])", str(path)])  # fmt: skip
        whole_json, chunk_json = folder / "routine.json", folder / "routine_chunked.json"
        job, job_s = child_peak_mib(_routine(path, whole_json))
        cap = f"{args.max_memory:g}"
        chunked, chunked_s = child_peak_mib(_routine(path, chunk_json, "--max-memory", cap))
        same = whole_json.read_bytes() == chunk_json.read_bytes()
        print(f"{'bare pyarrow read_table':<34} peak {bare:8.0f} MiB  {bare_s:6.1f} s")
        print(_line("gatetwin routine (whole history)", job, job_s, bare, args.max_memory))
        print(_line(f"gatetwin routine --max-memory {cap}", chunked, chunked_s, bare,
                    args.max_memory))  # fmt: skip
        print(f"chunked / whole peak memory: {chunked / job:.2f}x; time: "
              f"{chunked_s / job_s:.2f}x; same JSON: {same}")  # fmt: skip


if __name__ == "__main__":
    main()
