"""Routine operation histories of the virtual flume: days of SCADA logging with known truth.

No designed test: the gate moves by an operator's schedule (irregular moves of a few mm at
random times, held for minutes to hours, steering the level back towards an operating
line) or by a PI level controller (closed loop on the gauge, its set-point changed now and
then); the inflow drifts slowly and steps a few times; the logger loses whole stretches of
samples. The record is written in the standard format with sidecar ``test: "routine"``
(and, under level control, the controller's set-points in ``level_control``).

Truth: the flume's own FOPDT at each move, :func:`local_fopdt` — a noise-free small-step
simulation of the same flume at the move's discharge and openings, fitted with the
input-driven FOPDT as the record's windows are. The run uses a coarser cell than the
district's step records (:data:`ROUTINE_DX_M`) so a week at 1.2 s costs seconds; the truth
uses the same flume, so the two are consistent.

This module generates data; identifying it is :mod:`gatetwin.identification.routine`'s business.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from gatetwin.errors import FlumeError
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.envelope import steady_levels_mm
from gatetwin.flume.logger import LoggedRecord, LoggerConfig, log_run
from gatetwin.flume.simulate import FlumeRun, run_flume, spin_up
from gatetwin.identification.fopdt_driven import fit_fopdt_driven

__all__ = [
    "CONTROL_MODES",
    "LEVEL_BAND_MM",
    "ROUTINE_DX_M",
    "TRUTH_POST_S",
    "TRUTH_PRE_S",
    "TRUTH_SPIN_UP_S",
    "LocalFopdt",
    "RoutineSettings",
    "inflow_m3h",
    "local_fopdt",
    "logged_opening",
    "moves_of",
    "opening_for_level",
    "operator_schedule",
    "routine_history",
    "routine_run",
    "run_pi_loop",
]

#: Cell size of routine runs, m: the pool's slow mode (what K and T describe) is the same
#: to 4 digits at 0.1 m and 0.5 m, and 0.5 m runs a week at 1.2 s in a few seconds.
ROUTINE_DX_M = 0.5
#: Ways the gate is driven.
CONTROL_MODES = ("schedule", "pi")
#: Truth simulation: steady start before the move and record after it, s (the longest
#: district pool has T < 110 s, so 900 s is over 8 T).
TRUTH_PRE_S = 60.0
TRUTH_POST_S = 900.0
#: Spin-up of a truth simulation from a level surface, s.
TRUTH_SPIN_UP_S = 420.0
#: Steady gauge levels the operator keeps inside, mm (clear of the 400 mm flume depth).
LEVEL_BAND_MM = (150.0, 370.0)


@dataclass(frozen=True)
class RoutineSettings:
    """How a routine history is driven and logged.

    Attributes
    ----------
    days : float
        Length of the history, days.
    control : str
        ``"schedule"`` (an operator's moves, open loop) or ``"pi"`` (level controller).
    move_mm : tuple[int, int]
        Range of an operator move, whole mm.
    hold_s : tuple[float, float]
        Range of the time between operator moves, s (log-uniform draw).
    drift_fraction : float
        Amplitude of the slow inflow drift, fraction of the base flow.
    drift_period_s : tuple[float, float]
        Range of the drift's period, s.
    flow_steps : int
        Number of inflow steps (an upstream change), each a ramp of ``flow_ramp_s``.
    flow_step_fraction : tuple[float, float]
        Range of an inflow step, fraction of the base flow (sign random).
    flow_ramp_s : float
        Duration of an inflow step's ramp, s.
    gaps : int
        Number of logging gaps.
    gap_s : tuple[float, float]
        Range of a gap's length, s.
    pi_period_s : float
        Level controller's period, s (it acts on the level averaged over one period).
    pi_deadband_mm : float
        Level error the controller ignores, mm: a 1 mm move shifts the level by 6–25 mm,
        so without a band of about half that a whole-mm drive hunts around the set-point.
    setpoint_hold_s : tuple[float, float]
        Range of the time between set-point changes, s.
    setpoint_step_mm : tuple[float, float]
        Range of a set-point change, mm (sign random, kept inside :data:`LEVEL_BAND_MM`).
    """

    days: float = 7.0
    control: str = "schedule"
    move_mm: tuple[int, int] = (2, 6)
    hold_s: tuple[float, float] = (900.0, 14400.0)
    drift_fraction: float = 0.04
    drift_period_s: tuple[float, float] = (1.5 * 86400.0, 4.0 * 86400.0)
    flow_steps: int = 3
    flow_step_fraction: tuple[float, float] = (0.04, 0.10)
    flow_ramp_s: float = 300.0
    gaps: int = 6
    gap_s: tuple[float, float] = (600.0, 10800.0)
    pi_period_s: float = 60.0
    pi_deadband_mm: float = 10.0
    setpoint_hold_s: tuple[float, float] = (6.0 * 3600.0, 24.0 * 3600.0)
    setpoint_step_mm: tuple[float, float] = (10.0, 30.0)

    def __post_init__(self) -> None:
        checks = {
            "days": self.days > 0,
            "control": self.control in CONTROL_MODES,
            "move_mm": 1 <= self.move_mm[0] <= self.move_mm[1],
            "hold_s": 0 < self.hold_s[0] <= self.hold_s[1],
            "drift_fraction": 0 <= self.drift_fraction < 0.5,
            "flow_steps": self.flow_steps >= 0,
            "gaps": self.gaps >= 0,
            "pi_period_s": self.pi_period_s > 0,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise FlumeError(f"routine settings: invalid {', '.join(bad)}")


@dataclass(frozen=True)
class LocalFopdt:
    """The flume's FOPDT for one move at one discharge (noise-free small-step fit)."""

    flow_m3h: float
    opening_from_mm: float
    opening_to_mm: float
    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float

    def to_dict(self) -> dict[str, float]:
        return {k: round(v, 4) for k, v in asdict(self).items()}


def logged_opening(run: FlumeRun) -> tuple[np.ndarray, np.ndarray]:
    """Hold flag and the opening as a record gives it: held values, linear during motion."""
    hold = ~run.moving & (np.abs(run.position_mm - run.command_mm) < 1e-9)
    t = run.time_s
    return hold, np.interp(t, t[hold], run.position_mm[hold])


def local_fopdt(cfg: FlumeConfig, flow_m3h: float, opening_from_mm: float,
                opening_to_mm: float, gauge: str) -> LocalFopdt:  # fmt: skip
    """The flume's FOPDT at ``gauge`` for a move ``opening_from_mm → opening_to_mm`` at a
    constant ``flow_m3h``: a steady start, the move, :data:`TRUTH_POST_S` of response, and
    :func:`~gatetwin.identification.fopdt_driven.fit_fopdt_driven` on the noise-free level with
    the opening reconstructed as from a record."""
    if not abs(opening_to_mm - opening_from_mm) >= 1.0:
        raise FlumeError("local FOPDT: the move must be >= 1 mm")
    n_pre = math.ceil(TRUTH_PRE_S / cfg.sample_period_s)
    n = n_pre + math.ceil(TRUTH_POST_S / cfg.sample_period_s)
    state = spin_up(cfg, flow_m3h, opening_from_mm, duration_s=TRUTH_SPIN_UP_S)
    cmd = np.where(np.arange(n) > n_pre, opening_to_mm, opening_from_mm)
    run = run_flume(cfg, cmd, np.full(n, flow_m3h), state=state)
    _, opening = logged_opening(run)
    fit = fit_fopdt_driven(run.time_s, opening, run.depth_mm[gauge])
    return LocalFopdt(flow_m3h, opening_from_mm, opening_to_mm, fit.gain_mm_per_mm,
                      fit.time_constant_s, fit.dead_time_s)  # fmt: skip


def inflow_m3h(settings: RoutineSettings, base_m3h: float, time_s: np.ndarray,
               rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """A slow sinusoidal drift plus a few ramped steps around ``base_m3h``."""
    duration = float(time_s[-1])
    period = rng.uniform(*settings.drift_period_s)
    phase = rng.uniform(0.0, 2.0 * np.pi)
    rel = settings.drift_fraction * np.sin(2.0 * np.pi * time_s / period + phase)
    level = 0.0
    for t_step in np.sort(rng.uniform(0.05, 0.95, settings.flow_steps)) * duration:
        size = rng.uniform(*settings.flow_step_fraction)
        sign = -np.sign(level) if abs(level) > 0.08 else rng.choice([-1.0, 1.0])
        level += sign * size
        rel = rel + sign * size * np.clip((time_s - t_step) / settings.flow_ramp_s, 0.0, 1.0)
    return base_m3h * (1.0 + rel)


def opening_for_level(cfg: FlumeConfig, flow_m3h: float, level_mm: float, gauge: str) -> float:
    """Opening (mm, continuous) whose steady level at ``gauge`` is ``level_mm`` (bisection)."""
    lo, hi = 3.0, 150.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if steady_levels_mm(cfg, flow_m3h, mid)[gauge] > level_mm:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _in_band(cfg: FlumeConfig, flow_m3h: float, opening_mm: float, gauge: str) -> bool:
    level = steady_levels_mm(cfg, flow_m3h, opening_mm)[gauge]
    return LEVEL_BAND_MM[0] <= level <= LEVEL_BAND_MM[1]


def operator_schedule(cfg: FlumeConfig, settings: RoutineSettings, flow: np.ndarray,
                      target_mm: float, gauge: str,
                      rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """Commanded opening per sample: moves of a few whole mm at log-uniform intervals,
    towards the opening that holds ``target_mm`` when more than 3 mm away from it, else
    in a random direction; a move that would leave :data:`LEVEL_BAND_MM` goes the other way."""
    dt = cfg.sample_period_s
    n = flow.size
    opening = float(round(opening_for_level(cfg, float(flow[0]), target_mm, gauge)))
    cmd = np.empty(n)
    k = 0
    lo, hi = np.log(settings.hold_s[0]), np.log(settings.hold_s[1])
    while k < n:
        stop = min(n, k + max(1, round(np.exp(rng.uniform(lo, hi)) / dt)))
        cmd[k:stop] = opening
        k = stop
        if k >= n:
            break
        q = float(flow[k])
        want = opening_for_level(cfg, q, target_mm, gauge)
        sign = np.sign(want - opening) if abs(want - opening) > 3.0 else rng.choice([-1, 1])
        move = float(rng.integers(settings.move_mm[0], settings.move_mm[1] + 1))
        for candidate in (opening + sign * move, opening - sign * move):
            if candidate >= 5.0 and _in_band(cfg, q, candidate, gauge):
                opening = candidate
                break
    return cmd


@dataclass(frozen=True)
class _PiLoop:
    """A velocity-form PI on the level averaged over each period, output whole mm."""

    gain_mm_per_mm: float  # controller gain, mm of opening per mm of level error
    integral_s: float  # integral time, s
    period_s: float
    deadband_mm: float


def _pi_tuning(cfg: FlumeConfig, flow_m3h: float, opening_mm: float, gauge: str,
               period_s: float, deadband_mm: float) -> _PiLoop:  # fmt: skip
    """SIMC-like tuning on the flume's own FOPDT, with a closed-loop time of 3 T (slow)."""
    local = local_fopdt(cfg, flow_m3h, opening_mm, opening_mm + 2.0, gauge)
    tau_c = 3.0 * local.time_constant_s
    gain = local.time_constant_s / (abs(local.gain_mm_per_mm) * (tau_c + local.dead_time_s))
    return _PiLoop(gain, local.time_constant_s, period_s, deadband_mm)


def _setpoints(settings: RoutineSettings, duration_s: float, target_mm: float,
               rng: np.random.Generator) -> list[tuple[float, float]]:  # fmt: skip
    """Set-point changes: (time s, level mm), the first at t = 0."""
    points, t, sp = [(0.0, target_mm)], 0.0, target_mm
    while True:
        t += rng.uniform(*settings.setpoint_hold_s)
        if t >= duration_s:
            return points
        step = rng.uniform(*settings.setpoint_step_mm) * rng.choice([-1.0, 1.0])
        low, high = LEVEL_BAND_MM[0] + 20.0, LEVEL_BAND_MM[1] - 20.0
        sp = sp + step if low <= sp + step <= high else sp - step
        points.append((float(round(t, 1)), float(round(sp, 1))))


def _concat_runs(parts: list[FlumeRun], first: FlumeRun, dt: float) -> FlumeRun:
    """Stitch chunk runs (each starting at the previous one's last sample) into one."""

    def cat(get: Any) -> np.ndarray:
        return np.concatenate([get(first)[:1]] + [get(p)[1:] for p in parts])

    gauges = list(first.depth_mm)
    n = sum(p.time_s.size - 1 for p in parts) + 1
    return FlumeRun(
        time_s=np.arange(n) * dt, command_mm=cat(lambda r: r.command_mm),
        position_mm=cat(lambda r: r.position_mm), moving=cat(lambda r: r.moving),
        flow_m3h=cat(lambda r: r.flow_m3h),
        depth_mm={g: cat(lambda r, g=g: r.depth_mm[g]) for g in gauges},
        outflow_m3h=cat(lambda r: r.outflow_m3h),
        volume_balance_error=max(p.volume_balance_error for p in parts),
        final_state=parts[-1].final_state,
    )  # fmt: skip


def run_pi_loop(cfg: FlumeConfig, settings: RoutineSettings, flow: np.ndarray,
                setpoints: list[tuple[float, float]], gauge: str,
                opening_mm: float) -> FlumeRun:  # fmt: skip
    """The flume under PI level control, one controller period per :func:`run_flume` call."""
    dt = cfg.sample_period_s
    loop = _pi_tuning(
        cfg, float(flow[0]), opening_mm, gauge, settings.pi_period_s, settings.pi_deadband_mm
    )
    m = max(1, round(loop.period_s / dt))
    sp_t = np.array([p[0] for p in setpoints])
    sp_v = np.array([p[1] for p in setpoints])
    state = spin_up(cfg, float(flow[0]), opening_mm, duration_s=TRUTH_SPIN_UP_S)
    u, cmd, pos = opening_mm, opening_mm, opening_mm
    prev_err: float | None = None
    parts: list[FlumeRun] = []
    for k in range(0, flow.size - 1, m):
        stop = min(flow.size - 1, k + m)
        run = run_flume(cfg, np.full(stop - k + 1, cmd), flow[k : stop + 1], state=state,
                        start_position_mm=pos)  # fmt: skip
        parts.append(run)
        state, pos = run.final_state, float(run.position_mm[-1])
        sp = sp_v[np.searchsorted(sp_t, stop * dt, side="right") - 1]
        err = float(np.mean(run.depth_mm[gauge][1:])) - sp
        err = 0.0 if abs(err) < loop.deadband_mm else err
        d_err = 0.0 if prev_err is None else err - prev_err
        u = float(np.clip(u + loop.gain_mm_per_mm * (d_err + err * loop.period_s
                                                     / loop.integral_s), 5.0, 150.0))  # fmt: skip
        prev_err = err
        if abs(u - cmd) >= 0.8:  # a whole-mm drive with a little hysteresis
            cmd = float(round(u))
    return _concat_runs(parts, parts[0], dt)


def _gap_mask(settings: RoutineSettings, n: int, dt: float,
              rng: np.random.Generator) -> np.ndarray:  # fmt: skip
    """True for the samples the logger keeps (a gap is at most 5 % of a short history)."""
    keep = np.ones(n, dtype=bool)
    for _ in range(settings.gaps):
        length = min(round(rng.uniform(*settings.gap_s) / dt), n // 20)
        start = int(rng.integers(1, max(2, n - length - 1)))
        keep[start : start + length] = False
    return keep


def moves_of(run: FlumeRun) -> list[tuple[int, float, float]]:
    """Every command change of a run: (sample index, opening before mm, after mm)."""
    idx = np.flatnonzero(np.diff(run.command_mm) != 0) + 1
    return [(int(i), float(run.command_mm[i - 1]), float(run.command_mm[i])) for i in idx]


def routine_run(cfg: FlumeConfig, settings: RoutineSettings, *, base_flow_m3h: float,
                target_level_mm: float, gauge: str, seed: int,
                ) -> tuple[FlumeRun, list[tuple[float, float]]]:  # fmt: skip
    """The noise-free history and the set-points (empty under an operator's schedule)."""
    rng = np.random.default_rng(seed)
    dt = cfg.sample_period_s
    n = int(settings.days * 86400.0 / dt) + 1
    time_s = np.arange(n) * dt
    flow = inflow_m3h(settings, base_flow_m3h, time_s, rng)
    if settings.control == "pi":
        setpoints = _setpoints(settings, float(time_s[-1]), target_level_mm, rng)
        e0 = float(round(opening_for_level(cfg, float(flow[0]), target_level_mm, gauge)))
        return run_pi_loop(cfg, settings, flow, setpoints, gauge, e0), setpoints
    cmd = operator_schedule(cfg, settings, flow, target_level_mm, gauge, rng)
    state = spin_up(cfg, float(flow[0]), float(cmd[0]), duration_s=TRUTH_SPIN_UP_S)
    return run_flume(cfg, cmd, flow, state=state), []


def _drop_gaps(rec: LoggedRecord, keep: np.ndarray) -> LoggedRecord:
    return LoggedRecord(rec.time_s[keep], rec.opening_mm[keep], rec.hold[keep],
                        rec.flow_m3h[keep], {g: v[keep] for g, v in rec.levels_mm.items()},
                        rec.sidecar)  # fmt: skip


def routine_history(cfg: FlumeConfig, logger: LoggerConfig, settings: RoutineSettings, *,
                    base_flow_m3h: float, target_level_mm: float, gauge: str, seed: int,
                    sidecar: dict[str, Any] | None = None,
                    ) -> tuple[LoggedRecord, dict[str, Any]]:  # fmt: skip
    """A logged routine history and its truth (every move's :class:`LocalFopdt`).

    Parameters
    ----------
    cfg, logger : FlumeConfig, LoggerConfig
        The flume (use ``dx_m =`` :data:`ROUTINE_DX_M` for speed) and its logger.
    settings : RoutineSettings
        How the gate is driven and the history logged.
    base_flow_m3h : float
        Mean inflow, m³/h.
    target_level_mm : float
        Level the operator steers towards (the controller's first set-point), mm.
    gauge : str
        The gauge the operator (or controller) watches.
    seed : int
        Seed of every draw (moves, inflow, gaps, logger noise).
    sidecar : dict, optional
        Extra sidecar fields (``gate``, ...).

    Returns
    -------
    record : LoggedRecord
        The history as the logger wrote it (gaps dropped), sidecar ``test: "routine"``.
    truth : dict
        Settings, moves (time s, flow m³/h, openings mm, observed or inside a gap) with
        the flume's K, T, L for each, and the set-points.
    """
    run, setpoints = routine_run(cfg, settings, base_flow_m3h=base_flow_m3h,
                                 target_level_mm=target_level_mm, gauge=gauge,
                                 seed=seed)  # fmt: skip
    rng = np.random.default_rng(seed + 1)
    keep = _gap_mask(settings, run.time_s.size, cfg.sample_period_s, rng)
    side: dict[str, Any] = {"test": "routine", "control": settings.control, **(sidecar or {})}
    if setpoints:
        side["level_control"] = {"kind": "PI", "gauge": gauge,
                                 "setpoints_mm": [list(p) for p in setpoints]}  # fmt: skip
    rec = _drop_gaps(log_run(run, cfg, seed + 2, logger=logger, sidecar=side), keep)
    moves = []
    for i, before, after in moves_of(run):
        local = local_fopdt(cfg, float(run.flow_m3h[i]), before, after, gauge)
        moves.append({"time_s": round(float(run.time_s[i]), 3),
                      "observed": bool(keep[i - 1] and keep[min(i + 1, keep.size - 1)]),
                      **local.to_dict()})  # fmt: skip
    truth = {"settings": asdict(settings), "seed": seed, "gauge": gauge, "dx_m": cfg.dx_m,
             "base_flow_m3h": base_flow_m3h, "target_level_mm": target_level_mm,
             "setpoints_mm": [list(p) for p in setpoints], "moves": moves}  # fmt: skip
    return rec, truth
