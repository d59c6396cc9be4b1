"""Python reference simulation of a :class:`~gatetwin.plant.model.Plant`.

One step interface for every plant (``initialize`` then ``do_step``), written so that the
C FMU (``fmu_templates/``) and the pythonfmu FMU can follow it operation by operation and
agree with it to round-off. It is the semantic reference, not the fast path.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from gatetwin.plant import blocks
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.effects import EffectSet
from gatetwin.plant.inputs import SimulationError, check_inputs
from gatetwin.plant.model import (
    FopdtPlant,
    PhysicalPlant,
    Plant,
    envelope_steady,
    interp_clamped,
    steady_depth_m,
)
from gatetwin.plant.physical import PhysicalSimulator

#: Capacity of the FOPDT input-change history, as in the C FMU.
DELAY_HISTORY_CAPACITY = 4096
#: Relative tolerance for "the communication step is a whole number of ARX samples".
ARX_STEP_RTOL = 1e-9
#: Most ARX samples one communication step may span: a budget of work per step (1e6 samples
#: take milliseconds) that also guards against h / Ts overflowing.
ARX_MAX_SUBSTEPS = 1e6
#: Longest FOPDT communication step, s (the dead-time history and the exact solution stay
#: meaningful; every FMU rendering refuses a longer one).
FOPDT_MAX_STEP_S = 1e6


@dataclass
class EffectState:
    """State of the effect blocks (see :mod:`gatetwin.plant.effects`); unused fields stay 0.

    Attributes
    ----------
    actuator_mm, gate_mm : float
        Actuator position ``a`` and gate position ``g``, mm.
    held_gate_mm : float
        The gate position the FOPDT dynamics see (sampled on the actuator's grid), mm.
    grid_origin_s : float
        Origin of the actuator's sub-step grid (the initialisation time), s.
    seiche_x1, seiche_x2 : float
        Seiche oscillator states.
    inflow_mm, drift_mm : float
        Inflow term and accumulated drift, mm.
    sensed_mm : float
        Sensor-lag output, mm.
    """

    actuator_mm: float = 0.0
    gate_mm: float = 0.0
    held_gate_mm: float = 0.0
    grid_origin_s: float = 0.0
    seiche_x1: float = 0.0
    seiche_x2: float = 0.0
    inflow_mm: float = 0.0
    drift_mm: float = 0.0
    sensed_mm: float = 0.0


@dataclass
class PlantSimulator:
    """Stepwise simulation of one plant.

    Use ``initialize(opening_mm, flow_m3h, time_s)``, then ``do_step(h, opening_mm,
    flow_m3h)`` per communication step; ``level_mm`` is the output at the current time.

    Pipeline of a step (the FMUs follow it): the command is turned into pieces of constant
    gate position by the input blocks (one piece per step without a rate limit; pieces on the
    actuator's grid with one; one piece per sample for ARX), the dynamics and the seiche run
    over the pieces, then the inflow term and the drift over the whole step.
    """

    plant: Plant
    time_s: float = 0.0
    x: float = 0.0
    #: Depth of the pool below the gate, m, of an envelope FOPDT whose gate discharges into one
    #: (else 0; see :func:`~gatetwin.plant.physical_kernel.tail_pool_piece`).
    tail_m: float = 0.0
    history_t: list[float] = field(default_factory=list)
    history_u: list[float] = field(default_factory=list)
    x_hist: list[float] = field(default_factory=list)
    u_hist: list[float] = field(default_factory=list)
    flow_m3h: float = 0.0
    warned_range: bool = False
    fx: EffectSet = field(default_factory=EffectSet)
    es: EffectState = field(default_factory=EffectState)
    envelope_p: list[float] | None = None
    envelope_memo: dict[tuple[float, float], tuple[float, float, float]] = field(
        default_factory=dict
    )

    def initialize(self, opening_mm: float, flow_m3h: float, time_s: float = 0.0) -> None:
        check_inputs(opening_mm, flow_m3h)
        self.fx = self.plant.effect_set
        self.time_s = time_s
        self.flow_m3h = flow_m3h
        self._check_range(flow_m3h)
        self.es = EffectState(opening_mm, opening_mm, opening_mm, time_s)
        u = self._effective_input(opening_mm)
        p = self.plant
        if isinstance(p, FopdtPlant):
            self.envelope_p = list(p.envelope.values()) if p.envelope is not None else None
            self.envelope_memo.clear()
            if self.envelope_p is not None:
                self.x = self._envelope_point(u, flow_m3h)[0]
                self.tail_m = kernel.tail_steady_m(flow_m3h, self.envelope_p)
            else:
                self.x = self._fopdt_parameters(flow_m3h)[0] * u
            self.history_t = [time_s]
            self.history_u = [u]
        else:
            self.envelope_p = list(p.envelope.values()) if p.envelope is not None else None
            self.envelope_memo.clear()
            if self.envelope_p is not None:
                # the input is the gate law's steady level: at rest the state equals it
                x0 = u_in = self._envelope_point(u, flow_m3h)[0]
            else:
                a, b = p.coefficients(flow_m3h)
                sum_a, x0 = blocks.arx_equilibrium(a.tolist(), b.tolist(), u, p.na, p.nb)
                if sum_a == 1.0:
                    raise SimulationError(f"arx: no equilibrium at flow_m3h = {flow_m3h} (sum "
                                          "of a coefficients is 1)")  # fmt: skip
                u_in = u
            self.x = x0
            self.x_hist = [x0] * p.na
            self.u_hist = [u_in] * (p.nk + p.nb - 1)
        self._initialize_output_blocks(opening_mm, flow_m3h)

    def _initialize_output_blocks(self, opening_mm: float, flow_m3h: float) -> None:
        fx, es = self.fx, self.es
        if fx.seiche:
            v = opening_mm - self.plant.opening_ref_mm
            es.seiche_x1 = blocks.seiche_equilibrium(v, fx.seiche.period_s, fx.seiche.decay_time_s)
        if fx.inflow:
            es.inflow_mm = fx.inflow.gain_mm_per_m3h * (flow_m3h - fx.inflow.flow_ref_m3h)
        es.sensed_mm = self._level_ref(flow_m3h) + self.x

    @property
    def level_mm(self) -> float:
        """What the gauge reads, mm (the plant's output)."""
        fx, es = self.fx, self.es
        if fx.lag:
            return self._physical_terms(es.sensed_mm) + (es.drift_mm if fx.drift else 0.0)
        return self.process_level_mm + (es.drift_mm if fx.drift else 0.0)

    @property
    def process_level_mm(self) -> float:
        """The water level itself, mm: the output without the sensor lag and drift."""
        return self._physical_terms(self._level_ref(self.flow_m3h) + self.x)

    def _level_ref(self, flow_m3h: float) -> float:
        """What the output adds to the state: ``level_ref_mm(Q)``, or 0 for an envelope
        FOPDT (its state is the level itself)."""
        if self.envelope_p is not None:
            return 0.0
        return self.plant.schedule.at("level_ref_mm", flow_m3h)

    def _envelope_point(self, u: float, q: float) -> tuple[float, float]:
        """Steady level and (tangent) time constant of the envelope at the opening
        ``u + opening_ref`` (as the C FMU forms it) and discharge ``q``."""
        return self._envelope_steady(u, q)[:2]

    def _envelope_steady(self, u: float, q: float) -> tuple[float, float, float]:
        """:func:`~gatetwin.plant.model.envelope_steady` at ``u + opening_ref`` and ``q``;
        remembered for the last few inputs."""
        key = (u, q)
        point = self.envelope_memo.get(key)
        if point is None:
            if len(self.envelope_memo) > 64:
                self.envelope_memo.clear()
            point = envelope_steady(u + self.plant.opening_ref_mm, q, self.envelope_p)
            self.envelope_memo[key] = point
        return point

    def _piece_point(self, u: float, q: float) -> tuple[float, float]:
        """An envelope FOPDT piece from the state ``x`` with the input ``u`` held: the target
        and the storage's secant time constant to it (``piece_point`` of the C FMU)."""
        target, tangent, depth = self._envelope_steady(u, q)
        tau = kernel.secant_time_constant_s(
            self.x, target, depth, tangent, u + self.plant.opening_ref_mm, q, self.envelope_p
        )
        return target, tau

    def _tail_pool(self) -> bool:
        """Whether the plant is an envelope FOPDT whose gate discharges into a pool."""
        p = self.envelope_p
        return p is not None and bool(kernel.has_tail(p))

    def _tail_pool_piece(self, u: float, q: float, duration_s: float) -> None:
        """An envelope FOPDT piece with a pool below the gate (``piece`` of the C FMU): the
        sub-steps of the kernel's longest sub-step, the steady depth at the tail pool's depth
        at the start of each."""
        p = self.envelope_p
        e = u + self.plant.opening_ref_mm
        n = int(kernel.substep_count(duration_s, p))
        for _ in range(n):
            steady = steady_depth_m(e, q, p, self.tail_m)
            self.x, self.tail_m = kernel.tail_pool_piece(
                self.x, self.tail_m, steady, e, q, duration_s / n, p
            )

    def _physical_terms(self, y: float) -> float:
        """``y`` plus the seiche and inflow terms (in the output blocks' order)."""
        fx, es = self.fx, self.es
        if fx.seiche:
            y += blocks.seiche_output(es.seiche_x2, fx.seiche.period_s,
                                      fx.seiche.amplitude_mm_per_mm)  # fmt: skip
        if fx.inflow:
            y += es.inflow_mm
        return y

    def do_step(self, h: float, opening_mm: float, flow_m3h: float) -> float:
        """Advance by ``h`` seconds with inputs held; return the level at the new time."""
        check_inputs(opening_mm, flow_m3h)
        if not 0 < h < math.inf:
            raise SimulationError(f"communication step {h} s must be > 0 and finite")
        # every check raises before any state changes, so a refused step changes nothing
        if isinstance(self.plant, FopdtPlant):
            self._fopdt_check_step(h, opening_mm)
            for t_start, t_end, gate in self._fopdt_pieces(h, opening_mm):
                self._fopdt_piece(t_start, t_end, self._effective_input(gate), flow_m3h)
                self._seiche_piece(t_end - t_start, gate)
        else:
            n = self._arx_samples(h)
            a, b = (c.tolist() for c in self.plant.coefficients(flow_m3h))
            level_ref = self.plant.schedule.at("level_ref_mm", flow_m3h)
            for gate in self._arx_pieces(n, opening_mm):
                u = self._effective_input(gate)
                if self.envelope_p is None:
                    self._arx_sample(u, a, b, level_ref)
                else:
                    self._arx_sample(*self._arx_envelope(u, flow_m3h, a, b), level_ref)
                self._seiche_piece(self.plant.sample_period_s, gate)
        self._output_blocks_step(h, flow_m3h)
        self._check_range(flow_m3h)
        self.flow_m3h = flow_m3h
        self.time_s += h
        return self.level_mm

    # -- input blocks --------------------------------------------------------------------
    def _effective_input(self, gate_mm: float) -> float:
        """``u`` the dynamics see for a gate position (opening nonlinearity applied)."""
        v = gate_mm - self.plant.opening_ref_mm
        if self.fx.nonlinearity:
            return blocks.gain_map(v, self.fx.nonlinearity.gain_slope_per_mm)
        return v

    def _actuate(self, actuator: float, gate: float, command: float, duration_s: float
                 ) -> tuple[float, float]:  # fmt: skip
        """Actuator and gate after ``duration_s`` with ``command`` held (actuator monotone)."""
        fx = self.fx
        if fx.rate_limit:
            actuator = blocks.move_toward(actuator, command,
                                          fx.rate_limit.rate_mm_per_s * duration_s)  # fmt: skip
        else:
            actuator = command
        if fx.backlash:
            return actuator, blocks.play(gate, actuator, fx.backlash.deadband_mm)
        return actuator, actuator

    def _fopdt_pieces(self, h: float, command: float) -> Iterator[tuple[float, float, float]]:
        """``(t_start, t_end, gate)`` pieces of the step; updates the actuator state."""
        es, t0 = self.es, self.time_s
        t1 = t0 + h
        if not self.fx.rate_limit:
            es.actuator_mm, es.gate_mm = self._actuate(es.actuator_mm, es.gate_mm, command, h)
            es.held_gate_mm = es.gate_mm
            yield t0, t1, es.gate_mm
            return
        delta, origin = self.fx.rate_limit.substep_s, es.grid_origin_s
        k = blocks.grid_index_at_or_after(t0, origin, delta)
        tk, t_start, t_act = origin + k * delta, t0, t0
        while True:
            if tk > t_start:
                t_end = tk if tk < t1 else t1
                yield t_start, t_end, es.held_gate_mm
                if not tk < t1:
                    break
                t_start = tk
            es.actuator_mm, es.gate_mm = self._actuate(es.actuator_mm, es.gate_mm, command,
                                                       tk - t_act)  # fmt: skip
            es.held_gate_mm, t_act = es.gate_mm, tk
            k += 1
            tk = origin + k * delta
        es.actuator_mm, es.gate_mm = self._actuate(es.actuator_mm, es.gate_mm, command, t1 - t_act)

    def _arx_pieces(self, n: int, command: float) -> Iterator[float]:
        """The gate position at the start of each of the ``n`` ARX samples of the step."""
        es, ts = self.es, self.plant.sample_period_s
        duration = 0.0 if self.fx.rate_limit else ts
        for _ in range(n):
            es.actuator_mm, es.gate_mm = self._actuate(es.actuator_mm, es.gate_mm, command,
                                                       duration)  # fmt: skip
            es.held_gate_mm = es.gate_mm
            yield es.gate_mm
            duration = ts
        if self.fx.rate_limit:
            es.actuator_mm, es.gate_mm = self._actuate(es.actuator_mm, es.gate_mm, command, ts)

    # -- output blocks -------------------------------------------------------------------
    def _seiche_piece(self, duration_s: float, gate_mm: float) -> None:
        fx, es = self.fx, self.es
        if fx.seiche:
            es.seiche_x1, es.seiche_x2 = blocks.seiche_advance(
                es.seiche_x1,
                es.seiche_x2,
                gate_mm - self.plant.opening_ref_mm,
                duration_s,
                fx.seiche.period_s,
                fx.seiche.decay_time_s,
            )

    def _output_blocks_step(self, h: float, q: float) -> None:
        fx, es = self.fx, self.es
        if fx.inflow:
            target = fx.inflow.gain_mm_per_m3h * (q - fx.inflow.flow_ref_m3h)
            es.inflow_mm = blocks.first_order(es.inflow_mm, target, h, fx.inflow.time_constant_s)
        if fx.drift:
            es.drift_mm += fx.drift.rate_mm_per_s * h

    # -- FOPDT ---------------------------------------------------------------------------
    def _fopdt_parameters(self, q: float) -> tuple[float, float, float]:
        return fopdt_parameters(self.plant, self.fx, q)  # type: ignore[arg-type]

    def _fopdt_check_step(self, h: float, command: float) -> None:
        """Refuse a step that is too long or whose input changes would overflow the dead-time
        history."""
        if not h <= FOPDT_MAX_STEP_S:
            raise SimulationError(
                f"communication step {h} s exceeds the longest FOPDT step {FOPDT_MAX_STEP_S:g} s"
            )
        es = self.es
        if self.fx.rate_limit:
            delta, origin, t0 = self.fx.rate_limit.substep_s, es.grid_origin_s, self.time_s
            k0 = blocks.grid_index_at_or_after(t0, origin, delta)
            k1 = blocks.grid_index_at_or_after(t0 + h, origin, delta)
            pieces = k1 - k0 + (0 if origin + k0 * delta == t0 else 1)
            if len(self.history_u) + pieces > DELAY_HISTORY_CAPACITY:
                raise SimulationError(
                    f"communication step {h} s spans {pieces} actuator sub-steps; with the "
                    f"{len(self.history_u)} input changes held for the dead time they exceed "
                    f"the dead-time history ({DELAY_HISTORY_CAPACITY})"
                )
            return
        gate = self._actuate(es.actuator_mm, es.gate_mm, command, h)[1]
        u = self._effective_input(gate)
        if u != self.history_u[-1] and len(self.history_u) >= DELAY_HISTORY_CAPACITY:
            raise SimulationError("input changes faster than the dead-time history can hold")

    def _fopdt_piece(self, t0: float, t1: float, u: float, q: float) -> None:
        p = self.plant
        k, tau, delay = self._fopdt_parameters(q)
        lag = self.fx.lag
        level_ref = p.schedule.at("level_ref_mm", q) if lag else 0.0
        if u != self.history_u[-1]:
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
            if self._tail_pool():
                self._tail_pool_piece(self.history_u[i], q, t_next - t)
                t = t_next
                continue
            if self.envelope_p is not None:
                target, tau = self._piece_point(self.history_u[i], q)
            else:
                target = k * self.history_u[i]
            if lag:
                self.es.sensed_mm = blocks.lag_interval(
                    self.es.sensed_mm,
                    level_ref + target,
                    self.x - target,
                    t_next - t,
                    tau,
                    lag.time_constant_s,
                )
            self.x = blocks.first_order(self.x, target, t_next - t, tau)
            t = t_next
        self._prune_history(t1, p.max_dead_time_s)

    def _prune_history(self, t_now: float, max_delay: float) -> None:
        # drop entry 0 once entry 1 has arrived for every dead time up to max_delay
        while len(self.history_t) > 1 and self.history_t[1] + max_delay <= t_now:
            del self.history_t[0]
            del self.history_u[0]

    # -- ARX -----------------------------------------------------------------------------
    def _arx_samples(self, h: float) -> int:
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
        return n

    def _arx_sample(self, u: float, a: list[float], b: list[float], level_ref: float) -> None:
        p = self.plant
        x_new = blocks.arx_sample(self.x_hist, self.u_hist, a, b, u, p.na, p.nb, p.nk)
        self.x = x_new
        if self.fx.lag:
            self.es.sensed_mm = blocks.first_order(self.es.sensed_mm, level_ref + x_new,
                                                   p.sample_period_s,
                                                   self.fx.lag.time_constant_s)  # fmt: skip

    def _arx_envelope(self, u: float, q: float, a: list[float], b: list[float]
                      ) -> tuple[float, list[float], list[float]]:  # fmt: skip
        """An envelope ARX's input (the gate law's steady level) and coefficients at the
        steady point of ``u`` and ``q``: the pole scaled by the time constant there."""
        level, tau = self._envelope_point(u, q)
        tau_ref = self.plant.schedule.at("time_constant_ref_s", q)
        a_now, b_now = [0.0], [0.0] * len(b)
        blocks.arx_envelope_coefficients(a, b, a_now, b_now, len(b), tau_ref, tau)
        return level, a_now, b_now

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


def fopdt_parameters(plant: FopdtPlant, fx: EffectSet, q: float) -> tuple[float, float, float]:
    """``K``, ``T`` (flow-dependent gain of ``fx`` applied) and ``L`` at discharge ``q``."""
    k = plant.schedule.at("gain_mm_per_mm", q)
    tau = plant.schedule.at("time_constant_s", q)
    if fx.flow_gain:
        fg = fx.flow_gain
        k = blocks.flow_scaled(k, fg.gain_slope_per_m3h, q, fg.flow_ref_m3h)
        tau = blocks.flow_scaled(tau, fg.time_constant_slope_per_m3h, q, fg.flow_ref_m3h)
    return k, tau, plant.schedule.at("dead_time_s", q)


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


def simulator_for(plant: Plant) -> PlantSimulator | PhysicalSimulator:
    """The stepwise simulator of any plant (``initialize``, ``do_step``, ``level_mm``)."""
    if isinstance(plant, PhysicalPlant):
        return PhysicalSimulator(plant)
    return PlantSimulator(plant)


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
    sim = simulator_for(plant)
    sim.initialize(float(e[0]), float(q[0]), float(t[0]))
    out = np.empty_like(t)
    out[0] = sim.level_mm
    for i in range(1, t.size):
        out[i] = sim.do_step(float(t[i] - t[i - 1]), float(e[i - 1]), float(q[i - 1]))
    return out


__all__ = [
    "EffectState",
    "PlantSimulator",
    "SimulationError",
    "check_inputs",
    "fopdt_parameters",
    "interp_clamped",
    "simulate",
    "simulator_for",
]
