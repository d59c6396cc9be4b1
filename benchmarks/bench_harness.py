"""Cost of running each FMU in a child process, next to running it in this process.

The FOPDT and the physical model of gauge 3F (``models/``) are exported as C and pythonfmu
FMUs and validated against every bundled record with a 3F gauge, once with
``isolate=False`` (fmpy in this process, as the harness used to run) and once isolated (a
forked child of the FMU host per FMU), alternating, ``--repeat`` times; medians are printed
side by side with their ratio (never asserted). Two levels:

1. the FMU runs alone (:func:`run_in_process` against :func:`run_isolated` on the same
   requests): what isolation adds to the simulation;
2. the whole ``validate_fmu`` (reading, static validation, metrics, noise floor, step
   comparison, validity): what a user of ``gatetwin validate`` sees.

The FMU host's start (a ``python -c`` importing numpy, fmpy and the harness, once per
process) is measured apart: the first isolated run minus a later one.

usage: python benchmarks/bench_harness.py [--repeat 5] [--save]

``--save`` keeps the numbers in ``docs/results/harness.json`` for the validation page.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from gatetwin.bundled import bundled_records_dir
from gatetwin.fmu import export_fmu
from gatetwin.identification import reconstructed_opening
from gatetwin.modelfile import read_model_file
from gatetwin.records import detect_table_kind, read_record
from gatetwin.validation import communication_grid, inspect_fmu, validate_fmu
from gatetwin.validation.isolation import RunRequest, run_in_process, run_isolated

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("fopdt_3F", "physical_3F")
GAUGE = "3F"


def export_all(folder: Path) -> list[Path]:
    out = []
    for name in MODELS:
        plant = read_model_file(ROOT / "models" / f"{name}.json").plant
        for backend in ("c", "python"):
            out.append(
                export_fmu(
                    plant,
                    folder / f"{name}_{backend}.fmu",
                    backend=backend,
                    model_name=name,
                    provenance={"purpose": "benchmark"},
                )
            )
    return out


def bundled_records() -> list:
    paths = sorted(bundled_records_dir().glob("*.csv"))
    records = [read_record(p) for p in paths if detect_table_kind(p) != "static"]
    return [r for r in records if GAUGE in r.levels_mm]


def requests_of(records: list) -> list[RunRequest]:
    out = []
    for r in records:
        opening = reconstructed_opening(r.time_s, r.opening_mm, r.hold)
        grid = communication_grid(r.time_s, r.sample_period_s)
        out.append(RunRequest(f"level_{GAUGE}_mm", grid, opening, r.flow_m3h))
    return out


def seconds(call: Callable[[], object]) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def paired(a: Callable[[], object], b: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Medians of ``a`` and ``b`` timed alternately."""
    ta, tb = [], []
    for _ in range(repeat):
        ta.append(seconds(a))
        tb.append(seconds(b))
    return statistics.median(ta), statistics.median(tb)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument(
        "--save", action="store_true", help="keep the numbers in docs/results/harness.json"
    )
    args = parser.parse_args(argv)
    records = bundled_records()
    requests = requests_of(records)
    n_steps = sum(r.grid.n_steps for r in requests)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        fmus = export_all(Path(tmp))
        infos = [inspect_fmu(f) for f in fmus]
        first = seconds(lambda: run_isolated(infos[0], requests[:1]))
        later = seconds(lambda: run_isolated(infos[0], requests[:1]))
        for fmu, info in zip(fmus, infos, strict=True):
            levels = {
                "FMU runs": (lambda i=info: run_in_process(i, requests),
                             lambda i=info: run_isolated(i, requests)),
                "validate_fmu": (lambda f=fmu: validate_fmu(f, records, isolate=False),
                                 lambda f=fmu: validate_fmu(f, records)),
            }  # fmt: skip
            for level, (local, isolated) in levels.items():
                t_local, t_isolated = paired(local, isolated, args.repeat)
                rows.append({"fmu": fmu.stem, "level": level, "in_process_s": t_local,
                             "isolated_s": t_isolated})  # fmt: skip
    data = {"records": len(records), "gauge": GAUGE, "steps_per_fmu": n_steps,
            "repeat": args.repeat, "host_start_s": first - later, "rows": rows}  # fmt: skip
    print(report(data))
    if args.save:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from results import save

        print(save("harness", data, "python benchmarks/bench_harness.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


def report(data: dict) -> str:
    """The overhead of isolation as Markdown (printed, and the validation page's block)."""
    steps = data["steps_per_fmu"]
    lines = ["| FMU | level | in process (s) | µs a step in process | isolated (s) | ratio |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    totals: dict[str, list[float]] = {}
    for r in data["rows"]:
        local, isolated = r["in_process_s"], r["isolated_s"]
        total = totals.setdefault(r["level"], [0.0, 0.0])
        total[0] += local
        total[1] += isolated
        per_step = f"{1e6 * local / steps:.1f}" if r["level"] == "FMU runs" else ""
        lines.append(f"| `{r['fmu']}` | {r['level']} | {local:.3f} | {per_step} | "
                     f"{isolated:.3f} | {isolated / local:.2f}× |")  # fmt: skip
    n = len(data["rows"]) // max(len(totals), 1)
    for level, (local, isolated) in totals.items():
        lines.append(f"| all {n} FMUs | {level} | {local:.3f} | | {isolated:.3f} | "
                     f"{isolated / local:.2f}× |")  # fmt: skip
    local, isolated = totals.get("validate_fmu", [1.0, 1.0])
    with_start = isolated + data["host_start_s"]
    return "\n".join(lines) + (
        f"\n\n{data['records']} bundled records with gauge {data['gauge']}, {steps} FMU steps "
        f"per FMU; medians of {data['repeat']}, each pair timed alternately. The FMU host's "
        f"start, once per process: {data['host_start_s']:.2f} s; with it the whole "
        f"`validate_fmu` takes {with_start / local:.2f}× its in-process time.\n"
    )


if __name__ == "__main__":
    main()
