"""Argument parsing and printing of ``identify``, ``models``, ``export`` and
``export-observer``, ``observe`` (no logic)."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from gatetwin._io import check_writable, undone_on_failure, write_json_atomic
from gatetwin.errors import GatetwinError, IdentificationError

__all__ = [
    "PI_FILTER_HELP",
    "TEST_CHOICES",
    "add_export_arguments",
    "add_export_controller_arguments",
    "add_export_observer_arguments",
    "add_identify_arguments",
    "add_models_arguments",
    "add_observe_arguments",
    "add_routine_arguments",
    "check_pi_filter",
    "run_export",
    "run_export_controller",
    "run_export_observer",
    "run_identify",
    "run_models",
    "run_observe",
    "run_routine",
    "with_pi_filter",
]

TEST_CHOICES = ("step", "prbs")


def add_identify_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", metavar="RECORD.csv")
    parser.add_argument("--test", choices=TEST_CHOICES, help="override the sidecar/detection")
    parser.add_argument("--gauge", help="gauge (default: every gauge for step; for prbs, the "
                        "gauge with the highest signal-to-noise ratio, as gatetwin models "
                        "picks the discrete model's)")  # fmt: skip
    parser.add_argument(
        "--orders", nargs="+", metavar="N",
        help="ARX orders NA NB NK (default the paper's 2 2 1) or 'auto' (order search)",
    )  # fmt: skip
    parser.add_argument(
        "--criterion", default="bic", choices=("bic", "aic", "holdout_rmse", "holdout_fit"),
        help="criterion of --orders auto (default bic)",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True)


def _orders(values: list[str] | None) -> tuple[int, int, int] | str:
    if values is None:
        return (2, 2, 1)
    if values == ["auto"]:
        return "auto"
    try:
        na, nb, nk = (int(v) for v in values)
    except ValueError:
        raise GatetwinError(
            f"--orders: expected three integers NA NB NK or 'auto', got {' '.join(values)}"
        ) from None
    return (na, nb, nk)


def run_identify(args: argparse.Namespace) -> int:
    from gatetwin.identification import identify_prbs, identify_step
    from gatetwin.records import read_record

    check_writable(args.json)
    record = read_record(args.path, test=args.test)
    if record.test == "step" and args.orders is not None:
        raise GatetwinError(f"{args.path}: --orders applies to PRBS records, this is a step test")
    if record.test == "step":
        result = identify_step(record, args.gauge).to_dict()
        for g, res in result["gauges"].items():
            p, f = res["paper"], res["fit"]
            print(f"{g}: paper K {p['K']:.2f} L {p['L_s']:.1f} s T {p['T_s']:.1f} s | "
                  f"fit K {f['K']:.2f}±{f['K_se']:.2f} L {f['L_s']:.2f}±{f['L_se']:.2f} s "
                  f"T {f['T_s']:.1f}±{f['T_se']:.1f} s")  # fmt: skip
    elif record.test == "prbs":
        from gatetwin.identification.suite import arx_gauge_of

        gauge = args.gauge or arx_gauge_of([record])
        res = identify_prbs(record, gauge=gauge, orders=_orders(args.orders),
                            criterion=args.criterion)  # fmt: skip
        result = res.to_dict()
        print(f"ARX({result['na']},{result['nb']},{result['nk']}) at {result['gauge']}: "
              f"a {result['a']} b {result['b']}; one-step R² {result['one_step']['r2']:.3f}, "
              f"free-run fit {result['simulation']['fit_percent']:.1f} %")  # fmt: skip
    elif record.test == "routine":
        raise IdentificationError(
            f"{args.path}: a routine operation history; identify it with gatetwin routine"
        )
    else:
        raise IdentificationError(
            f"{args.path}: a {record.test!r} record has no method; use --test step or prbs"
        )
    write_json_atomic(args.json, result)
    return 0


def add_routine_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", metavar="RECORD.csv",
                        help="routine operation history (CSV or Parquet), or a folder of "
                        "its day files (read a file at a time)")  # fmt: skip
    parser.add_argument("--gauge", help="gauge (default: the record's only gauge)")
    parser.add_argument(
        "--pre-s", type=float, default=300.0,
        help="steady hold needed before a move, s (default 300)",
    )  # fmt: skip
    parser.add_argument(
        "--post-s", type=float, default=480.0,
        help="hold needed after a move for the level to settle, s: over 3 time constants "
        "(default 480)",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True,
                        help="windows, schedule on Q and overall estimate")  # fmt: skip
    parser.add_argument(
        "--max-memory", metavar="MIB", type=float,
        help="read a Parquet history a chunk at a time, window by window, to stay within "
        "this many MiB (same result as reading it whole); a folder of day files is always "
        "read a file at a time",
    )  # fmt: skip
    parser.epilog = (
        "exit status 0 with at least one informative window; 2 when the history has none "
        "(one line saying why the moves were rejected; nothing is written) or cannot be read"
    )


def _routine_result(args: argparse.Namespace, criteria: Any) -> Any:
    """The whole history read at once, or chunk by chunk (``--max-memory`` or a folder)."""
    from gatetwin.identification.routine import identify_routine
    from gatetwin.identification.routine_chunks import (
        DEFAULT_CHUNK_ROWS,
        chunk_rows_for,
        identify_routine_chunked,
    )
    from gatetwin.records import read_record

    if args.max_memory is None and not Path(args.path).is_dir():
        return identify_routine(read_record(args.path, test="routine"), args.gauge, criteria)
    rows = DEFAULT_CHUNK_ROWS if args.max_memory is None else chunk_rows_for(args.max_memory)
    return identify_routine_chunked(args.path, args.gauge, criteria, chunk_rows=rows)


def run_routine(args: argparse.Namespace) -> int:
    from gatetwin.identification.routine import WindowCriteria

    check_writable(args.json)
    if not (args.pre_s > 0 and args.post_s > 0):
        raise GatetwinError("--pre-s and --post-s: expected durations > 0 s")
    criteria = WindowCriteria(pre_s=args.pre_s, post_min_s=args.post_s,
                              post_max_s=max(1200.0, args.post_s))  # fmt: skip
    res = _routine_result(args, criteria)
    o = res.overall
    print(f"{res.gauge}: {len(res.windows)} informative window(s) of {res.n_moves} observed "
          f"move(s); K {o['gain_mm_per_mm']:.2f} mm/mm, T {o['time_constant_s']:.1f} s, "
          f"L {o['dead_time_s']:.1f} s over Q {o['flow_min_m3h']:.1f}-{o['flow_max_m3h']:.1f} "
          "m3/h")  # fmt: skip
    for b in res.schedule:
        print(f"  Q {b.flow_m3h:.1f} m3/h ({b.n_windows} windows): K {b.gain_mm_per_mm:.2f} "
              f"T {b.time_constant_s:.1f} s L {b.dead_time_s:.1f} s")  # fmt: skip
    for warning in res.warnings:
        print(f"gatetwin: warning: {warning}", file=sys.stderr)
    write_json_atomic(args.json, res.to_dict())
    return 0


def add_models_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--records", metavar="SOURCE", nargs="+",
        help="records folder (default: the bundled records); for many gates: a folder of "
        "gate folders, glob patterns (quoted), CSV files whose sidecars name their 'gate', or "
        "a manifest listing any of these one per line",
    )  # fmt: skip
    parser.add_argument("--out", metavar="DIR", required=True, help="where to write the models")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="run one task per gate on this dask.distributed scheduler (tcp://host:8786); "
        "needs gatetwin[fleet]",
    )  # fmt: skip
    parser.add_argument(
        "--workers", metavar="N", type=int,
        help="local processes, one gate per task, when no --scheduler is given (default: the "
        "CPUs available; 1 runs the gates one after another in this process); one records "
        "folder without it: its gauges are fitted on a pool of the CPUs available",
    )  # fmt: skip
    parser.add_argument(
        "--fmus", metavar="BACKEND", choices=("c", "python"),
        help="also build each gate's FMUs (into OUT/<gate>/fmus/) with this backend",
    )  # fmt: skip
    parser.add_argument(
        "--max-memory", metavar="MIB", type=float,
        help="memory budget of a worker reading a routine history in Parquet (a file, or a "
        "folder of day files next to its FOLDER.json) chunk by chunk, as gatetwin routine "
        "--max-memory does (default: chunks of 65,536 rows); a CSV history is read whole",
    )  # fmt: skip
    parser.epilog = (
        "with many gates: exit status 0 when every gate was identified, 1 when some failed "
        "(each named with its reason in OUT/fleet.json; the others are written), 2 for input "
        "that cannot be read"
    )


def _is_fleet(args: argparse.Namespace) -> bool:
    """Many gates unless the records are one plain records folder and nothing asks for more."""
    from gatetwin.fleet import is_one_records_folder

    if args.scheduler or args.workers is not None or args.fmus or args.max_memory is not None:
        return True
    return bool(args.records) and not is_one_records_folder(args.records)


def _run_fleet(args: argparse.Namespace) -> int:
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.fleet import FleetSettings, default_workers, run_fleet

    if args.workers is not None and args.workers < 1:
        raise GatetwinError(f"--workers: expected a whole number >= 1, got {args.workers}")
    if args.scheduler and args.workers is not None:
        raise GatetwinError("--workers applies to a local run; the dask workers run the "
                            "gates when --scheduler is given")  # fmt: skip
    if args.max_memory is not None:
        _check_budget(args.max_memory)
    settings = FleetSettings(scheduler=args.scheduler,
                             workers=args.workers or default_workers())  # fmt: skip
    sources = args.records or [str(bundled_records_dir())]
    # the gates written as they finished are kept; folders left empty go
    with undone_on_failure(args.out, keep_files=True):
        doc = run_fleet(sources, args.out, settings, fmu_backend=args.fmus,
                        max_memory_mib=args.max_memory, progress=_print_to_stderr)  # fmt: skip
    print(f"wrote {doc['n_ok']} model sets of {doc['n_gates']} gates and the summary "
          f"{Path(args.out) / 'fleet.json'}; {doc['n_failed']} failed, "
          f"{doc['n_no_window']} without an informative window")  # fmt: skip
    return 1 if doc["n_failed"] else 0


def _check_budget(max_memory_mib: float) -> None:
    """Refuse a memory budget the chunked reader cannot keep, naming the option."""
    from gatetwin.identification.routine_chunks import chunk_rows_for

    try:
        chunk_rows_for(max_memory_mib)
    except GatetwinError as exc:
        raise GatetwinError(f"--max-memory: {exc}") from None


def _print_to_stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def run_models(args: argparse.Namespace) -> int:
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.fleet import FleetSettings, default_workers
    from gatetwin.identification.suite import identify_folder
    from gatetwin.modelfile import write_model_files

    check_writable(args.out, folder=True)  # before any gate is identified, fleet or not
    if _is_fleet(args):
        return _run_fleet(args)
    folder = Path(args.records[0]) if args.records else bundled_records_dir()
    # one gate: its gauges' fits spread over the CPUs, as gatetwin run spreads them
    ident = identify_folder(folder, progress=lambda line: _print_to_stderr(line.strip()),
                            fleet=FleetSettings(workers=default_workers()))  # fmt: skip
    for name, why in ident.not_identified.items():
        print(f"gatetwin: warning: {name} not identified ({' '.join(why.split())}); the "
              "others are written", file=sys.stderr)  # fmt: skip
    with undone_on_failure(args.out):
        paths = write_model_files(ident.models, Path(args.out))
    for path in paths:
        print(f"wrote {path}")
    return 0


def add_export_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL.json")
    parser.add_argument("--backend", choices=("c", "python"), required=True)
    parser.add_argument("--out", metavar="NAME.fmu", required=True)
    parser.add_argument(
        "--fmi",
        choices=("2", "3"),
        default="2",
        help="FMI version of the co-simulation FMU: 2 (default) or 3 (C backend)",
    )
    parser.add_argument(
        "--platforms",
        metavar="WHICH",
        default="host",
        help="C backend: host (default), all, or a comma-separated list of binary folders: "
        "FMI 2: linux64, win64, darwin64, aarch64-linux, aarch64-darwin; FMI 3: x86_64-linux, "
        "x86_64-windows, x86_64-darwin, aarch64-linux, aarch64-darwin; other than the host's "
        "need gatetwin[cross]",
    )
    parser.add_argument(
        "--cross-check",
        metavar="DIR",
        help="also write the FMI cross-check package into DIR/<model>/: the FMU, the inputs of "
        "a record, the reference result and the settings to compare them in another tool",
    )
    parser.add_argument(
        "--cross-check-record",
        metavar="RECORD.csv",
        help="the record whose inputs drive the cross-check (default: the bundled Eboth, gate "
        "moves and inflow steps together)",
    )


def run_export(args: argparse.Namespace) -> int:
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.modelfile import read_model_file

    model = read_model_file(args.model)
    check_writable(args.out)
    path = export_fmu(model.plant, args.out, backend=args.backend, model_name=model.name,
                      provenance=fmu_provenance(model), platforms=args.platforms,
                      fmi_version=f"{args.fmi}.0")  # fmt: skip
    print(f"wrote {path}")
    if args.cross_check:
        from gatetwin.bundled import bundled_records_dir
        from gatetwin.fmu.crosscheck import write_cross_check
        from gatetwin.records import read_record

        record = read_record(args.cross_check_record or bundled_records_dir() / "Eboth.csv")
        folder = Path(args.cross_check) / model.name
        write_cross_check(model, Path(path), record, folder)
        print(f"wrote the cross-check package {folder}")
    return 0


#: Help of ``--pi-filter`` (``export-controller``, ``mpc-demo``).
PI_FILTER_HELP = (
    "time constant of a first-order filter on the PI's measured level, s (default 0: none); "
    "SIMC tunes Kc and Ti for the filtered loop. On a noisy gauge sampled fast the unfiltered "
    "PI moves the gate at every reading; a few sample periods calm it"
)


def check_pi_filter(value: float | None) -> None:
    """Refuse a ``--pi-filter`` that is not a finite time constant >= 0, in one line."""
    if value is not None and not 0 <= value < math.inf:
        raise GatetwinError(f"--pi-filter: {value} s must be finite and >= 0")


def with_pi_filter(settings: Any, value: float | None) -> Any:
    """``settings`` (a :class:`~gatetwin.mpc.demo.DemoSettings`) with the PI's level filter
    ``value`` s, or as they are when it is None."""
    if value is None:
        return settings
    return replace(settings, pi=replace(settings.pi, filter_time_s=value))


def add_export_controller_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "model", metavar="MODEL.json",
        help="FOPDT or physical model file (SIMC tuning; a physical model linearised along "
        "its discharge range); operating point, limits, sample period, horizon and weights "
        "come from it",
    )  # fmt: skip
    parser.add_argument(
        "--kind", choices=("pi", "mpc"), default="pi",
        help="controller: pi (default), or mpc (the demo's single-point MPC)",
    )  # fmt: skip
    parser.add_argument(
        "--horizon", metavar="N", type=int,
        help="mpc: prediction horizon in prediction steps (default: the model's settling "
        "time, 4 T + L, in at most 100 steps of the sample period, coarser only when 100 do "
        "not reach T + L; the step's cost grows about as N^3)",
    )  # fmt: skip
    parser.add_argument(
        "--opening-range", metavar=("LO", "HI"), type=float, nargs=2,
        help="the gate's openings the controller may use, mm (default: the openings the "
        "model was identified over, its validity; an inflow step may need more)",
    )  # fmt: skip
    parser.add_argument(
        "--without-effects", action="store_true",
        help="mpc: control the model's FOPDT with its effect blocks dropped (the MPC FMU does "
        "not cover them; a model with effect blocks is refused otherwise)",
    )  # fmt: skip
    parser.add_argument("--pi-filter", metavar="S", type=float,
                        help=f"pi: {PI_FILTER_HELP}")  # fmt: skip
    parser.add_argument("--out", metavar="NAME.fmu", required=True)
    parser.add_argument(
        "--fmi",
        choices=("2", "3"),
        default="2",
        help="FMI version of the co-simulation FMU: 2 (default) or 3",
    )


def run_export_controller(args: argparse.Namespace) -> int:
    from gatetwin.fmu.controller import check_controller_kind, export_controller
    from gatetwin.modelfile import read_model_file

    check_controller_kind(args.kind)
    if args.horizon is not None and args.kind != "mpc":
        raise GatetwinError("--horizon applies to --kind mpc")
    if args.pi_filter is not None and args.kind != "pi":
        raise GatetwinError("--pi-filter applies to --kind pi")
    check_pi_filter(args.pi_filter)
    model = read_model_file(args.model)
    settings = None
    if args.horizon is not None or args.opening_range is not None or args.pi_filter is not None:
        from gatetwin.fmu.controller_settings import controller_plant, derived_settings

        given = tuple(args.opening_range) if args.opening_range else None
        try:
            settings = derived_settings(model, controller_plant(model), given)
        except GatetwinError as exc:
            if given is None:
                raise
            raise GatetwinError(f"--opening-range: {exc}") from None
        if args.horizon is not None:
            settings = replace(settings, mpc=replace(settings.mpc, horizon=args.horizon))
        settings = with_pi_filter(settings, args.pi_filter)
    check_writable(args.out)
    if args.without_effects and args.kind != "mpc":
        raise GatetwinError("--without-effects applies to --kind mpc")
    path = export_controller(model, args.kind, args.out, settings=settings,
                             fmi_version=f"{args.fmi}.0",
                             without_effects=args.without_effects)  # fmt: skip
    print(f"wrote {path}")
    return 0


def add_export_observer_arguments(parser: argparse.ArgumentParser) -> None:
    from gatetwin.mpc.online import (
        ANOMALY_BAND_SIGMA,
        ANOMALY_RUN_SAMPLES,
        CUSUM_SLACK_SIGMA,
        CUSUM_THRESHOLD,
        DEFAULT_HORIZON_S,
        ENVELOPE_RUN_SAMPLES,
        LINEARISATIONS,
    )

    parser.add_argument("model", metavar="MODEL.json")
    parser.add_argument("--out", metavar="NAME.fmu", required=True)
    parser.add_argument("--horizon", metavar="S", type=float, default=None,
                        help="how far ahead predicted_level_mm looks, s: a whole multiple of "
                        "the sample period, the records' the model file states (default "
                        f"{DEFAULT_HORIZON_S:g}, or the nearest whole number of "
                        "samples)")  # fmt: skip
    parser.add_argument("--linearisation", choices=LINEARISATIONS, default="auto",
                        help="schedule: the FOPDT's schedule; envelope: the model's envelope "
                        "re-linearised at every sample, with the slow rule; auto (default): "
                        "envelope for a physical model, else schedule")  # fmt: skip
    parser.add_argument("--band", metavar="SIGMA", type=float, default=None,
                        help="band of the normalised innovation, standard deviations times "
                        f"its scale (default {ANOMALY_BAND_SIGMA:g})")  # fmt: skip
    parser.add_argument("--run-samples", metavar="N", type=int, default=None,
                        help="consecutive samples outside the band that raise the anomaly "
                        f"flag (default {ANOMALY_RUN_SAMPLES}; the envelope observer's "
                        f"{ENVELOPE_RUN_SAMPLES})")  # fmt: skip
    parser.add_argument("--cusum-slack", metavar="SIGMA", type=float, default=None,
                        help="slack of the innovation's two-sided CUSUM, standard deviations "
                        f"per sample (default {CUSUM_SLACK_SIGMA:g})")  # fmt: skip
    parser.add_argument("--cusum-threshold", metavar="H", type=float, default=None,
                        help="CUSUM value that raises the anomaly flag "
                        f"(default {CUSUM_THRESHOLD:g})")  # fmt: skip
    parser.add_argument("--without-effects", action="store_true",
                        help="observe with the model's effect blocks dropped (a model with "
                        "effect blocks is refused otherwise)")  # fmt: skip
    parser.add_argument("--fmi", choices=("2", "3"), default="2",
                        help="FMI version of the co-simulation FMU: 2 (default) or 3")  # fmt: skip
    parser.add_argument("--reference-gauges", metavar="G", nargs="+",
                        help="other gauges of the same pool: adds an input level_<G>_mm for "
                        "each and the gauge-drift rule (outputs gauge_slope_mm_per_s, "
                        "gauge_drift; anomaly_kind 4 where it alone holds)")  # fmt: skip


def run_export_observer(args: argparse.Namespace) -> int:
    from gatetwin.fmu.observer_fmu import export_observer
    from gatetwin.modelfile import read_model_file

    given = {
        "band_sigma": args.band,
        "run_samples": args.run_samples,
        "cusum_slack_sigma": args.cusum_slack,
        "cusum_threshold": args.cusum_threshold,
    }
    model = read_model_file(args.model)
    check_writable(args.out)
    path = export_observer(model, args.out, horizon_s=args.horizon,
                           anomaly={k: v for k, v in given.items() if v is not None},
                           without_effects=args.without_effects, fmi_version=f"{args.fmi}.0",
                           linearisation=args.linearisation,
                           reference_gauges=args.reference_gauges or ())  # fmt: skip
    print(f"wrote {path}")
    return 0


def add_observe_arguments(parser: argparse.ArgumentParser) -> None:
    from gatetwin.mpc.online import DEFAULT_HORIZON_S, LINEARISATIONS

    parser.add_argument("model", metavar="MODEL.json")
    parser.add_argument("record", metavar="RECORD.csv")
    parser.add_argument("--gauge", required=True, help="gauge whose level is observed (3F)")
    parser.add_argument("--out", metavar="NAME.csv", required=True)
    parser.add_argument("--linearisation", choices=LINEARISATIONS, default="auto",
                        help="schedule: the FOPDT's schedule (the observer FMU's model); "
                        "envelope: re-linearised at every sample, with the slow rule; "
                        "auto (default): envelope for a physical model, else schedule")  # fmt: skip
    parser.add_argument("--horizon", metavar="S", type=float, default=None,
                        help="how far ahead predicted_level_mm looks, s: a whole multiple of "
                        "the record's sample period, the observer's (default "
                        f"{DEFAULT_HORIZON_S:g}, or the nearest whole number of "
                        "samples)")  # fmt: skip
    parser.add_argument("--without-effects", action="store_true",
                        help="observe with the model's effect blocks dropped (a model with "
                        "effect blocks is refused otherwise)")  # fmt: skip
    parser.add_argument("--reference-gauges", metavar="G", nargs="+",
                        help="other gauges of the same pool: adds the redundancy rule for a "
                        "drift of the observed gauge (columns gauge_slope_mm_per_s, "
                        "gauge_drift; anomaly_kind 4 where it alone holds)")  # fmt: skip


def _with_gauge_rule(out: dict, record, args: argparse.Namespace) -> dict:
    """The observer's outputs with the redundancy rule of gatetwin.mpc.gauge_drift added."""
    from gatetwin.errors import ControlError
    from gatetwin.mpc.gauge_drift import GaugeDriftMonitor, with_gauge_rule
    from gatetwin.mpc.online import measured_inputs

    if args.gauge in args.reference_gauges:
        raise ControlError(f"observe: --reference-gauges lists the observed gauge {args.gauge}")
    others = [measured_inputs(record, g)[0] for g in args.reference_gauges]
    monitor = GaugeDriftMonitor(sample_period_s=float(record.sample_period_s))
    return with_gauge_rule(out, measured_inputs(record, args.gauge)[0], others, monitor)


def run_observe(args: argparse.Namespace) -> int:
    import warnings

    import numpy as np

    from gatetwin._io import write_text_atomic
    from gatetwin.diagnosis.onset import detection
    from gatetwin.modelfile import read_model_file
    from gatetwin.mpc.online import OnlineObserver, measured_inputs
    from gatetwin.records import read_record

    plant = read_model_file(args.model).plant
    if args.without_effects:
        plant = replace(plant, effects=())
    record = read_record(args.record)
    check_writable(args.out)
    observer = OnlineObserver(plant, horizon_s=args.horizon, linearisation=args.linearisation,
                              sample_period_s=float(record.sample_period_s))  # fmt: skip
    level, opening, flow = measured_inputs(record, args.gauge)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # Q beyond the knots: clamped
        out = observer.run(level, opening, flow)
    if args.reference_gauges:
        out = _with_gauge_rule(out, record, args)
    columns = {"time_s": np.asarray(record.time_s, dtype=float), **out}
    rows = [",".join(columns)]
    rows += [",".join(f"{v:.10g}" for v in row) for row in zip(*columns.values(), strict=True)]
    write_text_atomic(args.out, "\n".join(rows) + "\n")
    found = detection(columns["time_s"], out["anomaly"], None)
    rule = ""
    if args.reference_gauges:
        rises = detection(columns["time_s"], out["gauge_drift"], None).false_alarms
        rule = f" (gauge drift rule: {rises})"
    print(f"wrote {args.out}: {len(rows) - 1} samples, {observer.linearisation} observer, "
          f"anomaly flag rose {found.false_alarms} times{rule}")  # fmt: skip
    return 0
