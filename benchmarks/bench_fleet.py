"""Fleet throughput: a synthetic district identified serially and on a local process pool.

    python benchmarks/bench_fleet.py [--gates N] [--workers W]

Generates N gates (``gatetwin.fleet.write_district``), identifies them with 1 process and
with W, side by side in one run, and prints gates/s, logged samples/s and the pool's speed-up.
The records are each gate's designed tests (step tests and a static table), not routine
operation histories, so the figures say how fast model sets are built, not how fast a
year of SCADA logs would be read.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from gatetwin.fleet import FleetSettings, run_fleet, write_district
from gatetwin.records import read_record


def _samples(district: Path) -> int:
    return sum(read_record(p).n_samples for p in district.rglob("*.csv")
               if "static" not in p.name)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gates", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        district = Path(tmp) / "district"
        t0 = time.perf_counter()
        write_district(args.gates, district, seed=1, workers=args.workers)
        generate_s = time.perf_counter() - t0
        samples = _samples(district)
        times, failed = {}, {}
        for workers in (1, args.workers):
            t0 = time.perf_counter()
            doc = run_fleet([str(district)], Path(tmp) / f"out{workers}",
                            FleetSettings(workers=workers))  # fmt: skip
            times[workers] = time.perf_counter() - t0
            failed[workers] = [(g["gate"], g.get("error", "")) for g in doc["gates"]
                               if g["status"] != "ok"]  # fmt: skip
    print(f"district: {args.gates} gates, {samples} logged samples, generated in "
          f"{generate_s:.1f} s")  # fmt: skip
    print("| processes | wall time (s) | gates/s | samples/s |")
    print("|---|---|---|---|")
    for workers, seconds in times.items():
        print(f"| {workers} | {seconds:.1f} | {args.gates / seconds:.2f} | "
              f"{samples / seconds:,.0f} |")  # fmt: skip
    print(f"speed-up with {args.workers} processes: {times[1] / times[args.workers]:.2f}x")
    for gate, why in failed[1]:
        print(f"failed (in both runs: {failed[1] == failed[args.workers]}): {gate}: {why}")


if __name__ == "__main__":
    main()
