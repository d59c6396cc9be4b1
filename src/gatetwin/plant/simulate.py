"""Python reference simulation of a :class:`~gatetwin.plant.model.Plant`.

One step interface for every plant (``initialize`` then ``do_step``), written so that the
C FMU (``fmu_templates/``) and the pythonfmu FMU can follow it operation by operation and
agree with it to round-off. It is the semantic reference, not the fast path.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from gatetwin.errors import GatetwinError
from gatetwin.plant.model import (
    FLOW_RANGE_M3H,
    OPENING_RANGE_MM,
    FopdtPlant,
    Plant,
    interp_clamped,
)

#: Capacity of the FOPDT input-change history, as in the C FMU.
DELAY_HISTORY_CAPACITY = 4096
#: Relative tolerance for "the communication step is a whole number of ARX samples".
ARX_STEP_RTOL = 1e-9
#: Most ARX samples one communication step may span (guards against h / Ts overflowing).
ARX_MAX_SUBSTEPS = 1e9


class SimulationError(GatetwinError, ValueError):
    """An input or communication step the plant cannot honour."""


def check_inputs(opening_mm: float, flow_m3h: float) -> None:
    """Refuse NaN or physically impossible inputs (as the FMUs do with fmi2Error)."""
    if not OPENING_RANGE_MM[0] <= opening_mm <= OPENING_RANGE_MM[1]:
        raise SimulationError(
            f"opening_mm = {opening_mm} is outside [{OPENING_RANGE_MM[0]}, {OPENING_RANGE_MM[1]}]"
        )
    if not FLOW_RANGE_M3H[0] <= flow_m3h <= FLOW_RANGE_M3H[1]:
        raise SimulationError(
            f"flow_m3h = {flow_m3h} is outside [{FLOW_RANGE_M3H[0]}, {FLOW_RANGE_M3H[1]}]"
        )


@dataclass
class PlantSimulator:
    """Stepwise simulation of one plant.

    Use ``initialize(opening_mm, flow_m3h, time_s)``, then ``do_step(h, opening_mm,
    flow_m3h)`` per communication step; ``level_mm`` is the output at the current time.
    """

    plant: Plant
    time_s: float = 0.0
    x: float = 0.0
    history_t: list[float] = field(default_factory=list)
    history_u: list[float] = field(default_factory=list)
    x_hist: list[float] = field(default_factory=list)
    u_hist: list[float] = field(default_factory=list)
    flow_m3h: float = 0.0
    warned_range: bool = False

    def initialize(self, opening_mm: float, flow_m3h: float, time_s: float = 0.0) -> None:
        check_inputs(opening_mm, flow_m3h)
        self.time_s = time_s
        self.flow_m3h = flow_m3h
        self._check_range(flow_m3h)
        u = opening_mm - self.plant.opening_ref_mm
        p = self.plant
        if isinstance(p, FopdtPlant):
            self.x = p.schedule.at("gain_mm_per_mm", flow_m3h) * u
            self.history_t = [time_s]
            self.history_u = [u]
        else:
            a, b = p.coefficients(flow_m3h)
            sum_a = _sum_in_order(a)
            if sum_a == 1.0:
                raise SimulationError(
                    f"arx: no equilibrium at flow_m3h = {flow_m3h} (sum of a coefficients is 1)"
                )
            x0 = _sum_in_order(b) / (1.0 - sum_a) * u
            self.x = x0
            self.x_hist = [x0] * p.na
            self.u_hist = [u] * (p.nk + p.nb - 1)

    @property
    def level_mm(self) -> float:
        return self.plant.schedule.at("level_ref_mm", self.flow_m3h) + self.x

    def do_step(self, h: float, opening_mm: float, flow_m3h: float) -> float:
        """Advance by ``h`` seconds with inputs held; return the level at the new time."""
        check_inputs(opening_mm, flow_m3h)
        if not 0 < h < math.inf:
            raise SimulationError(f"communication step {h} s must be > 0 and finite")
        u = opening_mm - self.plant.opening_ref_mm
        # the family steps raise before they change any state, so a refused step changes nothing
        if isinstance(self.plant, FopdtPlant):
            self._fopdt_step(h, u, flow_m3h)
        else:
            self._arx_step(h, u, flow_m3h)
        self._check_range(flow_m3h)
        self.flow_m3h = flow_m3h
        self.time_s += h
        return self.level_mm

    # -- FOPDT ---------------------------------------------------------------------------
    def _fopdt_step(self, h: float, u: float, q: float) -> None:
        p = self.plant
        k = p.schedule.at("gain_mm_per_mm", q)
        tau = p.schedule.at("time_constant_s", q)
        delay = p.schedule.at("dead_time_s", q)
        t0 = self.time_s
        t1 = t0 + h
        if u != self.history_u[-1]:
            if len(self.history_u) >= DELAY_HISTORY_CAPACITY:
                raise SimulationError("input changes faster than the dead-time history can hold")
            self.history_t.append(t0)
            self.history_u.append(u)
        t = t0
        while t < t1:
            # entry i is the newest change that has arrived at the plant by t; the next
            # arrival history_t[i + 1] + delay is then > t, so every pass makes progress
            i = _last_arrived_index(self.history_t, delay, t)
            t_next = t1
            if i + 1 < len(self.history_t):
                t_next = min(t1, self.history_t[i + 1] + delay)
            target = k * self.history_u[i]
            self.x = target + (self.x - target) * math.exp(-(t_next - t) / tau)
            t = t_next
        self._prune_history(t1, p.max_dead_time_s)

    def _prune_history(self, t_now: float, max_delay: float) -> None:
        # drop entry 0 once entry 1 has arrived for every dead time up to max_delay
        while len(self.history_t) > 1 and self.history_t[1] + max_delay <= t_now:
            del self.history_t[0]
            del self.history_u[0]

    # -- ARX -----------------------------------------------------------------------------
    def _arx_step(self, h: float, u: float, q: float) -> None:
        p = self.plant
        n_float = h / p.sample_period_s
        if not n_float <= ARX_MAX_SUBSTEPS:
            raise SimulationError(
                f"communication step {h} s spans more than {ARX_MAX_SUBSTEPS:.0e} ARX samples"
            )
        n = round(n_float)
        if n < 1 or abs(n_float - n) > ARX_STEP_RTOL * max(1.0, n_float):
            raise SimulationError(
                f"communication step {h} s is not a whole multiple of the ARX sample period "
                f"{p.sample_period_s} s"
            )
        a, b = p.coefficients(q)
        for _ in range(n):
            # u_hist[0] is u(k) (the held input), u_hist[m] is u(k-m)
            self.u_hist = [u, *self.u_hist[:-1]] if self.u_hist else []
            x_new = 0.0
            for i in range(p.na):
                x_new += a[i] * self.x_hist[i]
            for j in range(p.nb):
                x_new += b[j] * self._u_lag(p.nk - 1 + j, u)
            self.x_hist = [x_new, *self.x_hist[:-1]]
            self.x = x_new

    def _u_lag(self, m: int, u: float) -> float:
        return u if m == 0 else self.u_hist[m]

    def _check_range(self, flow_m3h: float) -> None:
        lo, hi = self.plant.schedule.flow_range_m3h
        if not lo <= flow_m3h <= hi and not self.warned_range:
            self.warned_range = True
            warnings.warn(
                f"flow_m3h = {flow_m3h} outside the schedule's validity range [{lo}, {hi}]; "
                "parameters clamped",
                RuntimeWarning,
                stacklevel=3,
            )


def _last_arrived_index(times: list[float], delay: float, t: float) -> int:
    """Index of the last entry with ``times[i] + delay <= t`` (0 if none: the initial input).

    The comparison is made on arrival times (change time + dead time), the same sums that
    bound the integration intervals; comparing ``times[i] <= t - delay`` instead can pick an
    entry whose rounded arrival equals ``t`` and stall the integration loop.
    """
    i = len(times) - 1
    while i > 0 and times[i] + delay > t:
        i -= 1
    return i


def _sum_in_order(values: np.ndarray) -> float:
    """Left-to-right sum (numpy's pairwise ``sum`` reorders from 8 terms on; C does not)."""
    total = 0.0
    for v in values:
        total += float(v)
    return total


def simulate(
    plant: Plant,
    time_s: np.ndarray,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
) -> np.ndarray:
    """Level at every ``time_s`` with inputs held from each time to the next.

    ``opening_mm[i]`` and ``flow_m3h[i]`` are in force over ``[time_s[i], time_s[i+1])``.
    """
    t = np.asarray(time_s, dtype=float)
    e = np.asarray(opening_mm, dtype=float)
    q = np.asarray(flow_m3h, dtype=float)
    sim = PlantSimulator(plant)
    sim.initialize(float(e[0]), float(q[0]), float(t[0]))
    out = np.empty_like(t)
    out[0] = sim.level_mm
    for i in range(1, t.size):
        out[i] = sim.do_step(float(t[i] - t[i - 1]), float(e[i - 1]), float(q[i - 1]))
    return out


__all__ = ["PlantSimulator", "SimulationError", "check_inputs", "simulate", "interp_clamped"]
