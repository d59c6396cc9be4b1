"""Routine operation histories: accuracy of K and T against the flume's truth, and cost.

Generates a district's week-long histories (``gatetwin flume --district N --routine mixed``
does the same) or reads an existing folder, identifies every gate with
:func:`gatetwin.identification.routine.identify_routine`, and prints per gate the relative errors
of the overall K and T against the median truth of the windows used, the share of windows
within 10 % on both, and the simulated time per wall second of generation and of
identification.

    python benchmarks/bench_routine.py --gates 20 --days 7
    python benchmarks/bench_routine.py --records DIR     # a folder written by gatetwin flume

``--save`` keeps the numbers in ``docs/results/routine.json`` for the many-gates page.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.fleet.district import GAUGE, GateTruth
from gatetwin.fleet.routine import routine_flume, write_routine_district
from gatetwin.flume.routine import local_fopdt
from gatetwin.identification.routine import identify_routine
from gatetwin.records import read_record

BAND = 0.10


def _truth_of(moves: list[dict], cfg, w) -> tuple[float, float]:
    for m in moves:
        if (w.n_moves == 1 and abs(m["time_s"] - w.onset_time_s) < 2.5
                and m["opening_from_mm"] == w.opening_before_mm
                and m["opening_to_mm"] == w.opening_after_mm):  # fmt: skip
            return m["gain_mm_per_mm"], m["time_constant_s"]
    local = local_fopdt(cfg, w.flow_m3h, w.opening_before_mm, w.opening_after_mm, GAUGE)
    return local.gain_mm_per_mm, local.time_constant_s


def evaluate(folder: Path) -> list[dict]:
    district = json.loads((folder / "truth.json").read_text())
    rows = []
    for entry in district["gates"]:
        gate = GateTruth(**{k: entry[k] for k in GateTruth.__dataclass_fields__})
        truth = json.loads((folder / gate.gate / "truth.json").read_text())
        t0 = time.perf_counter()
        record = read_record(folder / gate.gate / "routine.csv")
        try:
            ident = identify_routine(record)
        except IdentificationError as exc:  # reported, the other gates go on
            rows.append({"gate": gate.gate, "control": entry["control"], "error": str(exc)})
            continue
        wall = time.perf_counter() - t0
        used = [w for w in ident.windows if not w.closed_loop] or list(ident.windows)
        cfg = routine_flume(gate)
        tr = np.array([_truth_of(truth["routine"]["moves"], cfg, w) for w in used])
        est = np.array([(w.gain_mm_per_mm, w.time_constant_s) for w in used])
        rel = np.abs(est / tr - 1.0)
        rows.append({
            "gate": gate.gate, "control": entry["control"], "moves": ident.n_moves,
            "windows": len(ident.windows), "used": len(used),
            "K": ident.overall["gain_mm_per_mm"], "K_true": float(np.median(tr[:, 0])),
            "T": ident.overall["time_constant_s"], "T_true": float(np.median(tr[:, 1])),
            "windows_in_band": float(np.mean(np.all(rel <= BAND, axis=1))),
            "identify_s": wall, "history_s": float(record.time_s[-1] - record.time_s[0]),
        })  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gates", type=int, default=20)
    parser.add_argument("--days", type=float, default=7.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--records", type=Path, help="an existing routine district folder")
    parser.add_argument(
        "--save", action="store_true", help="keep the numbers in docs/results/routine.json"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.records
        gen_s = None
        if folder is None:
            folder = Path(tmp)
            t0 = time.perf_counter()
            write_routine_district(args.gates, folder, seed=args.seed, control="mixed",
                                   days=args.days)  # fmt: skip
            gen_s = time.perf_counter() - t0
        rows = evaluate(folder)
    data = {"gates": len(rows), "days": args.days, "seed": args.seed, "generation_s": gen_s,
            "rows": rows}  # fmt: skip
    print(report(data))
    if args.save:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from results import save

        print(save("routine", data, "python benchmarks/bench_routine.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


def report(data: dict) -> str:
    """Accuracy per gate and cost as Markdown (printed, and the many-gates page's block)."""
    rows = data["rows"]
    lines = ["| gate | control | moves | windows (used) | K / truth | T / truth | "
             "windows in 10 % |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    ok = []
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['gate']} | {r['control']} | | | | | {r['error']} |")
            ok.append(False)
            continue
        ek, et = r["K"] / r["K_true"] - 1.0, r["T"] / r["T_true"] - 1.0
        ok.append(max(abs(ek), abs(et)) <= BAND)
        lines.append(
            f"| {r['gate']} | {r['control']} | {r['moves']} | {r['windows']} ({r['used']}) | "
            f"{r['K']:.2f} / {r['K_true']:.2f} ({ek:+.1%}) | {r['T']:.1f} / {r['T_true']:.1f} "
            f"({et:+.1%}) | {r['windows_in_band']:.0%} |"
        )
    done = [r for r in rows if "error" not in r]
    history = sum(r["history_s"] for r in done)
    identify_s = sum(r["identify_s"] for r in done)
    text = (f"\n\nGates with K and T both within 10 %: {sum(ok)} / {len(ok)}. "
            f"Identification (read, windows, fits): {identify_s / len(done):.2f} s a gate, "
            f"{history / identify_s:,.0f}× real time")  # fmt: skip
    if data.get("generation_s") is not None:
        gen_s = data["generation_s"]
        text += (f"; generation (flume, logger, truth, CSV): {gen_s / len(rows):.1f} s a gate, "
                 f"{history / gen_s:,.0f}× real time")  # fmt: skip
    return "\n".join(lines) + text + ".\n"


if __name__ == "__main__":
    main()
