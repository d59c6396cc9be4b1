"""The FOPDT family's part of the pythonfmu slave: its schedule's parameters and checks, the
dead-time history and the step in pieces of held input.

Spliced into the slave at export like ``slave_guard.py`` (between the BEGIN/END markers of
``slave_template.py``), without its imports of gatetwin: the slave defines those names
itself, so this file too uses the standard library only once embedded.
:class:`FopdtFamily` is a mixin of ``GatetwinPlant``, which holds the instance's variables and
state; it mirrors fmu_templates/model_fopdt.c. It is not the plant's pipeline
(``slave_template.py``) nor the gate-law envelope (``slave_physical.py``).
"""

from __future__ import annotations

from typing import Any

# BEGIN gatetwin imports (removed at export: the slave defines these names)
from gatetwin.fmu.slave_config import CONFIG, PlantError, _g
from gatetwin.plant import physical_kernel
from gatetwin.plant.blocks import first_order, flow_scaled, grid_index_at_or_after, lag_interval

# END gatetwin imports

__all__ = ["FopdtFamily"]


class FopdtFamily:
    """The FOPDT family (model_fopdt.c): methods of ``GatetwinPlant``."""

    def _fopdt_check_parameters(self) -> None:
        for k in range(self.n_knots):
            tau_vr = self.columns["time_constant_s"] + k
            delay_vr = self.columns["dead_time_s"] + k
            if not self.real[tau_vr] > 0.0:
                name = self.variables[tau_vr]["name"]
                raise PlantError(f"{name} = {_g(self.real[tau_vr])} must be > 0")
            if not self.real[delay_vr] >= 0.0:
                name = self.variables[delay_vr]["name"]
                raise PlantError(f"{name} = {_g(self.real[delay_vr])} must be >= 0")
            if self.initialized and self.real[delay_vr] > self.dyn["max_dead_time_s"]:
                raise PlantError(
                    f"{self.variables[delay_vr]['name']} = {_g(self.real[delay_vr])} exceeds the "
                    f"dead-time horizon {_g(self.dyn['max_dead_time_s'])} s fixed at "
                    "initialisation (older inputs are no longer held)"
                )

    def _fopdt_initialize(self, u: float, x0: float) -> None:
        tail = 0.0
        if self._envelope():
            tail = physical_kernel.tail_steady_m(self.real[self.vr_flow],
                                                          self._physical())  # fmt: skip
        self.dyn = {
            "x": x0,
            "change_t": [self.time_s],
            "change_u": [u],
            "max_dead_time_s": max(self._column("dead_time_s")),
            "tail_m": tail,
        }

    def _fopdt_parameters(self, q: float) -> tuple[float, float]:
        k = self._at("gain_mm_per_mm", q)
        tau = self._at("time_constant_s", q)
        if self._has("flow_dependent_gain"):
            ref = self._p("flow_dependent_gain", "flow_ref_m3h")
            k = flow_scaled(k, self._p("flow_dependent_gain", "gain_slope_per_m3h"), q, ref)
            tau = flow_scaled(
                tau, self._p("flow_dependent_gain", "time_constant_slope_per_m3h"), q, ref
            )
        return k, tau

    def _fopdt_check_step(self, h: float, command: float) -> None:
        if not h <= CONFIG["fopdt_max_step_s"]:
            raise PlantError(
                f"communication step {_g(h)} s exceeds the longest FOPDT step "
                f"{_g(CONFIG['fopdt_max_step_s'])} s"
            )
        capacity = CONFIG["history_capacity"]
        count = len(self.dyn["change_u"])
        if self._has("actuator_rate_limit"):
            delta = self._p("actuator_rate_limit", "substep_s")
            origin, t0 = self.fx["grid_origin_s"], self.time_s
            k0 = grid_index_at_or_after(t0, origin, delta)
            k1 = grid_index_at_or_after(t0 + h, origin, delta)
            pieces = k1 - k0 + (0 if origin + k0 * delta == t0 else 1)
            if count + pieces > capacity:
                raise PlantError(
                    f"communication step {_g(h)} s spans {pieces} actuator sub-steps; with the "
                    f"{count} input changes held for the dead time they exceed the dead-time "
                    f"history ({capacity})"
                )
            return
        probe = dict(self.fx)
        self._actuate(probe, command, h)
        u = self._effective_input(probe["gate_mm"])
        if u != self.dyn["change_u"][-1] and count >= capacity:
            raise PlantError(
                "input changes faster than the dead-time history can hold "
                f"({capacity} change points within the longest dead time)"
            )

    def _fopdt_step(self, h: float, command: float, q: float) -> None:
        k, tau = self._fopdt_parameters(q)
        delay = self._at("dead_time_s", q)
        level_ref = self._at("level_ref_mm", q)
        for t_start, t_end, gate in self._fopdt_pieces(h, command):
            self._fopdt_piece(t_start, t_end, self._effective_input(gate), (k, tau, delay),
                              level_ref, q)  # fmt: skip
            self._seiche_piece(t_end - t_start, gate)

    def _fopdt_pieces(self, h: float, command: float) -> Any:
        fx, t0 = self.fx, self.time_s
        t1 = t0 + h
        if not self._has("actuator_rate_limit"):
            self._actuate(fx, command, h)
            fx["held_gate_mm"] = fx["gate_mm"]
            yield t0, t1, fx["gate_mm"]
            return
        delta, origin = self._p("actuator_rate_limit", "substep_s"), fx["grid_origin_s"]
        k = grid_index_at_or_after(t0, origin, delta)
        tk, t_start, t_act = origin + k * delta, t0, t0
        while True:
            if tk > t_start:
                t_end = tk if tk < t1 else t1
                yield t_start, t_end, fx["held_gate_mm"]
                if not tk < t1:
                    break
                t_start = tk
            self._actuate(fx, command, tk - t_act)
            fx["held_gate_mm"], t_act = fx["gate_mm"], tk
            k += 1
            tk = origin + k * delta
        self._actuate(fx, command, t1 - t_act)

    def _fopdt_piece(
        self,
        t0: float,
        t1: float,
        u: float,
        params: tuple[float, float, float],
        level_ref: float,
        q: float,
    ) -> None:
        d = self.dyn
        times, inputs = d["change_t"], d["change_u"]
        k, tau, delay = params
        lag = self._has("sensor_lag")
        if u != inputs[-1]:
            times.append(t0)
            inputs.append(u)
        t = t0
        while t < t1:
            j = len(times) - 1
            while j > 0 and times[j] + delay > t:
                j -= 1
            t_next = t1
            if j + 1 < len(times):
                t_next = min(t1, times[j + 1] + delay)
            if self._tail_pool():
                self._tail_pool_piece(inputs[j], q, t_next - t)
                t = t_next
                continue
            if self._envelope():
                target, tau = self._piece_point(inputs[j], d["x"], q)
            else:
                target = k * inputs[j]
            if lag:
                self.fx["sensed_mm"] = lag_interval(
                    self.fx["sensed_mm"],
                    level_ref + target,
                    d["x"] - target,
                    t_next - t,
                    tau,
                    self._p("sensor_lag", "time_constant_s"),
                )
            d["x"] = first_order(d["x"], target, t_next - t, tau)
            t = t_next
        while len(times) > 1 and times[1] + d["max_dead_time_s"] <= t1:
            del times[0]
            del inputs[0]
