"""The diagnosis on generated records with a hidden effect: rates, gap reduction, parameter
errors and time per case.

Runs the cases of tests/test_diagnose_generated.py (63 by default; ``--cases N``) and prints
the measured rates, then every case that was named wrong or missed a threshold.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from diagnose_cases import case_plan  # noqa: E402
from test_diagnose_generated import rates, run_case  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", type=int, default=63)
    parser.add_argument("--first-seed", type=int, default=1000)
    args = parser.parse_args()
    outcomes, start = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed, effect in case_plan(args.cases, args.first_seed):
            outcomes.append(run_case(seed, effect, Path(tmp)))
    elapsed = time.perf_counter() - start
    for key, value in rates(outcomes).items():
        print(f"{key:24s} {value:.3f}" if isinstance(value, float) else f"{key:24s} {value}")
    print(f"{'seconds_per_case':24s} {elapsed / len(outcomes):.2f}")
    print("per effect: named right / cases, worst and median parameter error, worst gap reduction")
    for effect in sorted({o.truth for o in outcomes}):
        rows = [o for o in outcomes if o.truth == effect]
        errors = sorted(e for o in rows for e in o.parameter_errors.values())
        worst = f"{errors[-1]:.3f}" if errors else "-"
        median = f"{errors[len(errors) // 2]:.3f}" if errors else "-"
        gap = min(o.gap_reduction for o in rows)
        print(
            f"  {effect:22s} {sum(o.right for o in rows)}/{len(rows)}  {worst:>6s} {median:>6s}"
            f"  {gap:.2f}"
        )
    for o in outcomes:
        errors = {k: round(v, 3) for k, v in o.parameter_errors.items()}
        if not o.right or (o.truth != "none" and (o.gap_reduction < 0.5 or not o.parameters_ok)):
            print(
                f"  seed {o.seed}: {o.truth} -> {o.named}, gap reduction "
                f"{o.gap_reduction:.2f}, parameter errors {errors}"
            )


if __name__ == "__main__":
    main()
