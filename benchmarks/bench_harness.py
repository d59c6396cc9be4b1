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

usage: python benchmarks/bench_harness.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from gatetwin.bundled import bundled_records_dir
from gatetwin.fmu import export_fmu
from gatetwin.identify import reconstructed_opening
from gatetwin.modelfile import read_model_file
from gatetwin.records import detect_table_kind, read_record
from gatetwin.validate import communication_grid, inspect_fmu, validate_fmu
from gatetwin.validate.isolation import RunRequest, run_in_process, run_isolated

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    records = bundled_records()
    requests = requests_of(records)
    n_steps = sum(r.grid.n_steps for r in requests)
    with tempfile.TemporaryDirectory() as tmp:
        fmus = export_all(Path(tmp))
        infos = [inspect_fmu(f) for f in fmus]
        first = seconds(lambda: run_isolated(infos[0], requests[:1]))
        later = seconds(lambda: run_isolated(infos[0], requests[:1]))
        print(
            f"{len(records)} bundled records with gauge {GAUGE}, {n_steps} FMU steps per FMU;"
            f" median of {args.repeat}"
        )
        print(f"FMU host start (once per process): {first - later:.2f} s\n")
        header = f"{'FMU':<24}{'level':<14}{'in process s':>14}{'isolated s':>12}{'ratio':>8}"
        print(header)
        print("-" * len(header))
        totals = {"FMU runs": [0.0, 0.0], "validate_fmu": [0.0, 0.0]}
        for fmu, info in zip(fmus, infos, strict=True):
            levels = {
                "FMU runs": (lambda i=info: run_in_process(i, requests),
                             lambda i=info: run_isolated(i, requests)),
                "validate_fmu": (lambda f=fmu: validate_fmu(f, records, isolate=False),
                                 lambda f=fmu: validate_fmu(f, records)),
            }  # fmt: skip
            for level, (local, isolated) in levels.items():
                t_local, t_isolated = paired(local, isolated, args.repeat)
                totals[level][0] += t_local
                totals[level][1] += t_isolated
                print(
                    f"{fmu.name:<24}{level:<14}{t_local:>14.3f}{t_isolated:>12.3f}"
                    f"{t_isolated / t_local:>8.2f}"
                )
        print("-" * len(header))
        for level, (t_local, t_isolated) in totals.items():
            print(
                f"{'all ' + str(len(fmus)) + ' FMUs':<24}{level:<14}{t_local:>14.3f}"
                f"{t_isolated:>12.3f}{t_isolated / t_local:>8.2f}"
            )
        t_local, t_isolated = totals["validate_fmu"]
        with_start = t_isolated + first - later
        print(
            f"{'… with the host start':<38}{t_local:>14.3f}{with_start:>12.3f}"
            f"{with_start / t_local:>8.2f}"
        )


if __name__ == "__main__":
    main()
