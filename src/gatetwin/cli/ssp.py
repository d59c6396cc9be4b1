"""Argument parsing and printing of ``ssp`` and ``simulate-ssp`` (no logic)."""

from __future__ import annotations

import argparse
from dataclasses import replace

from gatetwin._io import check_writable
from gatetwin.errors import GatetwinError

__all__ = ["add_simulate_ssp_arguments", "add_ssp_arguments", "run_simulate_ssp", "run_ssp"]


def add_ssp_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "model", metavar="MODEL.json",
        help="FOPDT model file (with --observe, also a physical model)",
    )  # fmt: skip
    parser.add_argument("--out", metavar="LOOP.ssp", required=True, help="the package to write")
    parser.add_argument(
        "--controller", choices=("pi", "mpc"),
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
        "--minutes", type=float,
        help="length of the demo's setpoint_steps scenario, simulated minutes (default 30, "
        "or six spans of the MPC's horizon where longer: a pool that settles in hours)",
    )  # fmt: skip
    parser.add_argument(
        "--observe", metavar="RECORD.csv",
        help="instead of the loop, pack the observer FMU on this record: a scenario component "
        "plays its level, opening and discharge sample by sample (as gatetwin observe feeds "
        "them); simulate-ssp logs the observer's outputs",
    )  # fmt: skip
    parser.add_argument(
        "--gauge", metavar="G",
        help="with --observe: the gauge whose level is observed (default: the model's)",
    )  # fmt: skip


#: The options of the closed loop, which ``--observe`` (a system without a loop) refuses.
LOOP_OPTIONS = ("controller", "horizon", "observer", "minutes")


def run_ssp(args: argparse.Namespace) -> int:
    from gatetwin.fmu.controller import check_controller_kind
    from gatetwin.fmu.controller_settings import demo_minutes, demo_settings
    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc.demo import demo_scenarios
    from gatetwin.ssp import write_ssp

    if args.observe is not None:
        return _run_observe_ssp(args)
    if args.gauge is not None:
        raise GatetwinError("--gauge applies to --observe")
    controller = args.controller or "pi"
    check_controller_kind(controller)
    if args.horizon is not None and controller != "mpc":
        raise GatetwinError("--horizon applies to --controller mpc")
    model = read_model_file(args.model)
    settings = demo_settings(model)
    if args.horizon is not None:
        settings = replace(settings, mpc=replace(settings.mpc, horizon=args.horizon))
    check_writable(args.out)
    try:
        minutes = demo_minutes(settings) if args.minutes is None else args.minutes
        scenario = demo_scenarios(minutes, settings)[0]
    except GatetwinError as exc:
        raise GatetwinError(f"--minutes: {exc}") from None
    path = write_ssp(model, args.out, controller=controller, scenario=scenario,
                     settings=settings, observer=args.observer,
                     without_effects=args.without_effects)  # fmt: skip
    print(f"wrote {path}")
    return 0


def _run_observe_ssp(args: argparse.Namespace) -> int:
    from gatetwin.modelfile import read_model_file
    from gatetwin.records import read_record
    from gatetwin.ssp import write_observer_ssp

    given = [f"--{n}" for n in LOOP_OPTIONS if getattr(args, n) is not None
             and getattr(args, n) is not False]  # fmt: skip
    if given:
        raise GatetwinError(f"{given[0]} applies to the closed loop, not to --observe")
    model = read_model_file(args.model)
    record = read_record(args.observe)
    check_writable(args.out)
    path = write_observer_ssp(model, record, args.out, gauge=args.gauge,
                              without_effects=args.without_effects)  # fmt: skip
    print(f"wrote {path}: the observer on {len(record.time_s)} samples of {args.observe}")
    return 0


def add_simulate_ssp_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("ssp", metavar="LOOP.ssp", help="SSP 1.0 package (gatetwin ssp)")
    parser.add_argument("--out", metavar="RESULT.csv", required=True,
                        help="one row per communication point")  # fmt: skip
    parser.add_argument(
        "--step-size", metavar="SECONDS", type=float,
        help="communication step (default: a component's sample_period_s, else the FMUs' "
        "default experiment step, e.g. the controller's or the observer's sample period)",
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
    from gatetwin.diagnosis.onset import detection
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
    elif "observer.anomaly" in run.columns:
        rises = detection(run.time_s, run.columns["observer.anomaly"], None).false_alarms
        print(f"observer over {run.time_s.size} steps of {run.step_s:g} s: anomaly flag rose "
              f"{rises} times")  # fmt: skip
    print(f"wrote {args.out}")
    return 0
