"""The ``gatetwin diagnose`` subcommand: arguments and run (the logic is in gatetwin.diagnosis)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gatetwin._io import write_json_atomic
from gatetwin.errors import GatetwinError

__all__ = ["add_diagnose_arguments", "add_spread_arguments", "run_diagnose", "spread_settings"]


def add_diagnose_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("record", metavar="RECORD.csv", nargs="+",
                        help="measured record (CSV); several are diagnosed one record per "
                        "task and OUT.json lists them under 'diagnoses'")  # fmt: skip
    parser.add_argument(
        "--model", metavar="MODEL.json",
        help="model file of the baseline (default: identify one from the record)",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True, help="findings as JSON")
    parser.add_argument("--plots", metavar="DIR", help="write the diagnosis figure (PNG)")
    parser.add_argument(
        "--fmu-dir", metavar="DIR",
        help="where the augmented model file and its FMUs go (default: next to OUT.json)",
    )  # fmt: skip
    parser.add_argument("--gauge", metavar="G", help="gauge to diagnose (default: the model's, "
                        "else 3F if logged, else the first)")  # fmt: skip
    parser.add_argument(
        "--input", choices=("command", "reconstructed"), default="command",
        help="drive the models with the commanded opening (default) or the reconstructed ramp",
    )  # fmt: skip
    add_spread_arguments(parser, "diagnose the records")


def add_spread_arguments(parser: argparse.ArgumentParser, verb: str, *,
                         every_cpu: bool = False) -> None:  # fmt: skip
    """``--workers N`` and ``--scheduler ADDRESS``: where the records' tasks run (by default
    here, one after another; ``every_cpu``: on a process per CPU)."""
    # None: a process per CPU, counted when the settings are made (not while parsing)
    default, said = (None, "the CPUs this process may use") if every_cpu else (
        1, "1: record after record in this process")  # fmt: skip
    parser.add_argument(
        "--workers", metavar="N", type=int, default=default,
        help=f"{verb} on N local processes, one task each (default {said}; the same "
        "outputs with any N)",
    )  # fmt: skip
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help=f"{verb} one record per task on this dask.distributed scheduler "
        "(tcp://host:8786); the workers must read the input files by the same paths",
    )  # fmt: skip


def spread_settings(args: argparse.Namespace, verb: str) -> Any:
    """The :class:`~gatetwin.fleet.execute.FleetSettings` of ``--workers``/``--scheduler``;
    ``None`` for record after record in this process."""
    if args.workers is None:  # the default of a command that spreads over every CPU
        from gatetwin.fleet.execute import default_workers

        args.workers = 1 if args.scheduler else default_workers()
    if args.workers < 1:
        raise GatetwinError(f"--workers: expected a whole number >= 1, got {args.workers}")
    if args.scheduler and args.workers != 1:
        raise GatetwinError(f"--workers applies to a local run; the dask workers {verb} the "
                            "records when --scheduler is given")  # fmt: skip
    if not args.scheduler and args.workers == 1:
        return None
    from gatetwin.fleet.execute import FleetSettings

    return FleetSettings(scheduler=args.scheduler, workers=args.workers)


def _describe(result: dict) -> list[str]:
    lines = [
        f"{result['record']} gauge {result['gauge']}: named effect {result['named_effect']}",
        f"noise floor {result['noise_floor_mm']:.2f} mm; RMSE {result['rmse_before_mm']:.2f} -> "
        f"{result['rmse_after_mm']:.2f} mm; gap {result['gap_mm']['before']['all']:.2f} -> "
        f"{result['gap_mm']['after']['all']:.2f} mm",
        f"{len(result['windows'])} window(s) where the baseline's residual exceeds the noise floor",
    ]
    for c in result["candidates"]:
        if c.get("score") is None:
            lines.append(f"  {c['effect']:22s} not fitted: {c['not_fitted']}")
            continue
        verdict = "significant" if c["significant"] else "not significant"
        if c["immaterial_because"]:
            verdict += f", immaterial ({c['immaterial_because']})"
        lines.append(f"  {c['effect']:22s} score {c['score']:9.1f}  RMSE {c['rmse_mm']:.2f} mm  "
                     f"{verdict}")  # fmt: skip
    return lines


def _diagnoses(args: argparse.Namespace, fmu_dir: Path) -> list[dict[str, Any]]:
    from gatetwin.diagnosis import DiagnosisSettings, diagnose_record
    from gatetwin.diagnosis.spread import DiagnoseTask, diagnose_records

    settings = DiagnosisSettings(gauge=args.gauge, input=args.input)
    spread = spread_settings(args, "diagnose")
    if spread is None:
        return [diagnose_record(record, args.model, plots_dir=args.plots, fmu_dir=fmu_dir,
                                settings=settings) for record in args.record]  # fmt: skip
    tasks = [DiagnoseTask(record, args.model, args.plots, str(fmu_dir), settings)
             for record in args.record]  # fmt: skip
    return diagnose_records(tasks, spread, progress=_to_stderr)


def _to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def run_diagnose(args: argparse.Namespace) -> int:
    out = Path(args.json)
    fmu_dir = Path(args.fmu_dir) if args.fmu_dir else out.parent
    results = _diagnoses(args, fmu_dir)
    doc = results[0] if len(results) == 1 else {"diagnoses": results}
    try:
        write_json_atomic(out, doc)
    except OSError as exc:
        raise GatetwinError(f"{out}: cannot write ({exc.strerror or exc})") from None
    for result in results:
        print("\n".join(_describe(result)))
        for path in [result["augmented_model"], *(f["path"] for f in result["fmus"]),
                     *result["plots"]]:  # fmt: skip
            if path:
                print(f"wrote {path}")
    print(f"wrote {out}")
    return 0
