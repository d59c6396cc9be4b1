"""1D Saint-Venant solver of the reach upstream of the gate.

Conservative first-order finite volumes on a uniform grid, HLL fluxes with the hydrostatic
reconstruction of Audusse et al. (2004) — well balanced: a lake at rest stays at rest over
the sloping bed — and semi-implicit Manning friction. Inflow boundary: prescribed discharge
Q(t). Outflow boundary: the gate (:mod:`gatetwin.flume.gate`). Explicit time stepping at a
fixed step that divides the logger period, set from the CFL condition at the flume's depth
limit.

Why numba: one step touches ~100 cells, so numpy's per-call overhead (~1 µs × ~50 array
operations) would cap the speed near 20× real time; compiled loops run the 3000 s benchmark
hundreds of times faster than real time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.gate import G, gate_law_array, unit_discharge

__all__ = [
    "Grid",
    "HydraulicState",
    "advance",
    "law_of",
    "leaf_speed",
    "leaf_step",
    "tailwater_of",
    "time_step_s",
]


@dataclass(frozen=True)
class Grid:
    """Cell centres and bed of the simulated reach."""

    n_cells: int
    dx_m: float
    distance_upstream_m: np.ndarray  # of each cell centre from the gate
    bed_m: np.ndarray  # bed elevation of each cell (gate sill = 0)

    @classmethod
    def of(cls, cfg: FlumeConfig) -> Grid:
        n = cfg.n_cells
        dx = cfg.pool_length_m / n
        dist = cfg.pool_length_m - (np.arange(n) + 0.5) * dx
        return cls(n, dx, dist, cfg.bed_slope * dist)

    def probe(self, distance_m: float) -> tuple[int, float]:
        """Left cell index and weight for linear interpolation at ``distance_m``."""
        x = (self.distance_upstream_m[0] - distance_m) / self.dx_m
        i = min(max(int(math.floor(x)), 0), self.n_cells - 2)
        return i, x - i


def time_step_s(cfg: FlumeConfig, grid: Grid) -> tuple[float, int]:
    """Fixed solver step (dividing the logger period) and steps per sample."""
    wave_speed = math.sqrt(G * (cfg.depth_limit_m + 0.1)) + 0.6
    dt_max = cfg.cfl * grid.dx_m / wave_speed
    n_sub = math.ceil(cfg.sample_period_s / dt_max)
    return cfg.sample_period_s / n_sub, n_sub


@njit(cache=True)
def _hll(hl: float, ql: float, hr: float, qr: float) -> tuple[float, float]:
    ul = ql / hl if hl > 1e-9 else 0.0
    ur = qr / hr if hr > 1e-9 else 0.0
    cl = math.sqrt(G * hl)
    cr = math.sqrt(G * hr)
    sl = min(ul - cl, ur - cr)
    sr = max(ul + cl, ur + cr)
    fl0, fl1 = ql, ql * ul + 0.5 * G * hl * hl
    fr0, fr1 = qr, qr * ur + 0.5 * G * hr * hr
    if sl >= 0.0:
        return fl0, fl1
    if sr <= 0.0:
        return fr0, fr1
    inv = 1.0 / (sr - sl)
    f0 = (sr * fl0 - sl * fr0 + sl * sr * (hr - hl)) * inv
    f1 = (sr * fl1 - sl * fr1 + sl * sr * (qr - ql)) * inv
    return f0, f1


@njit(cache=True)
def leaf_speed(depth_m: float, no_load_speed: float, stall_depth_m: float) -> float:
    """Actuator speed under the hydrostatic load of ``depth_m`` of water on the leaf.

    An electric drive slows linearly with its torque; the load on the leaf grows with the
    square of the depth, so ``v = v0 · (1 − (h / h_stall)²)``, floored at 5 % of ``v0``.
    """
    ratio = depth_m / stall_depth_m
    return no_load_speed * max(0.05, 1.0 - ratio * ratio)


@njit(cache=True)
def leaf_step(pos: float, command: float, max_step: float) -> float:
    d = command - pos
    if d > max_step:
        return pos + max_step
    if d < -max_step:
        return pos - max_step
    return command


@njit(cache=True)
def advance(
    h: np.ndarray,
    q: np.ndarray,
    bed: np.ndarray,
    dx: float,
    dt: float,
    inflow_m2s: np.ndarray,
    command_m: np.ndarray,
    actuator: np.ndarray,
    position_m: np.ndarray,
    flow_m3h: np.ndarray,
    manning_n: float,
    tailwater_m: float,
    law: np.ndarray,
    probe_index: np.ndarray,
    probe_weight: np.ndarray,
    steps_per_sample: int,
    levels_out: np.ndarray,
    outflow_out: np.ndarray,
) -> None:
    """Advance ``len(inflow_m2s)`` steps in place, sampling probes every few steps.

    ``levels_out[k, j]`` receives the depth at probe ``j`` after sample ``k``'s steps;
    ``outflow_out[k]`` the volume per unit width that left through the gate during them.
    Inputs are per solver step. ``h``, ``q`` are depth (m) and unit discharge (m²/s).
    The gate leaf follows ``command_m`` at the actuator's speed (see :func:`leaf_speed`);
    ``actuator`` = (start position m, no-load speed m/s, stall depth m); ``position_m``
    receives the leaf position after every step.
    """
    n = h.size
    f0 = np.empty(n + 1)
    f1l = np.empty(n + 1)  # momentum flux seen by the cell left of each face
    f1r = np.empty(n + 1)  # momentum flux seen by the cell right of each face
    n_steps = inflow_m2s.size
    pos = actuator[0]
    k = 0
    out_acc = 0.0
    for s in range(n_steps):
        # inflow face: prescribed discharge, hydrostatic pressure of the first cell
        q_in = inflow_m2s[s]
        f0[0] = q_in
        f1r[0] = q_in * q_in / h[0] + 0.5 * G * h[0] * h[0]
        for i in range(n - 1):
            zs = max(bed[i], bed[i + 1])
            hl = max(0.0, h[i] + bed[i] - zs)
            hr = max(0.0, h[i + 1] + bed[i + 1] - zs)
            ul = q[i] / h[i]
            ur = q[i + 1] / h[i + 1]
            a0, a1 = _hll(hl, hl * ul, hr, hr * ur)
            f0[i + 1] = a0
            f1l[i + 1] = a1 + 0.5 * G * (h[i] * h[i] - hl * hl)
            f1r[i + 1] = a1 + 0.5 * G * (h[i + 1] * h[i + 1] - hr * hr)
        # gate face: the leaf moves first, at a speed set by the load on it
        hg = h[n - 1]
        pos = leaf_step(pos, command_m[s], leaf_speed(hg, actuator[1], actuator[2]) * dt)
        position_m[s] = pos
        q_out = unit_discharge(hg, pos, tailwater_m, flow_m3h[s], law)
        f0[n] = q_out
        f1l[n] = q_out * q[n - 1] / hg + 0.5 * G * hg * hg
        r = dt / dx
        for i in range(n):
            h_new = h[i] - r * (f0[i + 1] - f0[i])
            q_new = q[i] - r * (f1l[i + 1] - f1r[i])
            if h_new < 1e-4:
                h_new = 1e-4
            fr = dt * G * manning_n * manning_n * abs(q_new) / h_new ** (7.0 / 3.0)
            h[i] = h_new
            q[i] = q_new / (1.0 + fr)
        out_acc += q_out * dt
        if (s + 1) % steps_per_sample == 0:
            for j in range(probe_index.size):
                i0 = probe_index[j]
                w = probe_weight[j]
                levels_out[k, j] = (1.0 - w) * h[i0] + w * h[i0 + 1]
            outflow_out[k] = out_acc
            out_acc = 0.0
            k += 1


@dataclass
class HydraulicState:
    """Depth and unit discharge of every cell (mutable: the solver's working arrays)."""

    depth_m: np.ndarray
    unit_discharge_m2s: np.ndarray

    def volume_m3(self, cfg: FlumeConfig, grid: Grid) -> float:
        return float(np.sum(self.depth_m) * grid.dx_m * cfg.width_m)


def law_of(cfg: FlumeConfig) -> np.ndarray:
    return gate_law_array(cfg.gate)


def tailwater_of(cfg: FlumeConfig) -> float:
    return -1.0 if cfg.tailwater_depth_m is None else float(cfg.tailwater_depth_m)
