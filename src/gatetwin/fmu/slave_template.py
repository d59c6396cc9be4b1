"""pythonfmu slave of one gatetwin plant FMU; copied into the FMU with its CONFIG filled in.

Self-contained on purpose: the FMU runs where gatetwin is not installed, so this file uses the
standard library and pythonfmu only. It mirrors gatetwin.plant.simulate.PlantSimulator and the
C FMU (fmu_templates/plant.c, model_fopdt.c, model_arx.c, effects.c) operation by operation.
The effect blocks' and the ARX sample's arithmetic is gatetwin/plant/blocks.py itself, and
the physical family's is gatetwin/plant/physical_kernel.py: at export their sources replace
the imports between the BEGIN/END markers below, so the FMU carries them.

The FMI callbacks themselves are gatetwin/fmu/slave_guard.py's GuardedSlave (embedded the same
way): it answers every refusal with a status and a log line and keeps pythonfmu's wrapper from
crashing the host; this class is the plant behind it and raises PlantError with the reason.
pythonfmu forwards log messages only when the importer turned logging on.
"""

from __future__ import annotations

import json
import math
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

# BEGIN gatetwin.fmu.slave_guard
from gatetwin.fmu.slave_guard import GuardedSlave, RefusedError  # replaced by its source at export

# END gatetwin.fmu.slave_guard
# BEGIN gatetwin.fmu.slave_state
from gatetwin.fmu.slave_state import StateError, check_state  # replaced by its source at export

# END gatetwin.fmu.slave_state
# isort: split
# BEGIN gatetwin.plant.physical_kernel
from gatetwin.plant import physical_kernel  # replaced at export by the module's source

# END gatetwin.plant.physical_kernel
# isort: split
# BEGIN gatetwin.plant.blocks
from gatetwin.plant.blocks import (  # replaced by the module's source at export
    arx_envelope_coefficients,
    arx_equilibrium,
    arx_sample,
    first_order,
    flow_scaled,
    gain_map,
    grid_index_at_or_after,
    lag_interval,
    move_toward,
    play,
    seiche_advance,
    seiche_equilibrium,
    seiche_output,
)

# END gatetwin.plant.blocks

__all__ = [
    "CONFIG",
    "CONFIG_JSON",
    "ERROR",
    "OK",
    "WARNING",
    "GatetwinPlant",
    "PlantError",
    "interp_clamped",
]

CONFIG_JSON = "{}"  # replaced at export by gatetwin.fmu.python_build
CONFIG: dict[str, Any] = json.loads(CONFIG_JSON)

OK, WARNING, ERROR = 0, 1, 2


class PlantError(RefusedError):
    """An input, parameter, state or step the plant refuses (the message says why)."""


def interp_clamped(knots: list[float], column: list[float], q: float) -> float:
    """As gatetwin.plant.model.interp_clamped and plant_locate/plant_interp in plant.c."""
    n = len(knots)
    if n == 1 or q <= knots[0]:
        return column[0]
    if q >= knots[-1]:
        return column[-1]
    i = 0
    while q > knots[i + 1]:
        i += 1
    w = (q - knots[i]) / (knots[i + 1] - knots[i])
    return column[i] + w * (column[i + 1] - column[i])


def _g(value: float) -> str:
    """C's %.17g for the messages."""
    return f"{value:.17g}"


class GatetwinPlant(GuardedSlave):
    author = "gatetwin"
    description = CONFIG.get("summary")
    model_guid = CONFIG.get("guid", "")

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.modelName = CONFIG["model_identifier"]
        self.guid = CONFIG["guid"]
        self.variables = CONFIG["variables"]
        self.n_knots = CONFIG["n_knots"]
        self.columns = CONFIG["columns"]
        self.real = [float(v["start"] or 0.0) for v in self.variables]
        self.vr_opening = self._vr("opening_mm")
        self.vr_flow = self._vr("flow_m3h")
        self.vr_opening_ref = self._vr("opening_ref_mm")
        self.time_s = 0.0
        self.flow_in_force_m3h = 0.0
        self.initialized = False
        self.warned_flow_range = False
        self.warned_validity: list[str] = []
        self.parameters_changed = True
        self.dyn: dict[str, Any] = {"x": 0.0}
        #: the last steady point of the envelope: ((opening, discharge, *kernel), point)
        self.steady_point: tuple[tuple[float, ...], tuple[float, float, float]] = ((), (0, 0, 0))
        self.fx: dict[str, float] = {}
        for v in self.variables:
            self._register(v)

    def _vr(self, name: str) -> int:
        return next(v["vr"] for v in self.variables if v["name"] == name)

    def _register(self, v: dict[str, Any]) -> None:
        vr = v["vr"]
        kwargs: dict[str, Any] = {
            "causality": Fmi2Causality[v["causality"]],
            "variability": Fmi2Variability[v["variability"]],
            "description": v["description"],
            "getter": lambda: self._get(vr),
        }
        if v["initial"] is not None:
            kwargs["initial"] = Fmi2Initial[v["initial"]]
        if v["kind"] != "output":
            kwargs["setter"] = lambda value: self._set(vr, value)
            kwargs["start"] = v["start"]
        var = Real(v["name"], **kwargs)
        self.register_variable(var, nested=False)
        if var.value_reference != vr:
            raise RuntimeError(f"value reference of {v['name']} is not {vr}")

    # -- variables ----------------------------------------------------------------------------
    def _get(self, vr: int) -> float:
        """The getter pythonfmu registers (it reads start values at build time)."""
        return self._read(vr)

    def _set(self, vr: int, value: float) -> None:
        self._write([vr], [value])

    def _variable(self, vr: Any) -> dict[str, Any]:
        if type(vr) is not int or not 0 <= vr < len(self.variables):
            raise PlantError(f"unknown value reference {vr!r}")
        return self.variables[vr]

    def _read(self, vr: int) -> float:
        if self._variable(vr)["kind"] != "output":
            return self.real[vr]
        return self._output()

    def _write(self, vrs: list[int], values: list[float]) -> None:
        """Check every (value reference, value), then apply them all (or none)."""
        for vr in vrs:
            v = self._variable(vr)
            if v["kind"] == "output":
                raise PlantError(f"{v['name']} is an output and cannot be set")
            if v["kind"] == "fixed" and self.initialized:
                raise PlantError(
                    f"{v['name']} is a fixed parameter, settable only before "
                    "fmi2ExitInitializationMode"
                )
        for vr, value in zip(vrs, values, strict=True):
            self.real[vr] = float(value)
            if self.variables[vr]["kind"] != "input":
                self.parameters_changed = True

    def _column(self, name: str) -> list[float]:
        first = self.columns[name]
        return self.real[first : first + self.n_knots]

    def _at(self, name: str, q: float) -> float:
        return interp_clamped(self._column("flow_m3h"), self._column(name), q)

    # -- FMI (called by GuardedSlave, which refuses on PlantError) -------------------------------
    def _setup(self, start_time: float) -> None:
        if self.initialized:
            raise PlantError("the experiment is already initialised")
        if not math.isfinite(start_time):
            raise PlantError(f"startTime {_g(start_time)} s must be finite")
        self.time_s = float(start_time)

    def _initialize(self) -> None:
        if self.initialized:
            raise PlantError("the instance is already initialised")
        status, message = self._initial_state()
        level = self._finite_output("parameters and inputs")
        self._log_status(status, message)
        self._check_validity(level)

    def _step(self, current_time: float, step_size: float) -> None:
        rtol = CONFIG["communication_point_rtol"]
        if not self.initialized:
            raise PlantError("fmi2DoStep must not be called before fmi2ExitInitializationMode")
        if not abs(current_time - self.time_s) <= rtol * max(1.0, abs(self.time_s)):
            raise PlantError(
                f"fmi2DoStep: currentCommunicationPoint {_g(current_time)} s differs from the "
                f"FMU's time {_g(self.time_s)} s"
            )
        status, message = self._do_step(step_size)
        level = self._finite_output(f"the step of {_g(step_size)} s")
        self._log_status(status, message)
        self._check_validity(level)

    def _finite_output(self, cause: str) -> float:
        level = self._output()
        if not math.isfinite(level):
            name = self.variables[self._vr_output()]["name"]
            raise PlantError(f"{cause} make the output {name} = {_g(level)} (not finite)")
        return level

    def _vr_output(self) -> int:
        return next(v["vr"] for v in self.variables if v["kind"] == "output")

    def _log_status(self, status: int, message: str) -> None:
        if status == WARNING:
            self.log(message, Fmi2Status.warning, "logStatusWarning")

    def _check_validity(self, level_mm: float) -> None:
        """Warn once per instance, the first time the opening, the discharge or the level
        leaves the model's validity envelope (in that order; plant.c's check_validity)."""
        values = {"opening_mm": self.real[self.vr_opening], "flow_m3h": self.real[self.vr_flow],
                  "level_mm": level_mm}  # fmt: skip
        if self.warned_validity:
            return
        for quantity, (lo, hi, word, unit) in CONFIG["validity"].items():
            value = values[quantity]
            if lo <= value <= hi:
                continue
            self.warned_validity.append(quantity)
            message = (
                f"{word} {value:g} outside the model's validity {lo:g}..{hi:g} {unit}; "
                "results are extrapolated"
            )
            self.log(message, Fmi2Status.warning, "logStatusWarning")
            return

    # -- FMU state (plain JSON data; GuardedSlave owns the handles) -----------------------------
    def _snapshot(self) -> dict[str, Any]:
        """A copy of everything a step or an initialisation changes (cheap: no JSON)."""
        return {
            "time_s": self.time_s,
            "real": list(self.real),
            "flow_in_force_m3h": self.flow_in_force_m3h,
            "initialized": self.initialized,
            "warned_flow_range": self.warned_flow_range,
            "warned_validity": list(self.warned_validity),
            "parameters_changed": self.parameters_changed,
            "dyn": {k: list(v) if isinstance(v, list) else v for k, v in self.dyn.items()},
            "fx": dict(self.fx),
        }

    def _restore(self, snapshot: dict[str, Any]) -> None:
        self.time_s = snapshot["time_s"]
        self.real = snapshot["real"]
        self.flow_in_force_m3h = snapshot["flow_in_force_m3h"]
        self.initialized = snapshot["initialized"]
        self.warned_flow_range = snapshot["warned_flow_range"]
        self.warned_validity = snapshot["warned_validity"]
        self.parameters_changed = snapshot["parameters_changed"]
        self.dyn = snapshot["dyn"]
        self.fx = snapshot["fx"]

    def _state(self) -> dict[str, Any]:
        return self._snapshot()

    def _load_state(self, state: dict[str, Any]) -> None:
        self._restore(state)

    def _checked_state(self, state: dict[str, Any]) -> dict[str, Any]:
        """A restorable copy of ``state`` after checking all of it; PlantError otherwise."""
        try:
            checked = check_state(state, len(self.variables), CONFIG)
        except StateError as exc:
            raise PlantError(str(exc)) from None
        current = self._snapshot()
        self._restore(checked)  # the parameter checks read the instance
        try:
            self._check_parameters()
            if self.initialized:
                self._finite_output("the restored state's parameters")
        finally:
            self._restore(current)
        return checked

    # -- the plant (plant.c) --------------------------------------------------------------------
    def _check_inputs(self, opening_mm: float, flow_m3h: float) -> None:
        lo, hi = CONFIG["opening_range_mm"]
        if not lo <= opening_mm <= hi:
            raise PlantError(f"opening_mm = {_g(opening_mm)} is outside [{_g(lo)}, {_g(hi)}]")
        lo, hi = CONFIG["flow_range_m3h"]
        if not lo <= flow_m3h <= hi:
            raise PlantError(f"flow_m3h = {_g(flow_m3h)} is outside [{_g(lo)}, {_g(hi)}]")

    def _check_parameters(self) -> None:
        for v in self.variables:
            if v["kind"] in ("tunable", "fixed") and not math.isfinite(self.real[v["vr"]]):
                raise PlantError(f"parameter {v['name']} = {_g(self.real[v['vr']])} must be finite")
        first = self.columns["flow_m3h"]
        for vr in range(first + 1, first + self.n_knots):
            if not self.real[vr] > self.real[vr - 1]:
                raise PlantError(
                    "schedule knots must increase strictly: "
                    f"{self.variables[vr]['name']} = {_g(self.real[vr])} <= "
                    f"{self.variables[vr - 1]['name']} = {_g(self.real[vr - 1])}"
                )
        if CONFIG["family"] == "fopdt":
            self._fopdt_check_parameters()
            if self._envelope():
                self._physical_check_parameters()
        elif CONFIG["family"] == "physical":
            self._physical_check_parameters()
        else:
            self._arx_check_parameters()
            if self._envelope():
                self._physical_check_parameters()
        self._effects_check_parameters()

    def _check_flow_range(self, flow_m3h: float) -> tuple[int, str]:
        knots = self._column("flow_m3h")
        lo, hi = knots[0], knots[-1]
        if not lo <= flow_m3h <= hi and not self.warned_flow_range:
            self.warned_flow_range = True
            return WARNING, (
                f"flow_m3h = {_g(flow_m3h)} outside the schedule's validity range "
                f"[{_g(lo)}, {_g(hi)}]; parameters clamped (warned once per instance)"
            )
        return OK, ""

    def _equilibrium(self, u: float, q: float) -> float:
        if self._envelope():
            return self._envelope_point(u, q)[0]
        if CONFIG["family"] == "fopdt":
            return self._fopdt_parameters(q)[0] * u
        if CONFIG["family"] == "physical":
            gate = physical_kernel.actuator_target_mm(u, self._physical())
            return self._physical_level(self._physical_depth(gate, q), gate, q)
        return self._arx_equilibrium(u, q)

    def _initial_state(self) -> tuple[int, str]:
        opening_mm, flow_m3h = self.real[self.vr_opening], self.real[self.vr_flow]
        self._check_inputs(opening_mm, flow_m3h)
        self._check_parameters()
        u = self._effective_input(opening_mm)
        x0 = self._equilibrium(u, flow_m3h)
        if CONFIG["family"] == "fopdt":
            self._fopdt_initialize(u, x0)
        elif CONFIG["family"] == "physical":
            self._physical_initialize(u, x0, flow_m3h)
        else:
            self._arx_initialize(u, x0)
        self._effects_initialize(opening_mm, flow_m3h, self._level_offset(flow_m3h) + x0)
        self.flow_in_force_m3h = flow_m3h
        self.parameters_changed = False
        self.initialized = True
        return self._check_flow_range(flow_m3h)

    def _do_step(self, h: float) -> tuple[int, str]:
        opening_mm, flow_m3h = self.real[self.vr_opening], self.real[self.vr_flow]
        self._check_inputs(opening_mm, flow_m3h)
        if not 0 < h < math.inf:
            raise PlantError(f"communication step {_g(h)} s must be > 0 and finite")
        if self.parameters_changed:
            self._check_parameters()
            self.parameters_changed = False
        # ---- pipeline: input blocks and dynamics over the family's pieces, then output blocks
        if CONFIG["family"] == "fopdt":
            self._fopdt_check_step(h, opening_mm)
            self._fopdt_step(h, opening_mm, flow_m3h)
        elif CONFIG["family"] == "physical":
            self._physical_step(h, opening_mm, flow_m3h)
        else:
            n = self._arx_samples(h)
            self._arx_step(n, opening_mm, flow_m3h)
        self._effects_step_end(h, flow_m3h)
        status = self._check_flow_range(flow_m3h)
        self.flow_in_force_m3h = flow_m3h
        self.time_s += h
        return status

    def _output(self) -> float:
        if self.initialized:
            return self._effects_output(self._level_offset(self.flow_in_force_m3h) + self.dyn["x"])
        opening_mm, flow_m3h = self.real[self.vr_opening], self.real[self.vr_flow]
        self._check_inputs(opening_mm, flow_m3h)
        self._check_parameters()
        x0 = self._equilibrium(self._effective_input(opening_mm), flow_m3h)
        level = self._level_offset(flow_m3h) + x0
        if self._has("inflow_disturbance"):
            level += self._p("inflow_disturbance", "gain_mm_per_m3h") * (
                flow_m3h - self._p("inflow_disturbance", "flow_ref_m3h")
            )
        return level

    # -- physical (model_physical.c around physical_kernel) -------------------------------------
    def _physical(self) -> list[float]:
        first = CONFIG["kernel_first"]
        return self.real[first : first + len(physical_kernel.PARAMETERS)]

    def _physical_check_parameters(self) -> None:
        first = CONFIG["kernel_first"]
        for name, bound in CONFIG["physical_lower_bounds"].items():
            vr = first + physical_kernel.INDEX[name]
            if not self.real[vr] > bound:
                raise PlantError(f"parameter {self.variables[vr]['name']} = {_g(self.real[vr])} "
                                 f"must be > {_g(bound)}")  # fmt: skip
        if not physical_kernel.storage_room_m2(self._physical()) > 0.0:
            raise PlantError(f"the storage area {CONFIG['physical_storage_rule']}")
        if "level_mm" in CONFIG["validity"] and "flow_m3h" in CONFIG["validity"]:
            for level in CONFIG["validity"]["level_mm"][:2]:
                for flow in CONFIG["validity"]["flow_m3h"][:2]:
                    if not physical_kernel.operating_room_m2(level, flow, self._physical()) > 0.0:
                        raise PlantError(
                            f"the storage area at level {_g(level)} mm and {_g(flow)} m3/h: "
                            f"{CONFIG['physical_operating_storage_rule']}"
                        )

    def _envelope(self) -> bool:
        return CONFIG["family"] in ("fopdt", "arx") and CONFIG["kernel_first"] is not None

    def _envelope_point(self, u: float, q: float) -> tuple[float, float]:
        """Steady level and time constant at the opening u + opening_ref (kernel_point.c)."""
        return self._envelope_steady(u, q)[:2]

    def _envelope_steady(self, u: float, q: float) -> tuple[float, float, float]:
        """The same and the steady depth at the gate, m (kernel_envelope_steady); the
        bisection only when the opening, the discharge or a parameter changed (as
        ``piece_point`` of model_fopdt.c keeps its point while they are held)."""
        p = self._physical()
        e = u + self.real[self.vr_opening_ref]
        key = (e, q, *p)
        if self.steady_point[0] != key:
            depth = self._physical_depth(e, q)
            self.steady_point = (key, (
                physical_kernel.level_mm(depth, e, q, p),
                physical_kernel.time_constant_s(depth, e, q, p),
                depth,
            ))  # fmt: skip
        return self.steady_point[1]

    def _piece_point(self, u: float, x: float, q: float) -> tuple[float, float]:
        """A piece from the level x with u held: the target and the storage's secant time
        constant to it (piece_point of model_fopdt.c)."""
        target, tangent, depth = self._envelope_steady(u, q)
        e = u + self.real[self.vr_opening_ref]
        return target, physical_kernel.secant_time_constant_s(
            x, target, depth, tangent, e, q, self._physical()
        )

    def _tail_pool(self) -> bool:
        """An envelope FOPDT whose gate discharges into a pool (model_fopdt.c)."""
        return self._envelope() and bool(physical_kernel.has_tail(self._physical()))

    def _tail_pool_piece(self, u: float, q: float, duration_s: float) -> None:
        """Sub-steps of the kernel's tail_pool_piece (tail_piece of model_fopdt.c)."""
        p, d = self._physical(), self.dyn
        e = u + self.real[self.vr_opening_ref]
        n = int(physical_kernel.substep_count(duration_s, p))
        for _ in range(n):
            steady = self._physical_depth(e, q, d["tail_m"])
            d["x"], d["tail_m"] = physical_kernel.tail_pool_piece(
                d["x"], d["tail_m"], steady, e, q, duration_s / n, p
            )

    def _level_offset(self, q: float) -> float:
        return 0.0 if self._envelope() else self._at("level_ref_mm", q)

    def _physical_depth(self, gate_mm: float, q: float, tail_m: float | None = None) -> float:
        """The steady depth (kernel_point.c): the tail pool steady, or held at ``tail_m``."""
        k, p = physical_kernel, self._physical()
        if tail_m is None:
            return k.steady_depth_m(gate_mm, q, p)
        return k.held_steady_depth_m(tail_m, gate_mm, q, p)

    def _physical_level(self, depth_m: float, gate_mm: float, q: float) -> float:
        return physical_kernel.level_mm(depth_m, gate_mm, q, self._physical())

    def _physical_initialize(self, u: float, x0: float, q: float) -> None:
        gate = physical_kernel.actuator_target_mm(u, self._physical())
        self.dyn = {
            "x": x0,
            "depth_m": self._physical_depth(gate, q),
            "tail_m": physical_kernel.tail_steady_m(q, self._physical()),
            "gate_mm": gate,
        }

    def _physical_step(self, h: float, command: float, q: float) -> None:
        p = self._physical()
        n = physical_kernel.substep_count(h, p)
        if not n <= CONFIG["physical_max_substeps"]:
            raise PlantError(
                f"communication step {_g(h)} s needs {n:.0f} sub-steps of at most "
                f"{_g(p[physical_kernel.INDEX['max_substep_s']])} s; the limit is "
                f"{CONFIG['physical_max_substeps']}"
            )
        target = physical_kernel.actuator_target_mm(command, p)
        depth, tail, gate, dt = self.dyn["depth_m"], self.dyn["tail_m"], self.dyn["gate_mm"], h / n
        for _ in range(int(n)):
            start = gate  # drives the seiche over the sub-step (model_physical.c)
            depth, tail, gate = physical_kernel.substep(depth, tail, gate, target, q, dt, p)
            self._seiche_piece(dt, start)
        self.dyn = {
            "x": physical_kernel.level_mm(depth, gate, q, p),
            "depth_m": depth,
            "tail_m": tail,
            "gate_mm": gate,
        }

    # -- FOPDT (model_fopdt.c) ------------------------------------------------------------------
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

    # -- ARX (model_arx.c) ----------------------------------------------------------------------
    def _arx_check_parameters(self) -> None:
        period = self.real[self._vr("sample_period_s")]
        if not period > 0.0:
            raise PlantError(f"sample_period_s = {_g(period)} must be > 0")

    def _arx_coefficients(self, q: float) -> tuple[list[float], list[float]]:
        na, nb, _ = CONFIG["arx_orders"]
        a = [self._at(f"a{i}", q) for i in range(1, na + 1)]
        b = [self._at(f"b{j}", q) for j in range(1, nb + 1)]
        return a, b

    def _arx_equilibrium(self, u: float, q: float) -> float:
        if self._envelope():
            return self._envelope_point(u, q)[0]
        na, nb, _ = CONFIG["arx_orders"]
        a, b = self._arx_coefficients(q)
        sum_a, x0 = arx_equilibrium(a, b, u, na, nb)
        if sum_a == 1.0:
            raise PlantError(
                f"arx: no equilibrium at flow_m3h = {_g(self.real[self.vr_flow])} "
                "(sum of a coefficients is 1)"
            )
        return x0

    def _arx_initialize(self, u: float, x0: float) -> None:
        na, nb, nk = CONFIG["arx_orders"]
        u_in = x0 if self._envelope() else u  # an envelope ARX's input is a level
        self.dyn = {"x": x0, "x_hist": [x0] * na, "u_hist": [u_in] * (nk + nb - 1)}

    def _arx_envelope(self, u: float, q: float, a: list[float], b: list[float]
                      ) -> tuple[float, list[float], list[float]]:  # fmt: skip
        """The gate law's steady level and the coefficients scaled there (model_arx.c)."""
        level, tau = self._envelope_point(u, q)
        a_now, b_now = [0.0], [0.0] * len(b)
        arx_envelope_coefficients(a, b, a_now, b_now, len(b), self._at("time_constant_ref_s", q),
                                  tau)  # fmt: skip
        return level, a_now, b_now

    def _arx_samples(self, h: float) -> int:
        period = self.real[self._vr("sample_period_s")]
        n_float = h / period
        if not n_float <= CONFIG["arx_max_substeps"]:
            raise PlantError(
                f"communication step {_g(h)} s spans more than "
                f"{CONFIG['arx_max_substeps']:.0e} ARX samples"
            )
        n = round(n_float)
        if n < 1 or abs(n_float - n) > CONFIG["arx_step_rtol"] * max(1.0, n_float):
            raise PlantError(
                f"communication step {_g(h)} s is not a whole multiple of the ARX sample "
                f"period {_g(period)} s"
            )
        return n

    def _arx_step(self, n: int, command: float, q: float) -> None:
        na, nb, nk = CONFIG["arx_orders"]
        a, b = a0, b0 = self._arx_coefficients(q)
        d, fx = self.dyn, self.fx
        ts = self.real[self._vr("sample_period_s")]
        level_ref = self._at("level_ref_mm", q)
        rate_limited = self._has("actuator_rate_limit")
        duration = 0.0 if rate_limited else ts
        for _ in range(n):
            self._actuate(fx, command, duration)
            fx["held_gate_mm"] = fx["gate_mm"]
            u = self._effective_input(fx["gate_mm"])
            if self._envelope():
                u, a, b = self._arx_envelope(u, q, a0, b0)
            x_new = arx_sample(d["x_hist"], d["u_hist"], a, b, u, na, nb, nk)
            d["x"] = x_new
            if self._has("sensor_lag"):
                fx["sensed_mm"] = first_order(fx["sensed_mm"], level_ref + x_new, ts,
                                              self._p("sensor_lag", "time_constant_s"))  # fmt: skip
            self._seiche_piece(ts, fx["gate_mm"])
            duration = ts
        if rate_limited:
            self._actuate(fx, command, ts)

    # -- effect blocks (effects.c) --------------------------------------------------------------
    def _has(self, kind: str) -> bool:
        return kind in CONFIG["effects"]

    def _p(self, kind: str, name: str) -> float:
        return self.real[CONFIG["effects"][kind][name]]

    def _effects_check_parameters(self) -> None:
        for vr, lo, hi, exclusive in CONFIG["effect_limits"]:
            value, name = self.real[vr], self.variables[vr]["name"]
            if exclusive and not value > lo:
                raise PlantError(f"{name} = {_g(value)} must be > {lo:g}")
            if not exclusive and not value >= lo:
                raise PlantError(f"{name} = {_g(value)} must be >= {lo:g}")
            if not value <= hi:
                raise PlantError(f"{name} = {_g(value)} must be <= {hi:g}")

    def _effective_input(self, gate_mm: float) -> float:
        v = gate_mm - self.real[self.vr_opening_ref]
        if self._has("opening_nonlinearity"):
            return gain_map(v, self._p("opening_nonlinearity", "gain_slope_per_mm"))
        return v

    def _actuate(self, fx: dict[str, float], command: float, duration: float) -> None:
        if self._has("actuator_rate_limit"):
            travel = self._p("actuator_rate_limit", "rate_mm_per_s") * duration
            fx["actuator_mm"] = move_toward(fx["actuator_mm"], command, travel)
        else:
            fx["actuator_mm"] = command
        if self._has("actuator_backlash"):
            band = self._p("actuator_backlash", "deadband_mm")
            fx["gate_mm"] = play(fx["gate_mm"], fx["actuator_mm"], band)
        else:
            fx["gate_mm"] = fx["actuator_mm"]

    def _effects_initialize(self, opening_mm: float, flow_m3h: float, level_mm: float) -> None:
        fx = dict.fromkeys(("seiche_x1", "seiche_x2", "inflow_mm", "drift_mm"), 0.0)
        fx.update(actuator_mm=opening_mm, gate_mm=opening_mm, held_gate_mm=opening_mm,
                  grid_origin_s=self.time_s, sensed_mm=level_mm)  # fmt: skip
        if self._has("seiche"):
            fx["seiche_x1"] = seiche_equilibrium(
                opening_mm - self.real[self.vr_opening_ref],
                self._p("seiche", "period_s"),
                self._p("seiche", "decay_time_s"),
            )
        if self._has("inflow_disturbance"):
            fx["inflow_mm"] = self._p("inflow_disturbance", "gain_mm_per_m3h") * (
                flow_m3h - self._p("inflow_disturbance", "flow_ref_m3h")
            )
        self.fx = fx

    def _seiche_piece(self, duration: float, gate_mm: float) -> None:
        if self._has("seiche"):
            fx = self.fx
            fx["seiche_x1"], fx["seiche_x2"] = seiche_advance(
                fx["seiche_x1"],
                fx["seiche_x2"],
                gate_mm - self.real[self.vr_opening_ref],
                duration,
                self._p("seiche", "period_s"),
                self._p("seiche", "decay_time_s"),
            )

    def _effects_step_end(self, h: float, q: float) -> None:
        fx = self.fx
        if self._has("inflow_disturbance"):
            target = self._p("inflow_disturbance", "gain_mm_per_m3h") * (
                q - self._p("inflow_disturbance", "flow_ref_m3h")
            )
            tau = self._p("inflow_disturbance", "time_constant_s")
            fx["inflow_mm"] = first_order(fx["inflow_mm"], target, h, tau)
        if self._has("sensor_drift"):
            fx["drift_mm"] += self._p("sensor_drift", "rate_mm_per_s") * h

    def _effects_output(self, level_mm: float) -> float:
        fx = self.fx
        y = fx["sensed_mm"] if self._has("sensor_lag") else level_mm
        if self._has("seiche"):
            y += seiche_output(fx["seiche_x2"], self._p("seiche", "period_s"),
                               self._p("seiche", "amplitude_mm_per_mm"))  # fmt: skip
        if self._has("inflow_disturbance"):
            y += fx["inflow_mm"]
        if self._has("sensor_drift"):
            y += fx["drift_mm"]
        return y
