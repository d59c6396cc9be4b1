"""The ``gatetwin`` command: parse arguments, call the library, print.

No logic lives here. Each subcommand is one :class:`Command` in ``_COMMANDS`` (name,
help, a function adding its arguments, a function running it and returning an exit
code); add a subcommand by writing those two functions and one ``Command(...)`` line.

Any :class:`~gatetwin.errors.GatetwinError` (bad input, impossible request) becomes one
line ``gatetwin: error: <message>`` on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from gatetwin._io import undone_on_failure, write_json_atomic
from gatetwin.cli import diagnose as _diagnose_cmds
from gatetwin.cli import model as _model_cmds
from gatetwin.cli import ssp as _ssp_cmds
from gatetwin.cli import swmm as _swmm_cmds
from gatetwin.errors import GatetwinError, RecordError
from gatetwin.records.sidecar import TEST_TYPES
from gatetwin.records.summary import format_record_summary, format_static_summary
from gatetwin.version import __version__

__all__ = ["EXIT_BROKEN_PIPE", "EXIT_ERROR", "Command", "build_parser", "main", "print_to_stderr"]

#: Exit code for a refused input or a failed command.
EXIT_ERROR = 2
#: Exit code when the output's reader closed the pipe (``| head``): a shell's for a command
#: ended by SIGPIPE, 128 + 13, without a message.
EXIT_BROKEN_PIPE = 141


@dataclass(frozen=True)
class Command:
    """One subcommand.

    Attributes
    ----------
    name : str
        The word after ``gatetwin``.
    help : str
        One line for ``gatetwin --help``.
    add_arguments : callable
        Adds the subcommand's arguments to its parser.
    run : callable
        Runs it on the parsed arguments; returns the exit code.
    """

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


def print_to_stderr(message: str) -> None:
    """Progress output: one line on stderr, flushed."""
    print(message, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- check


def _add_check_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", metavar="RECORD.csv", help="time-series record or static table")
    parser.add_argument(
        "--test", choices=TEST_TYPES, help="test type (overrides the sidecar and detection)"
    )
    parser.add_argument(
        "--json", metavar="OUT.json", help="also write the findings as JSON (after success)"
    )
    parser.add_argument(
        "--max-bytes", metavar="N", type=int,
        help="largest record file read, bytes (default: $GATETWIN_MAX_BYTES or 536870912)",
    )  # fmt: skip
    parser.add_argument(
        "--max-line-bytes", metavar="N", type=int,
        help="longest CSV line read, bytes (default: $GATETWIN_MAX_LINE_BYTES or 65536)",
    )  # fmt: skip


def _run_check(args: argparse.Namespace) -> int:
    from gatetwin.records import ReadLimits, detect_table_kind, read_record, read_static_table

    limits = ReadLimits.from_env()
    limits = ReadLimits(
        max_bytes=limits.max_bytes if args.max_bytes is None else args.max_bytes,
        max_line_bytes=(limits.max_line_bytes if args.max_line_bytes is None
                        else args.max_line_bytes),
    )  # fmt: skip
    if detect_table_kind(args.path, limits=limits) == "static":
        if args.test is not None:
            raise RecordError(
                f"{args.path}: --test applies to time-series records, not to a static rating table"
            )
        summary = read_static_table(args.path, limits=limits).summary()
        text = format_static_summary(summary)
    else:
        summary = read_record(args.path, test=args.test, limits=limits).summary()
        text = format_record_summary(summary)
    print(text)
    if args.json:
        _write_json(args.json, summary)
    return 0


def _write_json(path: str, data: object) -> None:
    try:
        write_json_atomic(path, data)
    except OSError as exc:
        raise GatetwinError(f"{path}: cannot write ({exc.strerror or exc})") from None


# --------------------------------------------------------------------------- run


def _add_run_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out",
        metavar="DIR",
        default="gatetwin-out",
        help="output directory, replaced only after success (default: gatetwin-out)",
    )
    _diagnose_cmds.add_spread_arguments(
        parser, "identify the gauges, export, validate the FMUs, run the MPC demo's plants "
        "and diagnose the records", every_cpu=True)  # fmt: skip


def _run_run(args: argparse.Namespace) -> int:
    from gatetwin.run.pipeline import run_pipeline

    fleet = _diagnose_cmds.spread_settings(args, "identify, validate and diagnose")
    out = run_pipeline(Path(args.out), progress=print_to_stderr, fleet=fleet)
    print_to_stderr(f"wrote {out}")
    return 0


# --------------------------------------------------------------------------- flume


def _add_flume_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", required=True, help="directory to write into")
    parser.add_argument(
        "--scenario", metavar="FILE",
        help="run a scenario described in JSON or TOML instead of the reference suite",
    )  # fmt: skip
    parser.add_argument(
        "--only", metavar="NAME", nargs="+", default=(),
        help="reference records to write (A B C D Q40 Q50 Q60 Q85 Q55, the validation "
        "records Emoves35 Emoves75 EflowLow EflowHigh Eboth Erandom60, static); default all",
    )  # fmt: skip
    parser.add_argument(
        "--district", metavar="N", type=int,
        help="instead, generate a synthetic district of N gates around the calibrated flume: "
        "one folder of records per gate, each with its truth.json, and truth.json for all",
    )  # fmt: skip
    parser.add_argument(
        "--routine", metavar="CONTROL", choices=("schedule", "pi", "mixed"),
        help="with --district: instead of step tests, one routine operation history per gate "
        "(routine.csv: the gate moved by an operator's schedule, by a PI level controller, or "
        "mixed: every fourth gate under the controller), with the flume's K, T at every move "
        "in truth.json",
    )  # fmt: skip
    parser.add_argument(
        "--days", type=float, default=7.0, help="length of a routine history, days (default 7)"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the district's draws (default 0)"
    )
    parser.add_argument(
        "--workers", metavar="N", type=int, default=1,
        help="local processes generating the district's gates (default 1)",
    )  # fmt: skip


def _run_flume(args: argparse.Namespace) -> int:
    from gatetwin.flume.experiments import (
        load_scenario,
        reference_scenarios,
        run_scenario,
        write_reference_records,
    )

    if args.district is not None:
        with undone_on_failure(args.out):
            return _run_district(args)
    if args.routine is not None:
        raise GatetwinError("--routine applies with --district N")
    if args.scenario:
        scn = load_scenario(args.scenario)
        with undone_on_failure(args.out):
            path = run_scenario(scn).write(Path(args.out) / f"{scn.name}.csv")
        print(f"wrote {path} and its sidecar")
        return 0
    known = {s.name for s in reference_scenarios()} | {"static"}
    unknown = sorted(set(args.only) - known)
    if unknown:
        raise GatetwinError(
            f"--only: unknown record(s) {', '.join(unknown)}; expected some of "
            f"{', '.join(sorted(known))}"
        )
    with undone_on_failure(args.out):
        paths = write_reference_records(args.out, progress=print_to_stderr,
                                        only=tuple(args.only))  # fmt: skip
    for path in paths:
        print(f"wrote {path}")
    return 0


def _run_district(args: argparse.Namespace) -> int:
    from gatetwin.fleet import write_district

    if args.scenario or args.only:
        raise GatetwinError("--district generates its own records; drop --scenario and --only")
    if args.district < 1 or args.workers < 1:
        raise GatetwinError("--district and --workers: expected whole numbers >= 1")
    if args.routine is not None:
        return _run_routine_district(args)
    path = write_district(args.district, args.out, seed=args.seed, workers=args.workers,
                          progress=print_to_stderr)  # fmt: skip
    print(f"wrote {args.district} gate folders in {args.out} and {path}")
    return 0


def _run_routine_district(args: argparse.Namespace) -> int:
    from gatetwin.fleet.routine import write_routine_district

    if not 0 < args.days <= 366:
        raise GatetwinError(f"--days: expected a length in (0, 366] days, got {args.days:g}")
    path = write_routine_district(args.district, args.out, seed=args.seed, control=args.routine,
                                  days=args.days, workers=args.workers,
                                  progress=print_to_stderr)  # fmt: skip
    print(f"wrote {args.district} routine histories in {args.out} and {path}")
    return 0


# --------------------------------------------------------------------------- validate


def _add_validate_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("fmu", metavar="FMU", help="FMI 2.0 or 3.0 co-simulation FMU to validate")
    parser.add_argument("records", metavar="RECORD", nargs="+",
                        help="measured record(s) (CSV); a static rating table among them is "
                        "left out")  # fmt: skip
    parser.add_argument("--gauge", metavar="G", help="compare output level_<G>_mm (default: "
                        "the FMU's only level output)")  # fmt: skip
    parser.add_argument(
        "--fail-under", metavar="METRIC=VALUE", action="append", default=[],
        help="fail a record whose METRIC is below VALUE; for fit_percent, r2, ljung_box_p and "
        "fit_vs_floor: the fit minus the record's noise floor in percentage points, the floor "
        "being the fit a perfect model scores against the record's level noise "
        "(fit_vs_floor=-5: fit at least floor - 5 points) (repeatable)",
    )  # fmt: skip
    parser.add_argument(
        "--fail-over", metavar="METRIC=VALUE", action="append", default=[],
        help="fail a record whose METRIC is above VALUE; for rmse_mm, mae_mm, "
        "max_abs_error_mm, abs_bias_mm, gain_abs_diff_mm_per_mm, time_constant_abs_diff_s, "
        "dead_time_abs_diff_s (repeatable)",
    )  # fmt: skip
    parser.add_argument(
        "--fail-outside-validity", action="store_true",
        help="fail a record lying outside the validity envelope the FMU states (opening, "
        "flow, level ranges in its resources/provenance.json); without it such a record is "
        "only warned about on stderr",
    )  # fmt: skip
    parser.add_argument(
        "--timeout", metavar="SECONDS", type=float,
        help="wall-clock limit of the FMU's run on each record; the FMU runs in a child "
        "process, killed at the limit (default: 10 s + 1 ms per FMU step, e.g. 10.75 s for "
        "a 750-sample record)",
    )  # fmt: skip
    parser.add_argument(
        "--workers", metavar="N", type=int, default=1,
        help="validate the records on N local processes, one record per task (default 1: "
        "record after record in this process)",
    )  # fmt: skip
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="validate one record per task on this dask.distributed scheduler "
        "(tcp://host:8786); the FMU travels with each task, no shared folder needed",
    )  # fmt: skip
    parser.add_argument(
        "--map", metavar="MAP.toml",
        help="validate an FMU that is not gatetwin's: a TOML file naming, for each record "
        "column (opening_mm, flow_m3h, level_<G>_mm), the FMU's variable and its unit",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True, help="findings as JSON")
    parser.add_argument("--junit", metavar="OUT.xml", help="findings as JUnit XML for CI")
    parser.add_argument("--plots", metavar="DIR", help="write measured-vs-FMU plots (PNG)")
    parser.epilog = (
        "exit status: 0 when everything passed, 1 when a threshold, fmpy's static "
        "validation, the FMU's run (it crashed, exited, overran --timeout or output NaN or "
        "infinity) or (with --fail-outside-validity) the validity envelope failed, 2 for "
        "input that cannot be validated (also a record whose time stamps would need more "
        "than 1,000,000 FMU steps)"
    )


def _validate(args: argparse.Namespace, thresholds: Any) -> Any:
    """The validation, here record after record, or one record per task elsewhere."""
    from gatetwin.errors import GatetwinError
    from gatetwin.validation import validate_fmu
    from gatetwin.validation.mapping import read_variable_map

    variable_map = read_variable_map(args.map) if args.map else None
    options = dict(gauge=args.gauge, thresholds=thresholds, timeout_s=args.timeout,
                   fail_outside_validity=args.fail_outside_validity,
                   variable_map=variable_map)  # fmt: skip
    if args.workers < 1:
        raise GatetwinError(f"--workers: expected a whole number >= 1, got {args.workers}")
    if args.scheduler and args.workers != 1:
        raise GatetwinError("--workers applies to a local run; the dask workers validate the "
                            "records when --scheduler is given")  # fmt: skip
    if not args.scheduler and args.workers == 1:
        return validate_fmu(args.fmu, args.records, **options)
    from gatetwin.fleet.execute import FleetSettings
    from gatetwin.validation.spread import validate_fmu_spread

    settings = FleetSettings(scheduler=args.scheduler, workers=args.workers)
    return validate_fmu_spread(args.fmu, args.records, settings, progress=print_to_stderr,
                               **options)  # fmt: skip


def _time_series(records: list[str]) -> list[str]:
    """The records to validate: a static rating table among them (a records folder's
    ``*.csv`` holds one) is named on stderr and left out; static tables alone are refused."""
    from gatetwin.errors import GatetwinError
    from gatetwin.records.static import detect_table_kind

    kept = []
    for path in records:
        if detect_table_kind(path) == "static":
            print_to_stderr(f"gatetwin: note: {path} is a static rating table, not a time "
                            "series: not validated")  # fmt: skip
        else:
            kept.append(path)
    if not kept:
        what = "is a static rating table" if len(records) == 1 else "are static rating tables"
        raise GatetwinError(f"no time series to validate: {', '.join(records)} {what}")
    return kept


def _run_validate(args: argparse.Namespace) -> int:
    from gatetwin.validation import (
        EXIT_FAILED,
        OutputPaths,
        matrix_cells,
        matrix_markdown,
        outside_message,
        parse_thresholds,
        write_outputs,
    )

    thresholds = parse_thresholds(args.fail_under, args.fail_over)
    args.records = _time_series(args.records)
    result = _validate(args, thresholds)
    plots = Path(args.plots) if args.plots else None
    junit = Path(args.junit) if args.junit else None
    written = write_outputs(result, OutputPaths(Path(args.json), junit, plots))
    for rec in result.records:
        if rec.failure_cause:
            print_to_stderr(f"gatetwin: {result.fmu.name} on {rec.record}: FMU run failed: "
                            f"{rec.failure_cause}")  # fmt: skip
        if rec.inside_validity is False:
            print_to_stderr(f"gatetwin: warning: {rec.record} lies outside {result.fmu.name}'s "
                            f"validity: {outside_message(rec)}")  # fmt: skip
        if rec.unobserved_steps:
            print_to_stderr(f"gatetwin: warning: {rec.record}: the gate moved inside logging "
                            f"gaps ({rec.unobserved_steps} opening change(s)); the FMU holds "
                            "the last logged opening through them, and the metrics include "
                            "the settling after them")  # fmt: skip
    print(matrix_markdown(matrix_cells(result)), end="")
    for finding in result.static_findings:
        print(f"fmpy static validation: {finding}")
    for path in written:
        print_to_stderr(f"wrote {path}")
    print("passed" if result.passed else "FAILED")
    return 0 if result.passed else EXIT_FAILED


# --------------------------------------------------------------------------- mpc-demo


def _add_mpc_demo_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--plant", choices=("fmu", "flume", "swmm"), default="fmu",
        help="plant in the loop: the exported C FMU through fmpy, the virtual flume, or an "
        "EPA SWMM model (--swmm-plant; the controllers' settings from --model) (default: fmu)",
    )  # fmt: skip
    parser.add_argument(
        "--swmm-plant", metavar="PLANT.json",
        help="--plant swmm: the SWMM plant spec (inp, gate, gauges, inflow, gate_speed_mm_s, "
        "sample_period_s, noise_sd_mm), as 'gatetwin swmm demo' writes it",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True, help="metrics (JSON)")
    parser.add_argument("--plots", metavar="DIR", required=True, help="one PNG per scenario")
    parser.add_argument(
        "--minutes", type=float, default=None,
        help="simulated minutes per scenario (default 30; with --model, six spans of the MPC's "
        "horizon where longer: a pool that settles in hours)",
    )  # fmt: skip
    parser.add_argument(
        "--model", metavar="MODEL.json",
        help="FOPDT model file to control (default: the 3F schedule identified from "
        "the bundled records); a gate whose validity does not hold the flume demo's operating "
        "point gets scenarios, limits and sample period from its own model file",
    )  # fmt: skip
    parser.add_argument("--pi-filter", metavar="S", type=float,
                        help=_model_cmds.PI_FILTER_HELP)  # fmt: skip


def _run_mpc_demo(args: argparse.Namespace) -> int:
    from gatetwin.mpc.demo import load_demo_plant, run_mpc_demo

    if (args.plant == "swmm") != (args.swmm_plant is not None):
        raise GatetwinError("--swmm-plant goes with --plant swmm, and --plant swmm needs it")
    if args.plant == "swmm" and args.model is None:
        raise GatetwinError("--plant swmm: give --model, an FOPDT identified on that model")
    _model_cmds.check_pi_filter(args.pi_filter)
    plant, extra = load_demo_plant(args.model), {}
    if args.plant == "swmm":
        from gatetwin.plants.swmm_loop import mpc_demo_inputs

        extra["settings"], extra["core_factory"] = mpc_demo_inputs(plant, args.swmm_plant)
    elif args.model is not None:
        from gatetwin.fmu.controller_settings import demo_settings
        from gatetwin.modelfile import read_model_file

        extra["settings"] = demo_settings(read_model_file(args.model))
    if args.pi_filter is not None:
        from gatetwin.mpc.demo import DemoSettings

        settings = extra.get("settings") or DemoSettings()
        extra["settings"] = _model_cmds.with_pi_filter(settings, args.pi_filter)
    minutes = args.minutes
    if minutes is None:  # the flume's 30 minutes, longer for a slow gate's own model
        from gatetwin.fmu.controller_settings import DEMO_MINUTES, demo_minutes

        sized = args.model is not None and args.plant != "swmm"
        minutes = demo_minutes(extra["settings"]) if sized else DEMO_MINUTES
    with undone_on_failure(args.plots):  # a run refused half-way leaves no plots behind
        result = run_mpc_demo(
            plant, plant_kind=args.plant, minutes=minutes,
            out_plots_dir=args.plots, progress=print_to_stderr, **extra,
        )  # fmt: skip
        _write_json(args.json, result)
    print(f"wrote {args.json} and the plots in {args.plots}")
    return 0


# --------------------------------------------------------------------------- registry

#: The subcommands, in ``--help`` order. Others (flume, identify, export, validate,
#: mpc-demo, diagnose) are added here as they are written.
_COMMANDS: tuple[Command, ...] = (
    Command(
        "check",
        "read and check a record or static table, and say what is in it",
        _add_check_arguments,
        _run_check,
    ),
    Command(
        "flume",
        "run the virtual flume: write the reference records or a described scenario",
        _add_flume_arguments,
        _run_flume,
    ),
    Command(
        "identify",
        "identify FOPDT (step records) or ARX (PRBS records) models of one record",
        _model_cmds.add_identify_arguments,
        _model_cmds.run_identify,
    ),
    Command(
        "routine",
        "identify FOPDT models from a routine operation history (SCADA log, no designed test)",
        _model_cmds.add_routine_arguments,
        _model_cmds.run_routine,
    ),
    Command(
        "models",
        "identify every model of a records folder and write the model files",
        _model_cmds.add_models_arguments,
        _model_cmds.run_models,
    ),
    Command(
        "export",
        "export a model file as an FMI 2.0 co-simulation FMU (C or pythonfmu)",
        _model_cmds.add_export_arguments,
        _model_cmds.run_export,
    ),
    Command(
        "export-controller",
        "export the level controller of a model file as an FMI 2.0 or 3.0 co-simulation FMU (C)",
        _model_cmds.add_export_controller_arguments,
        _model_cmds.run_export_controller,
    ),
    Command(
        "export-observer",
        "export the observer of a model file as an FMI 2.0 or 3.0 co-simulation FMU (C): "
        "filtered level, disturbance, innovation, forecast and an anomaly flag from measurements",
        _model_cmds.add_export_observer_arguments,
        _model_cmds.run_export_observer,
    ),
    Command(
        "observe",
        "run the observer in Python over a record: per-sample estimates and the anomaly flag "
        "as CSV (the envelope observer for a physical model)",
        _model_cmds.add_observe_arguments,
        _model_cmds.run_observe,
    ),
    Command(
        "validate",
        "simulate an FMU on measured records with fmpy and score it (JSON, JUnit, plots)",
        _add_validate_arguments,
        _run_validate,
    ),
    Command(
        "mpc-demo",
        "MPC vs SIMC PI on the exported FMU or the virtual flume: metrics JSON and plots",
        _add_mpc_demo_arguments,
        _run_mpc_demo,
    ),
    Command(
        "ssp",
        "pack a model's closed loop (plant FMU, controller FMU, scenario) as an SSP 1.0 package, "
        "or its observer on a record (--observe)",
        _ssp_cmds.add_ssp_arguments,
        _ssp_cmds.run_ssp,
    ),
    Command(
        "simulate-ssp",
        "run an SSP's FMUs with gatetwin's fixed-step master and write the result as CSV",
        _ssp_cmds.add_simulate_ssp_arguments,
        _ssp_cmds.run_simulate_ssp,
    ),
    Command(
        "diagnose",
        "find where a model and a record disagree, name the missing effect, add it, re-validate",
        _diagnose_cmds.add_diagnose_arguments,
        _diagnose_cmds.run_diagnose,
    ),
    Command(
        "swmm",
        "EPA SWMM as a plant: run experiments on a gate of a SWMM model and write records",
        _swmm_cmds.add_swmm_arguments,
        _swmm_cmds.run_swmm,
    ),
    Command(
        "run",
        "check the bundled records and write the pipeline's outputs",
        _add_run_arguments,
        _run_run,
    ),
)


class _OneLineParser(argparse.ArgumentParser):
    """Usage errors as one line ``gatetwin: error: ...`` and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_ERROR, f"gatetwin: error: {self.prog}: {_one_line(message)}\n")


def build_parser(commands: Sequence[Command] = _COMMANDS) -> argparse.ArgumentParser:
    """The argument parser with one subparser per command."""
    parser = _OneLineParser(
        prog="gatetwin",
        description="Control-ready digital-twin models of a canal sluice gate.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(
        dest="command", metavar="COMMAND", required=True, parser_class=_OneLineParser
    )
    for command in commands:
        sub_parser = sub.add_parser(command.name, help=command.help, description=command.help)
        command.add_arguments(sub_parser)
        sub_parser.set_defaults(run=command.run)
    return parser


def _one_line(message: str) -> str:
    return " ".join(message.split()) or "failed"


def _tolerant_streams() -> None:
    """Never crash on printing a character the terminal's encoding lacks."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            reconfigure(errors="backslashreplace")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``gatetwin`` command line; returns the exit code."""
    _tolerant_streams()
    args = build_parser().parse_args(argv)
    try:
        code = int(args.run(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's last flush
        return code
    except GatetwinError as exc:
        print(f"gatetwin: error: {_one_line(str(exc))}", file=sys.stderr)
    except BrokenPipeError:  # the reader of the output stopped early (| head): nothing to say
        with contextlib.suppress(OSError, ValueError):  # stdout may be no file (captured)
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # what is left to flush goes nowhere
        return EXIT_BROKEN_PIPE
    except OSError as exc:  # an output or input the system refuses (read-only, disk full)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"gatetwin: error: {_one_line(where + (exc.strerror or str(exc)))}",
              file=sys.stderr)  # fmt: skip
    except KeyboardInterrupt:
        print("gatetwin: error: interrupted", file=sys.stderr)
    return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
