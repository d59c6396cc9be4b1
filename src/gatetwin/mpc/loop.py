"""Closed-loop runs and their metrics: ``u = controller.step(y); y = plant.step(u)``.

A :class:`Scenario` says what happens (set-point changes, inflow changes, duration); a
controller (MPC or PI) and a :class:`~gatetwin.mpc.plants.LoopPlant` run it in
:func:`run_closed_loop`; :func:`loop_metrics` scores the run on the *true* level (the
noise-free level the gauge would read), so that noise does not count as control error.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.plants import LoopPlant


class Controller(Protocol):
    """What the loop needs of a controller (MPC and PI both have it)."""

    name: str
    last_solve_s: float

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None: ...

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> float: ...


@dataclass(frozen=True)
class Scenario:
    """A closed-loop experiment from rest.

    Attributes
    ----------
    name : str
        Scenario name (JSON key).
    duration_s : float
        Simulated time, s.
    flow_m3h : float
        Initial discharge, m³/h.
    opening_mm : float
        Initial (steady) opening, mm. The initial set-point is the plant's steady level.
    setpoint_changes : tuple of (time_s, offset_mm)
        From ``time_s`` on, the set-point is the initial level plus ``offset_mm``.
    flow_changes : tuple of (time_s, flow_m3h)
        From ``time_s`` on, the discharge is ``flow_m3h`` (a step of the pump).
    """

    name: str
    duration_s: float
    flow_m3h: float = 40.0
    opening_mm: float = 25.0
    setpoint_changes: tuple[tuple[float, float], ...] = ()
    flow_changes: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        times = [t for t, _ in (*self.setpoint_changes, *self.flow_changes)]
        if not self.duration_s > 0 or any(not 0 <= t < self.duration_s for t in times):
            raise ControlError(f"scenario {self.name}: events must lie within the duration")

    def samples(self, sample_period_s: float) -> int:
        return int(round(self.duration_s / sample_period_s))

    def schedules(self, sample_period_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Set-point offsets (mm) and discharges (m³/h) at every sample: a change is in force
        from the first sample :func:`gatetwin.mpc.signal_law.in_force` says (the rule of the
        SSP's scenario FMU)."""
        from gatetwin.mpc.signal_law import TIME_TOL_S, in_force

        t = np.arange(self.samples(sample_period_s)) * sample_period_s
        reached = np.vectorize(lambda t0, tk: in_force(t0, tk, TIME_TOL_S) > 0.0)
        offset = np.zeros_like(t)
        flow = np.full_like(t, self.flow_m3h)
        for t0, value in sorted(self.setpoint_changes):
            offset[reached(t0, t)] = value
        for t0, value in sorted(self.flow_changes):
            flow[reached(t0, t)] = value
        return offset, flow

    def event_times_s(self) -> list[float]:
        return sorted({t for t, _ in (*self.setpoint_changes, *self.flow_changes)})


@dataclass(frozen=True, eq=False)
class ClosedLoopRun:
    """One controller on one plant through one scenario, a row per sample.

    Attributes
    ----------
    scenario : Scenario
    controller : str
        ``"mpc"``, ``"mpc_envelope"`` or ``"pi"``.
    plant : str
        Description of the plant.
    time_s : ndarray
        Sample times, s.
    setpoint_mm, flow_m3h : ndarray
        Set-point and discharge in force from each sample on, mm and m³/h.
    level_mm, measured_level_mm : ndarray
        True and measured level at each sample, mm.
    command_mm, applied_mm : ndarray
        Opening commanded at each sample and the one the actuator applied (rounded), mm.
    solve_s, step_s : ndarray
        Solver time and whole controller step time at each sample, s.
    level_band_mm : tuple[float, float] or None
        Hard level band, mm.
    max_move_mm : float
        Largest allowed change of the command per sample, mm.
    opening_range_mm : tuple[float, float]
        Allowed opening, mm.
    """

    scenario: Scenario
    controller: str
    plant: str
    time_s: np.ndarray
    setpoint_mm: np.ndarray
    flow_m3h: np.ndarray
    level_mm: np.ndarray
    measured_level_mm: np.ndarray
    command_mm: np.ndarray
    applied_mm: np.ndarray
    solve_s: np.ndarray
    step_s: np.ndarray
    level_band_mm: tuple[float, float] | None
    max_move_mm: float
    opening_range_mm: tuple[float, float]
    extra: dict[str, Any] = field(default_factory=dict)

    def plot(self, axes: Any, *, color: str | None = None) -> None:
        """Draw level (+ set-point), opening and discharge on three matplotlib axes."""
        ax_level, ax_open, ax_flow = axes
        t = self.time_s / 60.0
        ax_level.plot(t, self.measured_level_mm, color=color, alpha=0.25, lw=0.6)
        ax_level.plot(t, self.level_mm, color=color, lw=1.2, label=f"{self.controller} level")
        ax_open.step(
            t,
            self.applied_mm,
            where="post",
            color=color,
            lw=1.0,
            label=f"{self.controller} opening (applied)",
        )
        ax_flow.plot(t, self.flow_m3h, color=color, lw=1.0, label=f"{self.controller} Q")


@dataclass(frozen=True)
class LoopSettings:
    """How the loop is scored.

    Attributes
    ----------
    settle_band_mm : float
        A response has settled once the true level stays within this of the set-point,
        mm. 5 mm: the 1 mm actuator resolution alone moves the level by ``|K|`` ≈ 9–15 mm,
        so an integrating controller dithers by a few mm about the set-point.
    sample_period_s : float
        Control period, s.
    """

    settle_band_mm: float = 5.0
    sample_period_s: float = SAMPLE_PERIOD_S


def run_closed_loop(
    plant: LoopPlant,
    controller: Controller,
    scenario: Scenario,
    *,
    level_band_mm: tuple[float, float] | None,
    max_move_mm: float,
    opening_range_mm: tuple[float, float],
    sample_period_s: float = SAMPLE_PERIOD_S,
) -> ClosedLoopRun:
    """Run ``scenario`` from rest: ``u = controller.step(y); y = plant.step(u)``."""
    offsets, flows = scenario.schedules(sample_period_s)
    n = offsets.size
    rows = {k: np.empty(n) for k in ("sp", "y", "ym", "cmd", "app", "solve", "step")}
    y = plant.start(scenario.opening_mm, float(flows[0]))
    base = plant.true_level_mm
    controller.reset(scenario.opening_mm, y, float(flows[0]))
    for k in range(n):
        r = base + offsets[k]
        rows["sp"][k], rows["y"][k], rows["ym"][k] = r, plant.true_level_mm, y
        start = time.perf_counter()
        u = controller.step(y, float(flows[k]), r)
        rows["step"][k] = time.perf_counter() - start
        rows["solve"][k] = controller.last_solve_s or rows["step"][k]
        y = plant.step(u, float(flows[k]))
        rows["cmd"][k], rows["app"][k] = u, plant.applied_opening_mm
    return ClosedLoopRun(
        scenario,
        controller.name,
        plant.core.description,
        np.arange(n) * sample_period_s,
        rows["sp"],
        flows,
        rows["y"],
        rows["ym"],
        rows["cmd"],
        rows["app"],
        rows["solve"],
        rows["step"],
        level_band_mm,
        max_move_mm,
        opening_range_mm,
    )


def _event_windows(run: ClosedLoopRun) -> list[tuple[int, int]]:
    """Sample ranges [start, stop) from each event to the next one (or the end)."""
    ts = run.time_s[1] - run.time_s[0] if run.time_s.size > 1 else SAMPLE_PERIOD_S
    starts = [int(round(t / ts)) for t in run.scenario.event_times_s()]
    stops = [*starts[1:], run.time_s.size]
    return list(zip(starts, stops, strict=True))


def _settling_s(err: np.ndarray, band: float, ts: float) -> float | None:
    """Time until |err| stays within ``band`` to the end of the window (None: never)."""
    outside = np.flatnonzero(np.abs(err) > band)
    if outside.size == 0:
        return 0.0
    last = int(outside[-1])
    return None if last == err.size - 1 else (last + 1) * ts


def _overshoot_mm(err: np.ndarray) -> float:
    """Largest excursion on the far side of the set-point from the first deviation."""
    peak = err[int(np.argmax(np.abs(err)))]
    return float(max(0.0, np.max(-np.sign(peak) * err))) if peak != 0 else 0.0


def _violations(run: ClosedLoopRun) -> dict[str, int]:
    lo_e, hi_e = run.opening_range_mm
    moves = np.abs(np.diff(np.concatenate([[run.scenario.opening_mm], run.command_mm])))
    out = {
        "opening_range": int(
            np.sum((run.command_mm < lo_e - 1e-9) | (run.command_mm > hi_e + 1e-9))
        ),
        "opening_rate": int(np.sum(moves > run.max_move_mm + 1e-6)),
        "level_band": 0,
    }
    if run.level_band_mm is not None:
        lo, hi = run.level_band_mm
        out["level_band"] = int(np.sum((run.level_mm < lo) | (run.level_mm > hi)))
    return out


def gate_reversals_per_hour(run: ClosedLoopRun) -> float:
    """Reversals of the applied opening per hour of the run, 1/h.

    The moves of the applied (actuator's) opening from the start opening on, zero moves
    dropped; a reversal is a move of the other sign than the move before it. A controller
    that hunts about a quantised opening reverses at every move; one that settles, rarely.
    """
    applied = np.concatenate([[run.scenario.opening_mm], run.applied_mm])
    moves = np.sign(np.diff(applied))
    moves = moves[moves != 0]
    ts = run.time_s[1] - run.time_s[0] if run.time_s.size > 1 else SAMPLE_PERIOD_S
    hours = run.time_s.size * ts / 3600.0
    return float(np.count_nonzero(moves[1:] != moves[:-1]) / hours)


def loop_metrics(run: ClosedLoopRun, settings: LoopSettings | None = None) -> dict[str, Any]:
    """Scores of a run on the true level (JSON-ready; ``None`` where undefined).

    Keys: ``iae`` (∫|level − set-point| dt, mm·s), ``max_dev_mm`` (largest
    |level − set-point|, mm; for a set-point step this includes the step itself),
    ``gate_reversals_per_hour`` (:func:`gate_reversals_per_hour`, 1/h),
    ``settling_s`` (longest time from an event until the level stays within the settle
    band until the next event; ``None`` if some response never settles), ``overshoot_mm``
    (largest excursion past the set-point on the far side of an event's first deviation),
    ``travel_mm`` (total movement of the applied opening), ``violations`` (samples breaking
    the hard level band, the opening range or the rate limit; per kind in
    ``violations_by_kind``), ``solve_ms_median`` / ``solve_ms_p99`` (solver call; for the PI
    its whole update) and ``step_ms_median`` / ``step_ms_p99`` (whole controller step).
    """
    s = settings or LoopSettings()
    ts = s.sample_period_s
    err = run.level_mm - run.setpoint_mm
    windows = _event_windows(run)
    settle = [_settling_s(err[a:b], s.settle_band_mm, ts) for a, b in windows]
    overshoot = [_overshoot_mm(err[a:b]) for a, b in windows]
    viol = _violations(run)
    applied = np.concatenate([[run.scenario.opening_mm], run.applied_mm])
    command = np.concatenate([[run.scenario.opening_mm], run.command_mm])
    return {
        "iae": float(np.sum(np.abs(err)) * ts),
        "max_dev_mm": float(np.max(np.abs(err))),
        "settling_s": None if any(v is None for v in settle) else float(max(settle, default=0.0)),
        "settling_s_per_event": settle,
        "overshoot_mm": float(max(overshoot, default=0.0)),
        "travel_mm": float(np.sum(np.abs(np.diff(applied)))),
        "command_travel_mm": float(np.sum(np.abs(np.diff(command)))),
        "gate_reversals_per_hour": gate_reversals_per_hour(run),
        "violations": int(sum(viol.values())),
        "violations_by_kind": viol,
        "solve_ms_median": float(np.median(run.solve_s) * 1e3),
        "solve_ms_p99": float(np.percentile(run.solve_s, 99) * 1e3),
        "step_ms_median": float(np.median(run.step_s) * 1e3),
        "step_ms_p99": float(np.percentile(run.step_s, 99) * 1e3),
        "final_error_mm": float(np.mean(err[-max(1, int(60 / ts)) :])),
        "samples": int(run.time_s.size),
    }


__all__ = [
    "ClosedLoopRun",
    "Controller",
    "LoopSettings",
    "Scenario",
    "gate_reversals_per_hour",
    "loop_metrics",
    "run_closed_loop",
]
