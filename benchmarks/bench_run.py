"""Wall-clock time of a fresh ``gatetwin run``, stage by stage.

Runs ``python -m gatetwin run --out <temp>/out`` in a new process (this checkout's ``src``
first on the path) in a temporary folder, reads the "Stage times" table the run appends to
its ``summary.md``, prints it and writes it as JSON with the machine, the date, the commit
and the command. The first run on a machine also pays numba's and Zig's one-time caches
(``~/.cache``); run it twice to see both. Never asserted: the times depend on the machine
and on what else it runs.

With ``--serial`` a second fresh run with ``--workers 1`` (every stage's pieces one after
another in one process) follows, and each stage's time is printed beside it with the ratio.

usage: python benchmarks/bench_run.py [--json bench_run.json] [--keep DIR] [--serial]
                                      [-- RUN OPTIONS]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: One row of the "Stage times" table: ``| title | seconds |``.
ROW = re.compile(r"^\| (?P<title>.+?) \| (?P<seconds>[0-9.]+) \|$")


def stage_times(summary: str) -> dict[str, float]:
    """Stage title -> seconds from the "## Stage times" section of a run's summary.md."""
    section = summary.split("## Stage times", 1)
    if len(section) != 2:
        raise SystemExit("summary.md has no '## Stage times' section")
    times = {}
    for line in section[1].splitlines():
        if line.startswith("## "):
            break
        if (found := ROW.match(line)) and found["title"] != "total":
            times[found["title"]] = float(found["seconds"])
    return times


def stage_total(summary: str) -> float:
    """The run's own seconds: the "total" row of summary.md's "## Stage times" (the stages of
    a group run at the same time, so it is less than their sum)."""
    for line in summary.split("## Stage times", 1)[-1].splitlines():
        if (found := ROW.match(line)) and found["title"] == "total":
            return float(found["seconds"])
    raise SystemExit("summary.md's stage times have no total")


def machine() -> dict[str, object]:
    """What the times were measured on."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {"platform": platform.platform(), "processor": platform.processor() or None,
            "python": platform.python_version(), "cpus": os.cpu_count(),
            "load_average_at_start": load}  # fmt: skip


def commit() -> str | None:
    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True)  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return None
    return done.stdout.strip()


def run(extra: list[str], keep: Path | None) -> dict[str, object]:
    """One fresh run; its stage times, its total wall-clock time and the command."""
    with tempfile.TemporaryDirectory(prefix="bench-run-") as tmp:
        out = keep or Path(tmp) / "out"
        command = [sys.executable, "-m", "gatetwin", "run", "--out", str(out), *extra]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            p for p in (str(ROOT / "src"), os.environ.get("PYTHONPATH")) if p)}  # fmt: skip
        start = time.perf_counter()
        done = subprocess.run(command, cwd=tmp, env=env, capture_output=True, text=True,
                              check=False)  # fmt: skip
        wall = time.perf_counter() - start
        if done.returncode != 0:
            raise SystemExit(f"gatetwin run failed ({done.returncode}): "
                             f"{done.stderr.strip().splitlines()[-1:]}")  # fmt: skip
        summary = (out / "summary.md").read_text(encoding="utf-8")
    return {"command": " ".join(command), "wall_s": round(wall, 2),
            "stages_s": stage_times(summary), "stages_total_s": stage_total(summary)}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--json",
        type=Path,
        default=Path("bench_run.json"),
        help="where to write the times (default: bench_run.json)",
    )
    parser.add_argument("--keep", type=Path, help="write the run's output here and keep it")
    parser.add_argument("--serial", action="store_true",
                        help="then a run with --workers 1, printed beside it")  # fmt: skip
    parser.add_argument("extra", nargs="*", help="options passed on to 'gatetwin run'")
    args = parser.parse_args(argv)
    doc = {"date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
           "machine": machine(), "commit": commit(),
           **run(args.extra, args.keep.resolve() if args.keep else None)}  # fmt: skip
    if args.serial:
        doc["serial"] = run([*args.extra, "--workers", "1"], None)
    _print(doc)
    args.json.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")
    return 0


def _print(doc: dict) -> None:
    """The stage times, and beside them the serial run's with the ratio when there is one."""
    whole = "whole process (imports and start-up included)"

    def rows(d: dict) -> dict[str, float]:
        return {**d["stages_s"], "the stages (summary.md's total)": d["stages_total_s"],
                whole: d["wall_s"]}  # fmt: skip

    mine, serial = rows(doc), rows(doc["serial"]) if "serial" in doc else {}
    width = max(len(t) for t in mine)
    if serial:
        print(f"{'':<{width}}  {'default':>9}  {'--workers 1':>11}  ratio")
    for title, seconds in mine.items():
        line = f"{title:<{width}}  {seconds:7.1f} s"
        if title in serial:
            ratio = f"{serial[title] / seconds:5.2f}x" if seconds > 0 else "–"
            line += f"  {serial[title]:9.1f} s  {ratio}"
        print(line)


if __name__ == "__main__":
    sys.exit(main())
