"""The envelope criterion over a run's validation matrix: which FMU × record pairs meet it.

    gatetwin run --out DIR
    python benchmarks/envelope_criterion.py DIR/validation.json [--backend c]

Criterion (per pair, through fmpy): free-run fit >= 90 %, or within 5 points of the record's
noise-floor fit at the FMU's gauge (``fit_vs_floor >= -5``), with |bias| <= 3 mm; a pair left
unscored (outside validity, or the run failed) misses it. Prints one Markdown table of fit %
(✗ where the criterion is missed), a noise-floor row per gauge, and the counts per backend.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

FIT_MIN, FLOOR_MARGIN, BIAS_MAX_MM = 90.0, -5.0, 3.0


def meets(cell: dict[str, Any]) -> bool:
    """Whether one validation cell meets the envelope criterion."""
    fit, vs_floor, bias = cell.get("fit_percent"), cell.get("fit_vs_floor"), cell.get("bias_mm")
    if cell.get("failure_cause") or fit is None or bias is None or not math.isfinite(fit):
        return False
    close = fit >= FIT_MIN or (vs_floor is not None and vs_floor >= FLOOR_MARGIN)
    return close and abs(bias) <= BIAS_MAX_MM


def table(cells: list[dict[str, Any]]) -> str:
    """Fit % per FMU (rows) and record (columns), ✗ on misses, then each gauge's floor."""
    records = sorted({c["record"] for c in cells})
    by_fmu: dict[str, dict[str, dict[str, Any]]] = defaultdict(dict)
    floors: dict[str, dict[str, float]] = defaultdict(dict)
    for c in cells:
        by_fmu[c["fmu"]][c["record"]] = c
        if c.get("noise_floor_fit_percent") is not None:
            floors[c["gauge"]][c["record"]] = c["noise_floor_fit_percent"]
    lines = ["| FMU | " + " | ".join(records) + " |", "|---" * (len(records) + 1) + "|"]
    for fmu in sorted(by_fmu):
        row = [f"{by_fmu[fmu][r]['fit_percent']:.1f}" + ("" if meets(by_fmu[fmu][r]) else " ✗")
               if r in by_fmu[fmu] else "–" for r in records]  # fmt: skip
        lines.append(f"| {fmu} | " + " | ".join(row) + " |")
    for gauge in sorted(floors):
        row = [f"{floors[gauge][r]:.1f}" if r in floors[gauge] else "–" for r in records]
        lines.append(f"| *floor at {gauge}* | " + " | ".join(row) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("validation", type=Path, help="validation.json of a gatetwin run")
    parser.add_argument("--backend", default="c", help="backend whose table is printed")
    args = parser.parse_args()
    cells = json.loads(args.validation.read_text(encoding="utf-8"))["matrix"]
    print(table([c for c in cells if c["backend"] == args.backend]))
    print()
    for backend in sorted({c["backend"] for c in cells}):
        mine = [c for c in cells if c["backend"] == backend]
        missed = [f"{c['fmu']} × {c['record']} (fit {c.get('fit_percent')} %, floor "
                  f"{c.get('noise_floor_fit_percent')} %, bias {c.get('bias_mm')} mm, "
                  f"{c.get('failure_cause') or 'scored'})"
                  for c in mine if not meets(c)]  # fmt: skip
        print(f"{backend}: {len(mine) - len(missed)} of {len(mine)} pairs meet the criterion"
              + ("; missed: " + "; ".join(missed) if missed else ""))  # fmt: skip


if __name__ == "__main__":
    main()
