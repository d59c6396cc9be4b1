"""Record reading speed and peak memory: gatetwin's reader next to pandas (and polars).

Writes a record of ``--rows`` samples (default 1,000,000) with nine columns (time,
opening, state, flow, five gauges) in a temporary directory, then reads it in fresh
child processes, ``--repeat`` times each:

* ``gatetwin read_record`` — the whole reader: parse, check, segment (what
  ``gatetwin check`` does before printing);
* ``gatetwin columns`` — the file-to-columns layer alone (``records.table.read_table``);
* ``gatetwin parquet`` — ``read_record`` on the same record written as Parquet;
* ``pandas.read_csv`` and, if installed, ``polars.read_csv`` — parsing only.

Time is the best of the repeats; peak memory is the rise of the child's maximum resident
set size (``ru_maxrss``) above its resident size just before reading, after imports.
Ratios are against pandas, and memory also against the CSV's size.

Run: ``PYTHONPATH=src python benchmarks/bench_reader.py [--rows N] [--repeat K]``
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

GAUGES = ("1D", "2E", "3F", "4G", "5H")

CHILD = r"""
import gc, json, resource, sys, time
kind, path = sys.argv[1], sys.argv[2]
import numpy
if kind.startswith("gatetwin"):
    import pyarrow, pyarrow.csv, pyarrow.compute, pyarrow.parquet
    from gatetwin.records import read_record
    from gatetwin.records.columns import is_record_column
    from gatetwin.records.table import read_table
elif kind == "pandas":
    import pandas
elif kind == "polars":
    import polars

def rss_kib():
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0

def read(kind, path):
    if kind in ("gatetwin", "gatetwin-parquet"):
        return read_record(path)
    if kind == "gatetwin-columns":
        return read_table(path, keep=is_record_column, text_columns=("state",))
    if kind == "pandas":
        return pandas.read_csv(path)
    return polars.read_csv(path)

warm = sys.argv[3]
read(kind, warm)  # page in the reader's code, so only data is measured
gc.collect()
before = rss_kib()
start = time.perf_counter()
result = read(kind, path)
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "peak_mib": max(peak - before, 0) / 1024}))
"""


def write_record(path: Path, rows: int) -> None:
    """A plausible record: 300-sample holds, 3-sample moves with empty opening."""
    rng = np.random.default_rng(7)
    k = np.arange(rows)
    phase = k % 303
    segment = k // 303
    opening = 15.0 + 5.0 * (segment % 6)
    moving = phase >= 300
    time_s = k * 1.2
    flow = 29.5 + 0.05 * rng.standard_normal(rows)
    columns = [np.char.mod("%.1f", time_s),
               np.where(moving, "", np.char.mod("%.0f", opening)),
               np.where(moving, "open", "hold"),
               np.char.mod("%.2f", flow)]  # fmt: skip
    for j, _ in enumerate(GAUGES):
        level = 400.0 - 6.0 * opening + 2.0 * j + 0.3 * rng.standard_normal(rows)
        columns.append(np.char.mod("%.1f", level))
    header = "time_s,opening_mm,state,flow_m3h," + ",".join(f"level_{g}_mm" for g in GAUGES)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(header + "\n")
        for start in range(0, rows, 100_000):
            block = [c[start : start + 100_000] for c in columns]
            handle.write("\n".join(",".join(cells) for cells in zip(*block, strict=True)))
            handle.write("\n")
    path.with_suffix(".json").write_text(json.dumps({"sample_period_s": 1.2}), "utf-8")


def write_parquet(csv_path: Path, parquet_path: Path) -> None:
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    pq.write_table(pacsv.read_csv(csv_path), parquet_path)
    parquet_path.with_suffix(".json").write_text(csv_path.with_suffix(".json").read_text())


def measure(kind: str, path: Path, warm: Path, repeat: int) -> dict[str, float]:
    runs = []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", CHILD, kind, str(path), str(warm)],
                             check=True, capture_output=True, text=True)  # fmt: skip
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return {"seconds": min(r["seconds"] for r in runs),
            "peak_mib": float(np.median([r["peak_mib"] for r in runs]))}  # fmt: skip


def write_files(folder: Path, rows: int) -> None:
    """The measured record and a small one to warm up with, as CSV and Parquet."""
    for stem, n in (("long", rows), ("warm", 2000)):
        write_record(folder / f"{stem}.csv", n)
        write_parquet(folder / f"{stem}.csv", folder / f"{stem}.parquet")


def main() -> None:
    if sys.argv[1:2] == ["--write"]:
        write_files(Path(sys.argv[2]), int(sys.argv[3]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        csv_path, parquet_path = Path(tmp) / "long.csv", Path(tmp) / "long.parquet"
        warm_csv, warm_parquet = Path(tmp) / "warm.csv", Path(tmp) / "warm.parquet"
        # The files are written by a child so that this process stays small: a child's
        # ru_maxrss starts from its parent's at fork.
        subprocess.run([sys.executable, __file__, "--write", tmp, str(args.rows)], check=True)
        size_mib = csv_path.stat().st_size / 2**20
        print(f"record: {args.rows} rows x 9 columns, CSV {size_mib:.1f} MiB, Parquet "
              f"{parquet_path.stat().st_size / 2**20:.1f} MiB; best of {args.repeat}")  # fmt: skip
        kinds = [("pandas", csv_path, warm_csv), ("gatetwin", csv_path, warm_csv),
                 ("gatetwin-columns", csv_path, warm_csv),
                 ("gatetwin-parquet", parquet_path, warm_parquet)]  # fmt: skip
        if importlib.util.find_spec("polars") is not None:
            kinds.append(("polars", csv_path, warm_csv))
        results = {kind: measure(kind, path, warm, args.repeat) for kind, path, warm in kinds}
    base = results["pandas"]
    print(f"{'reader':<18} {'time s':>7} {'x pandas':>9} {'peak MiB':>9} {'x pandas':>9} "
          f"{'x CSV size':>10}")  # fmt: skip
    for kind, r in results.items():
        print(f"{kind:<18} {r['seconds']:7.2f} {r['seconds'] / base['seconds']:9.2f} "
              f"{r['peak_mib']:9.0f} {r['peak_mib'] / base['peak_mib']:9.2f} "
              f"{r['peak_mib'] / size_mib:10.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
