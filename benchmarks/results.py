"""Measured numbers for the README and docs, kept in files so that a page cannot go stale.

A run or a benchmark writes its numbers into ``docs/results/NAME.json`` together with the
machine, the date and the command that produced them; the pages carry the tables rendered
from those files between two markers::

    <!-- generated: NAME.BLOCK -->
    ...rendered text...
    <!-- end generated -->

``python benchmarks/results.py collect-run OUT`` keeps the numbers of a ``gatetwin run
--out OUT`` (its ``mpc.json`` and stage times) in ``docs/results/run.json``;
``python benchmarks/results.py render`` rewrites every block from the files, and
``--check`` only says which blocks differ (``tests/docs/test_generated_numbers.py`` runs it).
Any other benchmark keeps its numbers with :func:`save`.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
#: The pages whose generated blocks are rendered and checked.
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
BLOCK = re.compile(
    r"(<!-- generated: (?P<file>[\w-]+)\.(?P<block>[\w-]+) -->\n)(?P<body>.*?)"
    r"(<!-- end generated -->)",
    re.S,
)


def machine() -> dict[str, Any]:
    """What the numbers were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "system": platform.platform(),
            "python": platform.python_version()}  # fmt: skip


def save(name: str, data: dict[str, Any], command: str) -> Path:
    """Keep ``data`` as ``docs/results/<name>.json`` with machine, date and command."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    doc = {"command": command, "date": datetime.date.today().isoformat(),
           "machine": machine(), "data": data}  # fmt: skip
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def load(name: str) -> dict[str, Any]:
    return json.loads((RESULTS / f"{name}.json").read_text(encoding="utf-8"))


def _provenance(doc: dict[str, Any]) -> str:
    m = doc["machine"]
    return (f"(measured by `{doc['command']}` on {doc['date']}, {m['cores']} cores, "
            f"{m['cpu']}, Python {m['python']})")  # fmt: skip


def _run_mpc(doc: dict[str, Any]) -> str:
    from gatetwin.run.stages import mpc_table

    return mpc_table(doc["data"]["mpc"]) + "\n" + _provenance(doc) + "\n"


def _run_stages(doc: dict[str, Any]) -> str:
    stages = doc["data"]["stage_seconds"]
    lines = ["| stage | s |", "|---|---|"]
    lines += [f"| {name} | {seconds:.1f} |" for name, seconds in stages.items()]
    # the stages of a group overlap: the run's total, where the file has it
    total = doc["data"].get("total_seconds", sum(stages.values()))
    lines.append(f"| **total** | {total:.1f} |")
    return "\n".join(lines) + "\n\n" + _provenance(doc) + "\n"


def _run_envelope(doc: dict[str, Any]) -> str:
    """The single-point and the envelope MPC side by side on ``wide_range``, per plant."""
    scenarios = doc["data"]["mpc"]["scenarios"]
    keys = ("iae", "overshoot_mm", "settling_s", "travel_mm", "gate_reversals_per_hour",
            "violations")  # fmt: skip
    lines = ["| plant | IAE (mm·s) | overshoot (mm) | settling (s) | gate travel (mm) | "
             "reversals per hour | violations |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for name, runs in scenarios.items():
        if "mpc_envelope" not in runs:
            continue
        cells = [" / ".join(f"{runs[c][k]:.4g}" for c in ("mpc", "mpc_envelope")) for k in keys]
        lines.append(f"| {name.removesuffix('_wide_range')} | " + " | ".join(cells) + " |")
    return ("single-point / envelope MPC, same plant and noise:\n\n" + "\n".join(lines)
            + "\n\n" + _provenance(doc) + "\n")  # fmt: skip


def _run_families(doc: dict[str, Any]) -> str:
    """Free runs per record: the local FOPDT, the envelope FOPDT and the physical model."""
    families = ("local FOPDT", "envelope FOPDT", "physical")
    lines = ["| record | floor fit % | "
             + " | ".join(f"{f}: fit % / RMSE / bias (mm)" for f in families) + " |",
             "|---|---|" + "---|" * len(families)]  # fmt: skip
    for row in doc["data"]["families"]["rows"]:
        cells = [f"{row[f]['fit_percent']:.1f} / {row[f]['rmse_mm']:.1f} / "
                 f"{row[f]['bias_mm']:+.1f}" for f in families]  # fmt: skip
        lines.append(f"| {row['record']} | {row['noise_floor_fit_percent']:.1f} | "
                     + " | ".join(cells) + " |")  # fmt: skip
    return "\n".join(lines) + "\n\n" + _provenance(doc) + "\n"


def _run_ssp(doc: dict[str, Any]) -> str:
    """The run's SSP of the closed loop against the Python loop on the same FMUs."""
    ssp = doc["data"]["mpc"]["closed_loop_ssp"]
    return (f"On the run's `{ssp['model']}` ({ssp['controller']}, {ssp['scenario']}, "
            f"{ssp['minutes']:g} min, no noise) `simulate-ssp` gives a closed-loop IAE of "
            f"{ssp['iae_ssp']:.6g} mm·s, the Python loop {ssp['iae_python_loop']:.6g} mm·s; "
            f"their levels differ by at most {ssp['max_abs_level_difference_mm']:.3g} mm.\n\n"
            + _provenance(doc) + "\n")  # fmt: skip


def _bench_report(module: str) -> Callable[[dict[str, Any]], str]:
    """A renderer that calls ``report(data)`` of ``benchmarks/<module>.py``, what it prints."""

    def render(doc: dict[str, Any]) -> str:
        if str(Path(__file__).parent) not in sys.path:
            sys.path.insert(0, str(Path(__file__).parent))
        report = __import__(module).report
        return report(doc["data"]) + "\n" + _provenance(doc) + "\n"

    return render


#: Renderers by ``file.block``: the file's JSON in, the block's Markdown out.
RENDERERS: dict[str, Callable[[dict[str, Any]], str]] = {
    "run.mpc": _run_mpc,
    "run.stages": _run_stages,
    "run.envelope": _run_envelope,
    "run.families": _run_families,
    "run.ssp": _run_ssp,
    "controller_fmu.cost": _bench_report("bench_controller_fmu"),
    "fmu_steps.table": _bench_report("bench_fmu"),
    "identify.arx": _bench_report("bench_identify"),
    "mpc_solve.solvers": _bench_report("bench_mpc"),
    "observer.times": _bench_report("bench_observer"),
    "harness.overhead": _bench_report("bench_harness"),
    "routine.gates": _bench_report("bench_routine"),
    "diagnose.cases": _bench_report("bench_diagnose"),
}


def render_page(text: str) -> str:
    """The page with every generated block rendered from its file."""

    def one(match: re.Match[str]) -> str:
        key = f"{match['file']}.{match['block']}"
        if key not in RENDERERS:
            raise KeyError(f"no renderer for generated block {key}")
        return match.group(1) + RENDERERS[key](load(match["file"])) + match.group(5)

    return BLOCK.sub(one, text)


def stale_pages() -> list[str]:
    """Pages whose generated blocks differ from what their files render."""
    texts = {p: p.read_text(encoding="utf-8") for p in PAGES}
    return [str(p.relative_to(ROOT)) for p, text in texts.items() if render_page(text) != text]


def collect_run(out: Path, command: str) -> Path:
    """Keep a ``gatetwin run``'s MPC results and stage times."""
    sys.path.insert(0, str(Path(__file__).parent))
    from bench_run import stage_times, stage_total

    mpc = json.loads((out / "mpc.json").read_text(encoding="utf-8"))
    families = json.loads((out / "families.json").read_text(encoding="utf-8"))
    summary = (out / "summary.md").read_text(encoding="utf-8")
    return save("run", {"mpc": mpc, "families": families, "stage_seconds": stage_times(summary),
                        "total_seconds": stage_total(summary)}, command)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    collect = sub.add_parser("collect-run", help="keep a gatetwin run's numbers")
    collect.add_argument("out", type=Path)
    collect.add_argument("--command", default=None)
    render = sub.add_parser("render", help="render the pages' generated blocks")
    render.add_argument("--check", action="store_true")
    args = parser.parse_args(argv)
    if args.what == "collect-run":
        print(collect_run(args.out, args.command or f"gatetwin run --out {args.out}"))
        return 0
    stale = stale_pages()
    if args.check:
        print("\n".join(f"stale: {p}" for p in stale) or "every generated block is current")
        return 1 if stale else 0
    for page in PAGES:
        page.write_text(render_page(page.read_text(encoding="utf-8")), encoding="utf-8")
    print(f"rendered {len(PAGES)} pages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
