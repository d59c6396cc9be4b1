"""The diagnosis on generated records with a hidden effect: rates, gap reduction, parameter
errors and time per case.

Runs the cases of tests/diagnosis/test_diagnose_generated.py (63 by default; ``--cases N``)
and prints the measured rates, the table per effect, then every case that was named wrong or
missed a threshold; ``--save`` keeps them in ``docs/results/diagnose.json`` for the diagnosis page.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", type=int, default=63)
    parser.add_argument("--first-seed", type=int, default=1000)
    parser.add_argument(
        "--save", action="store_true", help="keep the numbers in docs/results/diagnose.json"
    )
    args = parser.parse_args(argv)
    # the cases of the test (imported here, so that rendering the page's block needs none)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from diagnose_cases import case_plan, rates, run_case

    outcomes, start = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed, effect in case_plan(args.cases, args.first_seed):
            outcomes.append(run_case(seed, effect, Path(tmp)))
    elapsed = time.perf_counter() - start
    effects = []
    for effect in sorted({o.truth for o in outcomes}):
        rows = [o for o in outcomes if o.truth == effect]
        errors = sorted(e for o in rows for e in o.parameter_errors.values())
        effects.append({"effect": effect, "right": sum(o.right for o in rows), "cases": len(rows),
                        "worst_parameter_error": errors[-1] if errors else None,
                        "median_parameter_error": errors[len(errors) // 2] if errors else None,
                        "worst_gap_reduction": min(o.gap_reduction for o in rows)})  # fmt: skip
    misses = [{"seed": o.seed, "truth": o.truth, "named": o.named,
               "gap_reduction": o.gap_reduction,
               "parameter_errors": {k: round(v, 3) for k, v in o.parameter_errors.items()}}
              for o in outcomes
              if not o.right or (o.truth != "none"
                                 and (o.gap_reduction < 0.5 or not o.parameters_ok))]  # fmt: skip
    data = {"rates": rates(outcomes), "seconds_per_case": elapsed / len(outcomes),
            "effects": effects, "misses": misses}  # fmt: skip
    print(report(data))
    if args.save:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from results import save

        print(save("diagnose", data, "python benchmarks/bench_diagnose.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


def _pct(share: float, digits: int = 0) -> str:
    return f"{100 * share:.{digits}f} %"


def report(data: dict) -> str:
    """Rates, the table per effect and the misses as Markdown (printed, and the page's block)."""
    r = data["rates"]
    present = r["cases"] - next(e["cases"] for e in data["effects"] if e["effect"] == "none")
    text = (f"{r['cases']} cases: right name {_pct(r['right_name'])}, `none` wrongly flagged "
            f"{_pct(r['none_flagged'])}, gap down ≥ 50 % in {_pct(r['gap_down_50'])} of the "
            f"{present} effect cases (median {_pct(r['median_gap_reduction'])}), parameters "
            f"within 25 % in {_pct(r['parameters_within_25'])} (worst "
            f"{_pct(r['worst_parameter_error'], 1)}); {data['seconds_per_case']:.2f} s a case."
            "\n\n")  # fmt: skip
    lines = ["| effect | named right | worst / median parameter error | worst gap reduction |",
             "|---|---|---|---|"]  # fmt: skip
    for e in data["effects"]:
        worst, median = e["worst_parameter_error"], e["median_parameter_error"]
        errors = "–" if worst is None else f"{_pct(worst, 1)} / {_pct(median, 1)}"
        gap = "–" if e["effect"] == "none" else _pct(e["worst_gap_reduction"])
        lines.append(f"| {e['effect']} | {e['right']}/{e['cases']} | {errors} | {gap} |")
    for m in data["misses"]:
        errors = m["parameter_errors"]
        lines.append(f"\nseed {m['seed']}: {m['truth']} → {m['named']}, gap reduction "
                     f"{m['gap_reduction']:.2f}, parameter errors {errors}")  # fmt: skip
    return text + "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
