"""Fast simulation of a plant on a uniform time grid, for fitting.

The same semantics as :mod:`gatetwin.plant.simulate` (the reference), specialised to inputs
that change only at the points of a uniform grid of step ``step_s`` (a record's nominal
sample period): the FOPDT with its dead time is then an exact two-tap recursion per grid
interval (``L = n dt + theta``: the input of interval ``j - n - 1`` acts for ``theta``, that of
interval ``j - n`` for the rest), and the effect blocks run per interval, the rate-limited
actuator on its sub-step grid. Loops are compiled with numba around the effect blocks' and
the ARX sample's own arithmetic (:mod:`gatetwin.plant.blocks`, compiled as it is). Tests hold
it equal to the reference to round-off; it is a faster rendering of the same plant, not
another model.

The grid starts at the first record sample; a record's samples are mapped to the nearest grid
point (:func:`grid_index`), and inputs are held from one sample to the next, as the FMU
validation harness holds them across logging gaps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from gatetwin.errors import IdentificationError
from gatetwin.plant import blocks
from gatetwin.plant.effects import EffectSet
from gatetwin.plant.kernel_render import numba_functions
from gatetwin.plant.model import ArxPlant, FopdtPlant, Plant

__all__ = ["GridInputs", "grid_index", "grid_inputs", "simulate_grid"]


@dataclass(frozen=True)
class GridInputs:
    """Inputs on a uniform grid: ``command_mm[j]``, ``flow_m3h[j]`` held over interval ``j``.

    Attributes
    ----------
    command_mm, flow_m3h : ndarray
        One value per grid interval (``n`` intervals, ``n + 1`` points).
    step_s : float
        Grid step, s.
    sample_point : ndarray of int
        Grid point of every record sample.
    """

    command_mm: np.ndarray
    flow_m3h: np.ndarray
    step_s: float
    sample_point: np.ndarray

    @property
    def n_intervals(self) -> int:
        return int(self.command_mm.size)


def grid_index(time_s: np.ndarray, step_s: float) -> np.ndarray:
    """Nearest grid point of every sample time (grid origin: the first sample)."""
    t = np.asarray(time_s, dtype=float)
    return np.rint((t - t[0]) / step_s).astype(np.int64)


def grid_inputs(
    time_s: np.ndarray, command_mm: np.ndarray, flow_m3h: np.ndarray, step_s: float
) -> GridInputs:
    """Hold every sample's inputs until the next sample, on the grid of ``step_s``."""
    points = grid_index(time_s, step_s)
    if np.any(np.diff(points) < 1):
        raise IdentificationError(
            f"two samples fall on one point of the {step_s:g} s grid (time jitter above half a "
            "sample period)"
        )
    n = int(points[-1])
    owner = np.searchsorted(points, np.arange(n), side="right") - 1
    return GridInputs(
        np.asarray(command_mm, float)[owner], np.asarray(flow_m3h, float)[owner], float(step_s),
        points,
    )  # fmt: skip


# --------------------------------------------------------------------------- kernels


# The effect blocks' and the ARX sample's arithmetic, compiled: the very functions the
# reference simulator and the pythonfmu FMU run (:mod:`gatetwin.plant.blocks`), each calling
# its siblings' compiled copies, so this module only loops.
_blocks = numba_functions(blocks)
_move_toward = _blocks.move_toward
_play = _blocks.play
_relax = _blocks.first_order
_lag_interval = _blocks.lag_interval
_seiche_advance = _blocks.seiche_advance
_seiche_equilibrium = _blocks.seiche_equilibrium
_seiche_output = _blocks.seiche_output
_gain_map = _blocks.gain_map
_flow_scaled = _blocks.flow_scaled
# inlined: a call per sample would pass the coefficient rows as array views, which costs more
# than the sample itself (benchmarks/bench_arx.py)
_arx_sample = njit(cache=True, inline="always")(blocks.arx_sample)


@njit(cache=True)
def _gate_seen(command, has_rate, travel, has_band, band):  # pragma: no cover - numba
    """Gate position the dynamics see over each interval (see gatetwin.plant.effects)."""
    n = command.size
    seen = np.empty(n)
    a = command[0]
    g = command[0]
    for j in range(n):
        if has_rate:
            seen[j] = g
            a = _move_toward(a, command[j], travel)
        else:
            a = command[j]
        g = _play(g, a, band) if has_band else a
        if not has_rate:
            seen[j] = g
    return seen


@njit(cache=True)
def _fopdt(u, gain, tau, delay, level_ref, dt, x0, lag):  # pragma: no cover - numba
    """Bulk level (level_ref + x, or the sensor-lag output) at every grid point."""
    n = u.size
    out = np.empty(n + 1)
    x = x0
    z = level_ref[0] + x0
    out[0] = z if lag > 0.0 else level_ref[0] + x0
    for j in range(n):
        whole = math.floor(delay[j] / dt)
        theta = delay[j] - whole * dt
        i_old = j - int(whole) - 1
        i_new = i_old + 1
        u_old = u[i_old] if i_old > 0 else u[0]
        u_new = u[i_new] if i_new > 0 else u[0]
        for part in range(2):
            d = theta if part == 0 else dt - theta
            if d <= 0.0:
                continue
            target = gain[j] * (u_old if part == 0 else u_new)
            if lag > 0.0:
                z = _lag_interval(z, level_ref[j] + target, x - target, d, tau[j], lag)
            x = _relax(x, target, d, tau[j])
        out[j + 1] = z if lag > 0.0 else level_ref[j] + x
    return out


@njit(cache=True)
def _arx(u, a, b, nk, level_ref, x0, u0, dt, lag):  # pragma: no cover - numba
    n, na, nb = u.size, a.shape[1], b.shape[1]
    lags = nk + nb - 1
    x_hist = np.full(na, x0)
    u_hist = np.full(lags, u0)
    out = np.empty(n + 1)
    z = level_ref[0] + x0
    out[0] = z if lag > 0.0 else level_ref[0] + x0
    for j in range(n):
        x = _arx_sample(x_hist, u_hist, a[j], b[j], u[j], na, nb, nk)
        if lag > 0.0:
            z = _relax(z, level_ref[j] + x, dt, lag)
        out[j + 1] = z if lag > 0.0 else level_ref[j] + x
    return out


@njit(cache=True)
def _seiche(v, dt, period, decay, amplitude):  # pragma: no cover - numba
    n = v.size
    out = np.zeros(n + 1)
    x1 = _seiche_equilibrium(v[0], period, decay)
    x2 = 0.0
    for j in range(n):
        x1, x2 = _seiche_advance(x1, x2, v[j], dt, period, decay)
        out[j + 1] = _seiche_output(x2, period, amplitude)
    return out


@njit(cache=True)
def _first_order(target, dt, tau):  # pragma: no cover - numba
    n = target.size
    out = np.empty(n + 1)
    x = target[0]
    out[0] = x
    for j in range(n):
        x = _relax(x, target[j], dt, tau)
        out[j + 1] = x
    return out


@njit(cache=True)
def _flow_scaled_all(value, slope, flow, flow_ref):  # pragma: no cover - numba
    out = np.empty(flow.size)
    for j in range(flow.size):
        out[j] = _flow_scaled(value[j], slope, flow[j], flow_ref)
    return out


@njit(cache=True)
def _gain_mapped(v, slope):  # pragma: no cover - numba
    out = np.empty(v.size)
    for j in range(v.size):
        out[j] = _gain_map(v[j], slope)
    return out


# --------------------------------------------------------------------------- rendering


def _column(plant: Plant, name: str, flow: np.ndarray) -> np.ndarray:
    knots = np.asarray(plant.schedule.flow_m3h, dtype=float)
    values = np.asarray(plant.schedule.values[name], dtype=float)
    if knots.size == 1 or np.all(values == values[0]):
        return np.full(flow.size, values[0])
    return np.interp(flow, knots, values)


def _substeps(fx: EffectSet, plant: Plant, step_s: float) -> int:
    if not fx.rate_limit or isinstance(plant, ArxPlant):
        return 1
    m = step_s / fx.rate_limit.substep_s
    if abs(m - round(m)) > 1e-9 * m or round(m) < 1:
        raise IdentificationError(
            f"the actuator sub-step {fx.rate_limit.substep_s:g} s must divide the grid step "
            f"{step_s:g} s"
        )
    return int(round(m))


def _effective(fx: EffectSet, gate: np.ndarray, opening_ref: float) -> np.ndarray:
    v = gate - opening_ref
    if fx.nonlinearity:
        return _gain_mapped(v, fx.nonlinearity.gain_slope_per_mm)
    return v


def _bulk(plant: Plant, fx: EffectSet, u: np.ndarray, flow: np.ndarray, dt: float) -> np.ndarray:
    lag = fx.lag.time_constant_s if fx.lag else 0.0
    level_ref = _column(plant, "level_ref_mm", flow)
    if isinstance(plant, FopdtPlant):
        gain = _column(plant, "gain_mm_per_mm", flow)
        tau = _column(plant, "time_constant_s", flow)
        if fx.flow_gain:
            fg = fx.flow_gain
            gain = _flow_scaled_all(gain, fg.gain_slope_per_m3h, flow, fg.flow_ref_m3h)
            tau = _flow_scaled_all(tau, fg.time_constant_slope_per_m3h, flow, fg.flow_ref_m3h)
        delay = _column(plant, "dead_time_s", flow)
        return _fopdt(u, gain, tau, delay, level_ref, dt, gain[0] * u[0], lag)
    a = np.column_stack([_column(plant, f"a{i}", flow) for i in range(1, plant.na + 1)])
    b = np.column_stack([_column(plant, f"b{j}", flow) for j in range(1, plant.nb + 1)])
    sum_a, x0 = blocks.arx_equilibrium(a[0].tolist(), b[0].tolist(), float(u[0]), plant.na,
                                       plant.nb)  # fmt: skip
    if sum_a == 1.0:
        raise IdentificationError("arx: no equilibrium (sum of a coefficients is 1)")
    return _arx(u, a, b, plant.nk, level_ref, x0, u[0], dt, lag)


def simulate_grid(plant: Plant, inputs: GridInputs) -> np.ndarray:
    """Level (mm) at every record sample of ``inputs``, free run from equilibrium.

    Raises
    ------
    IdentificationError
        An ARX plant whose sample period is not the grid step, or an actuator sub-step that
        does not divide it.
    """
    fx = plant.effect_set
    dt = inputs.step_s
    if isinstance(plant, ArxPlant) and abs(plant.sample_period_s - dt) > 1e-9 * dt:
        raise IdentificationError(
            f"arx sample period {plant.sample_period_s:g} s differs from the grid step {dt:g} s"
        )
    m = _substeps(fx, plant, dt)
    command = np.repeat(inputs.command_mm, m)
    flow = np.repeat(inputs.flow_m3h, m)
    fine = dt / m
    travel = fx.rate_limit.rate_mm_per_s * fine if fx.rate_limit else 0.0
    band = fx.backlash.deadband_mm if fx.backlash else 0.0
    gate = _gate_seen(command, bool(fx.rate_limit), travel, bool(fx.backlash), band)
    level = _bulk(plant, fx, _effective(fx, gate, plant.opening_ref_mm), flow, fine)
    if fx.seiche:
        s = fx.seiche
        level = level + _seiche(gate - plant.opening_ref_mm, fine, s.period_s, s.decay_time_s,
                                s.amplitude_mm_per_mm)  # fmt: skip
    if fx.inflow:
        target = fx.inflow.gain_mm_per_m3h * (flow - fx.inflow.flow_ref_m3h)
        level = level + _first_order(target, fine, fx.inflow.time_constant_s)
    if fx.drift:
        level = level + fx.drift.rate_mm_per_s * fine * np.arange(level.size)
    return level[inputs.sample_point * m]
