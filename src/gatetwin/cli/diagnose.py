"""The ``gatetwin diagnose`` subcommand: arguments and run (the logic is in gatetwin.diagnose)."""

from __future__ import annotations

import argparse
from pathlib import Path

from gatetwin._io import write_json_atomic
from gatetwin.errors import GatetwinError


def add_diagnose_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("record", metavar="RECORD.csv", help="measured record (CSV)")
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


def run_diagnose(args: argparse.Namespace) -> int:
    from gatetwin.diagnose import DiagnosisSettings, diagnose_record

    out = Path(args.json)
    fmu_dir = Path(args.fmu_dir) if args.fmu_dir else out.parent
    settings = DiagnosisSettings(gauge=args.gauge, input=args.input)
    result = diagnose_record(args.record, args.model, plots_dir=args.plots, fmu_dir=fmu_dir,
                             settings=settings)  # fmt: skip
    try:
        write_json_atomic(out, result)
    except OSError as exc:
        raise GatetwinError(f"{out}: cannot write ({exc.strerror or exc})") from None
    print("\n".join(_describe(result)))
    for path in [result["augmented_model"], *(f["path"] for f in result["fmus"]),
                 *result["plots"], str(out)]:  # fmt: skip
        if path:
            print(f"wrote {path}")
    return 0
