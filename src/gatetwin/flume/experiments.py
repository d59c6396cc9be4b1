"""Experiments on the virtual flume: the reference suite and user-described scenarios.

A :class:`Scenario` is a pair of piecewise-constant schedules (commanded opening and pump
discharge) over a duration, with a seed for the logger. :func:`run_scenario` spins the
flume up to steady state at the first inputs, runs it and logs a record.

The reference suite (:func:`reference_scenarios`) is the paper's Table 1 (A, B step tests;
C, D PRBS tests) plus step tests at Q ≈ 40, 50, 60, 85 m³/h for the schedule on Q and one
held-out step test at Q ≈ 55 m³/h that no fit may use, and the validation records across
the flume's envelope (:mod:`gatetwin.flume.envelope`); :func:`static_table` is the
quasi-steady rating grid.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import max_len_seq

from gatetwin._io import write_text_atomic
from gatetwin.errors import FlumeError
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.envelope import envelope_scenarios
from gatetwin.flume.logger import FLUME_VERSION, LoggedRecord, LoggerConfig, log_run
from gatetwin.flume.scenario import Breakpoints, Scenario
from gatetwin.flume.simulate import run_flume, spin_up, steady_gate_depth_m
from gatetwin.flume.solver import leaf_speed

__all__ = [
    "Breakpoints",
    "Scenario",
    "reference_scenarios",
    "run_scenario",
    "static_table",
    "load_scenario",
    "prbs_scenario",
    "step_scenario",
    "write_reference_records",
]


def run_scenario(
    scn: Scenario, cfg: FlumeConfig | None = None, logger: LoggerConfig | None = None
) -> LoggedRecord:
    """Spin up at the first inputs, run the schedules, and log the record."""
    cfg = cfg or FlumeConfig()
    cmd, flow = scn.sampled(cfg.sample_period_s)
    _check_feasible(cfg, scn.name, flow, cmd)
    state = spin_up(cfg, flow[0], cmd[0])
    run = run_flume(cfg, cmd, flow, state=state)
    side = {"condition": scn.name, "test": scn.test, **scn.meta}
    return log_run(run, cfg, scn.seed, logger=logger, sidecar=side)


def _check_feasible(cfg: FlumeConfig, name: str, flow: np.ndarray, cmd: np.ndarray) -> None:
    for q, e in {(float(a), float(b)) for a, b in zip(flow, cmd, strict=True)}:
        h = steady_gate_depth_m(cfg, q, e)
        if h > cfg.depth_limit_m:
            raise FlumeError(
                f"scenario {name}: Q = {q} m³/h at e = {e} mm would need {1000 * h:.0f} mm of "
                f"water at the gate; the flume is {1000 * cfg.depth_limit_m:.0f} mm deep"
            )


def step_scenario(
    name: str, flow_m3h: float, before_mm: float, after_mm: float, seed: int, **meta: Any
) -> Scenario:
    """A step test: 180 s steady, then the opening step, then a 720 s hold."""
    return Scenario(
        name, ((0.0, flow_m3h),), ((0.0, before_mm), (180.0, after_mm)), 900.0, seed, "step",
        {"description": f"step {before_mm:g} -> {after_mm:g} mm at Q = {flow_m3h:g} m3/h",
         **meta},
    )  # fmt: skip


def prbs_scenario(
    name: str, flow_m3h: float, base_mm: float, seed: int, *, clock_s: float, order: int = 6,
    amplitude_mm: float = 5.0, cfg: FlumeConfig | None = None, **meta: Any,
) -> Scenario:  # fmt: skip
    """A PRBS test: a maximum-length sequence between base ± amplitude.

    Each run of equal bits holds for (run length × ``clock_s``) after the gate has arrived
    (the travel time of 2·amplitude at the actuator's loaded speed at the base opening, plus
    a 20 % margin), so every hold segment is at least one clock period long.
    """
    cfg = cfg or FlumeConfig()
    bits = max_len_seq(order, state=np.ones(order, dtype=np.int8))[0]
    runs = np.diff(np.flatnonzero(np.diff(np.r_[-1, bits, -1]) != 0))
    depth = steady_gate_depth_m(cfg, flow_m3h, base_mm + amplitude_mm)
    speed = leaf_speed(depth, cfg.actuator_speed_mm_s, cfg.actuator_stall_depth_m)
    travel = 1.2 * 2 * amplitude_mm / speed
    t, level, bps = 0.0, float(bits[0]), []
    for run_length in runs:
        value = base_mm + (amplitude_mm if level else -amplitude_mm)
        bps.append((t, value))
        t += travel + run_length * clock_s
        level = 1.0 - level
    desc = f"PRBS {base_mm - amplitude_mm:g}/{base_mm + amplitude_mm:g} mm at Q = {flow_m3h:g}"
    return Scenario(
        name, ((0.0, flow_m3h),), tuple(bps), t, seed, "prbs", {"description": desc, **meta}
    )


def reference_scenarios() -> list[Scenario]:
    """The bundled reference records (fixed seeds).

    The extra step conditions start on the operating line through A and B (level at 3F
    rising linearly from 231.6 mm at 29.5 m³/h to 340.5 mm at 72.5 m³/h, as an operator
    holds the level in a band while the discharge changes): the opening is the whole
    millimetre whose steady 3F level lies nearest that line, so that K, T and L of the
    conditions form a schedule on Q alone. The validation records across the envelope
    follow them (:func:`gatetwin.flume.envelope.envelope_scenarios`).
    """
    fit, held = {"role": "fit"}, {"role": "held_out"}
    return [
        step_scenario("A", 29.5, 15.0, 20.0, 101, paper_table="Table 2", **fit),
        step_scenario("B", 72.5, 30.0, 35.0, 102, paper_table="Table 3", **fit),
        prbs_scenario("C", 41.5, 35.0, 103, clock_s=24.0, paper_table="Table 4", **fit),
        prbs_scenario("D", 84.5, 65.0, 104, clock_s=12.0, paper_table="Table 4", **fit),
        step_scenario("Q40", 40.0, 19.0, 24.0, 105, **fit),
        step_scenario("Q50", 50.0, 23.0, 28.0, 106, **fit),
        step_scenario("Q60", 60.0, 26.0, 31.0, 107, **fit),
        step_scenario("Q85", 85.0, 35.0, 40.0, 108, **fit),
        step_scenario("Q55", 55.0, 25.0, 30.0, 109, **held),
        *envelope_scenarios(),
    ]


STATIC_FLOWS_M3H = tuple(float(q) for q in range(20, 95, 5))
STATIC_OPENINGS_MM = tuple(float(e) for e in range(10, 85, 5))
#: The paper's gauges read 0.1–0.6 m; the flume is 0.40 m deep.
STATIC_DEPTH_RANGE_MM = (100.0, 380.0)


def static_table(
    cfg: FlumeConfig | None = None, logger: LoggerConfig | None = None, seed: int = 110,
    n_samples: int = 100,
) -> str:  # fmt: skip
    """The quasi-steady rating grid as CSV text (feasible points only, see below).

    Q 20–90 m³/h × openings 10–80 mm in 5-unit steps; a point is run when its steady depth
    at the gate lies in ``STATIC_DEPTH_RANGE_MM`` (the rest would overtop the flume or fall
    below the gauges' range). Each point: steady run, ``n_samples`` logged samples, means
    and SDs per gauge.
    """
    cfg = cfg or FlumeConfig()
    lines, gauges = [], list(cfg.gauges_m)
    header = ["flow_m3h", "opening_mm"]
    header += [f"level_{g}_mm" for g in gauges] + [f"level_{g}_sd_mm" for g in gauges]
    lines.append(",".join(header))
    for i, (q, e) in enumerate(_feasible_points(cfg)):
        state = spin_up(cfg, q, e)
        run = run_flume(cfg, np.full(n_samples, e), np.full(n_samples, q), state=state)
        rec = log_run(run, cfg, seed * 1000 + i, logger=logger)
        means = [float(np.mean(rec.levels_mm[g])) for g in gauges]
        sds = [float(np.std(rec.levels_mm[g], ddof=1)) for g in gauges]
        row = [f"{np.mean(rec.flow_m3h):.2f}", f"{e:.0f}"]
        row += [f"{m:.2f}" for m in means] + [f"{s:.2f}" for s in sds]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _feasible_points(cfg: FlumeConfig) -> list[tuple[float, float]]:
    lo, hi = STATIC_DEPTH_RANGE_MM
    return [
        (q, e)
        for q in STATIC_FLOWS_M3H
        for e in STATIC_OPENINGS_MM
        if lo <= 1000.0 * steady_gate_depth_m(cfg, q, e) <= hi
    ]


def write_reference_records(
    out_dir: str | Path, *, progress: Any = None, only: tuple[str, ...] = ()
) -> list[Path]:
    """Write the reference suite (``A.csv`` … ``Q55.csv``, the envelope's validation records,
    ``static.csv``) into ``out_dir``."""
    out = Path(out_dir)
    paths = []
    scenarios = [s for s in reference_scenarios() if not only or s.name in only]
    for scn in scenarios:
        if progress:
            progress(f"flume: running {scn.name} ({scn.meta.get('description', '')})")
        paths.append(run_scenario(scn).write(out / f"{scn.name}.csv"))
    if not only or "static" in only:
        if progress:
            progress("flume: running the static rating grid")
        path = write_text_atomic(out / "static.csv", static_table())
        side = {"synthetic": True, "generator": f"gatetwin virtual flume {FLUME_VERSION}",
                "flume_version": FLUME_VERSION, "seed": 110, "kind": "static rating table",
                "gauges": dict(FlumeConfig().gauges_m),
                "gate_width_m": FlumeConfig().width_m}  # fmt: skip
        write_text_atomic(out / "static.json", json.dumps(side, indent=2) + "\n")
        paths.append(path)
    return paths


def load_scenario(path: str | Path) -> Scenario:
    """A scenario described in JSON or TOML (see docs/flume.md: "Describing a flume scenario")."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FlumeError(f"{p}: cannot read scenario ({exc.__class__.__name__})") from None
    data = _parse_scenario_text(p, text)
    try:
        return Scenario(
            name=str(data.get("name", p.stem)),
            flow_m3h=_breakpoints(data["flow_m3h"]),
            opening_mm=_breakpoints(data["opening_mm"]),
            duration_s=float(data["duration_s"]),
            seed=int(data.get("seed", 0)),
            test=str(data.get("test", "free")),
            meta={"description": str(data.get("description", "")), "scenario_file": p.name},
        )
    except KeyError as exc:
        raise FlumeError(f"{p}: scenario lacks the key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, FlumeError):
            raise FlumeError(f"{p}: {exc}") from None
        raise FlumeError(f"{p}: malformed scenario ({exc})") from None


def _parse_scenario_text(p: Path, text: str) -> dict[str, Any]:
    if p.suffix.lower() == ".toml":
        if sys.version_info < (3, 11):
            raise FlumeError(f"{p}: TOML scenarios need Python >= 3.11; use JSON")
        import tomllib

        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise FlumeError(f"{p}: invalid TOML ({exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FlumeError(f"{p}: invalid JSON at line {exc.lineno} ({exc.msg})") from None
    if not isinstance(data, dict):
        raise FlumeError(f"{p}: a scenario is a JSON object")
    return data


def _breakpoints(value: Any) -> Breakpoints:
    if isinstance(value, (int, float)):
        return ((0.0, float(value)),)
    return tuple((float(t), float(v)) for t, v in value)
