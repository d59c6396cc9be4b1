"""Argument parsing and printing of ``gatetwin swmm ...`` (no logic)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from gatetwin.errors import GatetwinError

__all__ = ["DEMO_DEFAULT", "add_swmm_arguments", "run_swmm", "run_swmm_demo", "run_swmm_experiment"]


def add_swmm_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="swmm_command", metavar="SUBCOMMAND", required=True,
                                parser_class=type(parser))  # fmt: skip
    exp = sub.add_parser(
        "experiment", help="run experiments on an EPA SWMM model and write them as records",
        description="Run experiments on a gate of an EPA SWMM model (pyswmm, the swmm extra) "
        "and write them as records (CSV + JSON sidecar), sized from the plant's own time "
        "constant measured by a first step test.",
    )  # fmt: skip
    exp.add_argument("model", metavar="MODEL.inp", help="SWMM input file (metric units)")
    exp.add_argument("--gate", metavar="LINK", required=True,
                     help="the gate: an [ORIFICES] link, SIDE, RECT_CLOSED")  # fmt: skip
    exp.add_argument(
        "--gauges", metavar="NODE=DIST", nargs="+", required=True,
        help="gauge nodes and their distances upstream of the gate, m (the first nearest the "
        "gate is the level the step test measures)",
    )  # fmt: skip
    exp.add_argument("--inflow", metavar="NODE", nargs="+", required=True,
                     help="node(s) receiving the inflow")  # fmt: skip
    exp.add_argument(
        "--design", choices=("static", "step", "prbs", "free", "all"), required=True,
        help="what to write; all: the whole records folder",
    )  # fmt: skip
    exp.add_argument("--out", metavar="DIR", required=True, help="directory to write into")
    _add_recording_arguments(exp)
    exp.add_argument("--opening", type=float, metavar="MM",
                     help="base opening, mm (default: the one the model's rules hold the "
                     "gate at, else half the orifice height)")  # fmt: skip

    _add_demo_arguments(sub)


#: The demo's default gate: check 1 of ASCE test canal 1, its pool (100 m) answering a gate
#: step in minutes (T = 517 s, measured), so the whole demo runs in a few minutes.
DEMO_DEFAULT = {"gate": "G1", "gauges": ["P1_2=0", "P1_1=50", "P1_0=100"], "inflow": ["P1_0"]}


def _add_demo_arguments(sub: Any) -> None:
    demo = sub.add_parser(
        "demo", help="experiments, models, FMUs, validation and MPC vs PI on a SWMM check gate",
        description="On a gate of an EPA SWMM model: run the experiments, identify the models, "
        "export the FMUs, validate them on held-out records and close the loop with the MPC "
        "and the PI designed on the twin; DIR/demo.json, summary.md, records/, models/, "
        "fmus/, validation.json, loops/. Default: check 1 (G1) of the shipped ASCE test "
        "canal 1, whose 100 m pool answers in minutes.",
    )  # fmt: skip
    demo.add_argument("--inp", metavar="MODEL.inp",
                      help="SWMM input file (default: the shipped ASCE test canal 1)")  # fmt: skip
    demo.add_argument("--gate", metavar="LINK", help="the gate (default with the shipped "
                      "model: G1)")  # fmt: skip
    demo.add_argument("--gauges", metavar="NODE=DIST", nargs="+",
                      help="gauge nodes and distances upstream of the gate, m (the first "
                      "nearest the gate is the controlled level)")  # fmt: skip
    demo.add_argument("--inflow", metavar="NODE", nargs="+", help="node(s) receiving the inflow")
    demo.add_argument("--out", metavar="DIR", required=True, help="output folder (replaced "
                      "only if an earlier run wrote it)")  # fmt: skip
    _add_recording_arguments(demo)
    demo.add_argument("--opening", type=float, metavar="MM",
                      help="base opening, mm (default: the model's rule for the gate, else "
                      "half the orifice height)")  # fmt: skip


def _add_recording_arguments(parser: Any) -> None:
    """The options of how SWMM's records are logged, shared by ``experiment`` and ``demo``."""
    parser.add_argument("--sample-period", type=float, default=10.0, metavar="S",
                        help="sample period, s (default 10)")  # fmt: skip
    parser.add_argument("--noise-mm", type=float, default=3.0,
                        help="gauge noise standard deviation, mm (default 3)")  # fmt: skip
    parser.add_argument("--gate-speed-mm-s", type=float, default=5.0,
                        help="actuator speed, mm/s (default 5)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    parser.add_argument(
        "--flow",
        type=float,
        metavar="M3S",
        help="base inflow, m³/s (default: the .inp's constant inflow there)",
    )


def run_swmm(args: argparse.Namespace) -> int:
    """Run the ``swmm`` subcommand named on the command line."""
    return {"experiment": run_swmm_experiment, "demo": run_swmm_demo}[args.swmm_command](args)


def run_swmm_demo(args: argparse.Namespace) -> int:
    from gatetwin.plants.swmm import SwmmPlantSpec
    from gatetwin.run.swmm_demo import DemoRequest, run_swmm_demo

    if args.inp is None:
        given = [k for k in DEMO_DEFAULT if getattr(args, k) is not None]
        if given:
            raise GatetwinError(f"--{given[0]} without --inp: the shipped model's gate is fixed")
        from gatetwin.bundled import bundled_swmm_model

        args.inp = str(bundled_swmm_model())
        for key, value in DEMO_DEFAULT.items():
            setattr(args, key, value)
    missing = [k for k in DEMO_DEFAULT if getattr(args, k) is None]
    if missing:
        raise GatetwinError(f"--inp {args.inp}: give --{' --'.join(missing)}")
    if not (args.noise_mm >= 0):
        raise GatetwinError(f"--noise-mm: expected >= 0 mm, got {args.noise_mm}")
    spec = SwmmPlantSpec(
        Path(args.inp), args.gate, _gauges(args.gauges), tuple(args.inflow),
        gate_speed_mm_s=args.gate_speed_mm_s, sample_period_s=args.sample_period,
        steady_tolerance_mm=max(args.noise_mm / 10.0, 0.1),
    )  # fmt: skip
    req = DemoRequest(spec, Path(args.out), flow_m3s=args.flow, opening_mm=args.opening,
                      noise_mm=args.noise_mm, seed=args.seed)  # fmt: skip
    doc = run_swmm_demo(req, progress=_progress)
    for stage, seconds in doc["times_s"].items():
        print(f"{stage}: {seconds:.1f} s")
    verdict = "passed" if doc["validation"]["passed"] else "FAILED on some held-out record"
    print(f"validation {verdict}; wrote {args.out}/demo.json and summary.md")
    return 0


def _gauges(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        node, sep, dist = item.rpartition("=")
        try:
            out[node] = float(dist)
        except ValueError:
            node = ""
        if not (sep and node):
            raise GatetwinError(f"--gauges: {item!r}; expected NODE=DISTANCE_M")
    return out


def run_swmm_experiment(args: argparse.Namespace) -> int:
    from gatetwin.plants.swmm import SwmmCore, SwmmPlantSpec
    from gatetwin.plants.swmm_designs import run_design
    from gatetwin.plants.swmm_experiments import write_outputs

    if not (args.noise_mm >= 0):
        raise GatetwinError(f"--noise-mm: expected >= 0 mm, got {args.noise_mm}")
    spec = SwmmPlantSpec(
        Path(args.model), args.gate, _gauges(args.gauges), tuple(args.inflow),
        gate_speed_mm_s=args.gate_speed_mm_s, sample_period_s=args.sample_period,
        steady_tolerance_mm=max(args.noise_mm / 10.0, 0.1),
    )  # fmt: skip
    core = SwmmCore(spec)
    flow_m3s = core.base_flow_m3s if args.flow is None else args.flow
    if not flow_m3s > 0:
        raise GatetwinError(f"{spec.inp_path.name}: no constant inflow at "
                            f"{', '.join(spec.inflow_nodes)}; give --flow")  # fmt: skip
    clock = time.perf_counter()
    try:
        opening = core.base_opening_mm(args.opening)
        outputs, base = run_design(core, args.design, opening, 3600.0 * flow_m3s,
                                   noise_mm=args.noise_mm, seed=args.seed,
                                   progress=_progress)  # fmt: skip
    finally:
        core.close()
    paths = write_outputs(Path(args.out), outputs)
    wall = time.perf_counter() - clock
    r = base.response
    print(f"step response at {spec.output_node}: K = {r.gain_mm_per_mm:.4g} mm/mm, "
          f"T = {r.time_constant_s:.0f} s, L = {r.dead_time_s:.0f} s")  # fmt: skip
    for path in paths:
        print(f"wrote {path} and its sidecar")
    print(f"wall time {wall:.1f} s for {len(paths)} record(s)")
    return 0


def _progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
