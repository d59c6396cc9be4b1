"""Argument parsing and printing of ``ssp`` and ``simulate-ssp`` (no logic)."""

from __future__ import annotations

import argparse
from dataclasses import replace

from gatetwin._io import check_writable
from gatetwin.errors import GatetwinError

__all__ = ["add_simulate_ssp_arguments", "add_ssp_arguments", "run_simulate_ssp", "run_ssp"]


def add_ssp_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL.json", help="FOPDT model file")
    parser.add_argument("--out", metavar="LOOP.ssp", required=True, help="the package to write")
    parser.add_argument(
        "--controller", choices=("pi", "mpc"), default="pi",
        help="controller FMU in the loop: pi (default) or mpc (the demo's single-point MPC)",
    )  # fmt: skip
    parser.add_argument(
        "--horizon", metavar="N", type=int,
        help="mpc: prediction horizon in samples (default: the demo's 100; the build takes "
        "~30 s at 100)",
    )  # fmt: skip
    parser.add_argument(
        "--observer", action="store_true",
        help="also pack the observer FMU, reading the measured level, opening and discharge; "
        "simulate-ssp logs its outputs",
    )  # fmt: skip
    parser.add_argument(
        "--without-effects", action="store_true",
        help="build the MPC and the observer on the model's FOPDT with its effect blocks "
        "dropped (the plant FMU keeps them; such a model is refused otherwise)",
    )  # fmt: skip
    parser.add_argument(
        "--minutes", type=float, default=30.0,
        help="length of the demo's setpoint_steps scenario, simulated minutes (default 30)",
    )  # fmt: skip


def run_ssp(args: argparse.Namespace) -> int:
    from gatetwin.fmu.controller import check_controller_kind
    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc.demo import DemoSettings, demo_scenarios
    from gatetwin.ssp import write_ssp

    check_controller_kind(args.controller)
    settings = DemoSettings()
    if args.horizon is not None:
        if args.controller != "mpc":
            raise GatetwinError("--horizon applies to --controller mpc")
        settings = replace(settings, mpc=replace(settings.mpc, horizon=args.horizon))
    model = read_model_file(args.model)
    check_writable(args.out)
    try:
        scenario = demo_scenarios(args.minutes, settings)[0]
    except GatetwinError as exc:
        raise GatetwinError(f"--minutes: {exc}") from None
    path = write_ssp(model, args.out, controller=args.controller, scenario=scenario,
                     settings=settings, observer=args.observer,
                     without_effects=args.without_effects)  # fmt: skip
    print(f"wrote {path}")
    return 0


def add_simulate_ssp_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("ssp", metavar="LOOP.ssp", help="SSP 1.0 package (gatetwin ssp)")
    parser.add_argument("--out", metavar="RESULT.csv", required=True,
                        help="one row per communication point")  # fmt: skip
    parser.add_argument(
        "--step-size", metavar="SECONDS", type=float,
        help="communication step (default: the controller's sample period)",
    )  # fmt: skip
    parser.add_argument(
        "--timeout", metavar="SECONDS", type=float,
        help="wall-clock limit of each FMI call; the FMUs run in a child process, and one "
        "that exits, crashes or overruns this ends the run with the cause named "
        "(default: 10)",
    )  # fmt: skip
    parser.add_argument(
        "--scheme", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
        help="gauss-seidel (default): the elements stepped in document order, each reading "
        "what those before it gave at this point; jacobi: all stepped on the values of the "
        "point, as engines that step them together do (the controller's move reaches the "
        "plant one sample later)",
    )  # fmt: skip


def run_simulate_ssp(args: argparse.Namespace) -> int:
    from gatetwin.ssp import simulate_ssp

    if args.step_size is not None and not args.step_size > 0:
        raise GatetwinError(f"--step-size: expected a positive number of seconds, got "
                            f"{args.step_size}")  # fmt: skip
    check_writable(args.out)
    run = simulate_ssp(
        args.ssp,
        out_csv=args.out,
        step_size_s=args.step_size,
        timeout_s=args.timeout,
        scheme=args.scheme,
    )
    levels = [c for c in run.columns if c.startswith("controller.level_")]
    if levels and "controller.setpoint_mm" in run.columns:
        iae = run.iae(levels[0], "controller.setpoint_mm")
        print(f"closed-loop IAE {iae:.6g} mm·s over {run.time_s.size} steps of {run.step_s:g} s")
    print(f"wrote {args.out}")
    return 0
