"""Run the virtual flume: inputs per logger sample in, true (noise-free) responses out.

The actuator (finite speed, 1 mm resolution) turns the commanded opening into the gate's
actual position; the solver advances the hydraulics; probes read the depth at each gauge at
every sample. Noise, spikes and the log format are the logger's business
(:mod:`gatetwin.flume.logger`), not this module's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gatetwin.errors import FlumeError
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.gate import G, unit_discharge
from gatetwin.flume.solver import Grid, HydraulicState, advance, law_of, tailwater_of, time_step_s


@dataclass(frozen=True)
class FlumeRun:
    """Noise-free result of a flume run, one row per logger sample.

    Attributes
    ----------
    time_s : ndarray
        Sample times, s.
    command_mm, position_mm : ndarray
        Commanded opening and the gate's actual position at each sample, mm.
    moving : ndarray of bool
        True if the gate moved during the interval ending at the sample.
    flow_m3h : ndarray
        Inflow at each sample, m³/h.
    depth_mm : dict[str, ndarray]
        True depth at each gauge, mm (no datum offset, no noise).
    outflow_m3h : ndarray
        Mean gate discharge over the interval ending at each sample, m³/h.
    volume_balance_error : float
        |ΔV − (V_in − V_out)| / V_in over the run (mass conservation check).
    final_state : HydraulicState
        Hydraulic state at the end (to continue a run).
    """

    time_s: np.ndarray
    command_mm: np.ndarray
    position_mm: np.ndarray
    moving: np.ndarray
    flow_m3h: np.ndarray
    depth_mm: dict[str, np.ndarray]
    outflow_m3h: np.ndarray
    volume_balance_error: float
    final_state: HydraulicState


def steady_gate_depth_m(cfg: FlumeConfig, flow_m3h: float, opening_mm: float) -> float:
    """Depth upstream of the gate at which the gate passes ``flow_m3h`` (bisection)."""
    q = flow_m3h / 3600.0 / cfg.width_m
    law, tw, e = law_of(cfg), tailwater_of(cfg), opening_mm / 1000.0
    lo, hi = 1e-4, 50.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if unit_discharge(mid, e, tw, flow_m3h, law) < q:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def initial_state(cfg: FlumeConfig, flow_m3h: float, opening_mm: float) -> HydraulicState:
    """A level water surface at the gate's steady depth, flowing at ``flow_m3h``."""
    grid = Grid.of(cfg)
    h_gate = steady_gate_depth_m(cfg, flow_m3h, opening_mm)
    if h_gate > 3 * cfg.depth_limit_m:
        raise FlumeError(
            f"flume: Q = {flow_m3h} m³/h through e = {opening_mm} mm needs a depth of "
            f"{h_gate:.2f} m; the flume is {cfg.depth_limit_m} m deep"
        )
    depth = h_gate + grid.bed_m[-1] - grid.bed_m
    q = np.full(grid.n_cells, flow_m3h / 3600.0 / cfg.width_m)
    return HydraulicState(depth, q)


def _check_inputs(cfg: FlumeConfig, command_mm: np.ndarray, flow_m3h: np.ndarray) -> None:
    if command_mm.shape != flow_m3h.shape or command_mm.ndim != 1 or command_mm.size < 2:
        raise FlumeError("flume: opening and flow schedules must be 1-D of the same length >= 2")
    if not (np.all(np.isfinite(command_mm)) and np.all(command_mm > 0)):
        raise FlumeError("flume: openings must be finite and > 0 mm")
    if not (np.all(np.isfinite(flow_m3h)) and np.all(flow_m3h > 0)):
        raise FlumeError("flume: flows must be finite and > 0 m³/h")


def run_flume(
    cfg: FlumeConfig,
    command_mm: np.ndarray,
    flow_m3h: np.ndarray,
    *,
    state: HydraulicState | None = None,
    start_position_mm: float | None = None,
) -> FlumeRun:
    """Simulate one sample period per entry of the input schedules.

    ``command_mm[k]`` and ``flow_m3h[k]`` are in force during the interval ending at sample
    ``k`` (sample 0 is the initial state at t = 0). Without ``state`` the run starts from
    :func:`initial_state` of the first inputs; call :func:`spin_up` first for a steady start.
    """
    command_mm = np.asarray(command_mm, dtype=float)
    flow_m3h = np.asarray(flow_m3h, dtype=float)
    _check_inputs(cfg, command_mm, flow_m3h)
    grid = Grid.of(cfg)
    dt, n_sub = time_step_s(cfg, grid)
    st = state if state is not None else initial_state(cfg, flow_m3h[0], command_mm[0])
    h, q = st.depth_m.copy(), st.unit_discharge_m2s.copy()
    start = command_mm[0] if start_position_mm is None else start_position_mm
    cmd_fine = np.repeat(command_mm[1:], n_sub)
    n_delay = min(round(cfg.actuator_delay_s / dt), cmd_fine.size)
    leaf_cmd = np.concatenate([np.full(n_delay, start), cmd_fine[: cmd_fine.size - n_delay]])
    pos_fine = np.empty(cmd_fine.size)
    actuator = np.array(
        [start / 1000.0, cfg.actuator_speed_mm_s / 1000.0, cfg.actuator_stall_depth_m]
    )
    flow_fine = np.repeat(flow_m3h[1:], n_sub)
    names = list(cfg.gauges_m)
    probes = [grid.probe(cfg.gauges_m[g]) for g in names]
    p_idx = np.array([p[0] for p in probes], dtype=np.int64)
    p_w = np.array([p[1] for p in probes])
    n = command_mm.size
    levels = np.empty((n, len(names)))
    levels[0] = [(1 - w) * h[i] + w * h[i + 1] for i, w in probes]
    outflow = np.zeros(n)
    v0 = float(np.sum(h))
    advance(
        h, q, grid.bed_m, grid.dx_m, dt, flow_fine / 3600.0 / cfg.width_m, leaf_cmd / 1000.0,
        actuator, pos_fine, flow_fine, cfg.manning_n, tailwater_of(cfg), law_of(cfg), p_idx,
        p_w, n_sub, levels[1:], outflow[1:],
    )  # fmt: skip
    pos_fine *= 1000.0
    if not np.all(np.isfinite(h)) or np.max(h) > 3 * cfg.depth_limit_m:
        raise FlumeError("flume: the run diverged or overtopped the flume (check inputs)")
    v_in = float(np.sum(flow_fine)) / 3600.0 / cfg.width_m * dt
    v_out = float(np.sum(outflow))
    dv = (float(np.sum(h)) - v0) * grid.dx_m
    balance = abs(dv - (v_in - v_out)) / v_in
    pos = np.concatenate([[start], pos_fine[n_sub - 1 :: n_sub]])
    step_moved = np.abs(np.diff(np.concatenate([[start], pos_fine]))) > 0
    step_moved |= np.abs(cmd_fine - pos_fine) > 0  # motor running, leaf not yet there
    moved = np.concatenate([[False], step_moved.reshape(-1, n_sub).max(axis=1)])
    return FlumeRun(
        time_s=np.arange(n) * cfg.sample_period_s,
        command_mm=command_mm,
        position_mm=pos,
        moving=moved,
        flow_m3h=flow_m3h,
        depth_mm={g: levels[:, j] * 1000.0 for j, g in enumerate(names)},
        outflow_m3h=outflow / cfg.sample_period_s * cfg.width_m * 3600.0,
        volume_balance_error=balance,
        final_state=HydraulicState(h, q),
    )


def spin_up(
    cfg: FlumeConfig, flow_m3h: float, opening_mm: float, duration_s: float = 900.0
) -> HydraulicState:
    """Steady state for constant inputs: run from a level surface for ``duration_s``."""
    n = max(2, math.ceil(duration_s / cfg.sample_period_s))
    run = run_flume(cfg, np.full(n, float(opening_mm)), np.full(n, float(flow_m3h)))
    return run.final_state


__all__ = ["FlumeRun", "G", "initial_state", "run_flume", "spin_up", "steady_gate_depth_m"]
