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

This file holds the plant's pipeline (plant.c), its variables, its FMU state and the effect
blocks (effects.c). Each family's part is a mixin of its own, spliced in the same way:
gatetwin/fmu/slave_fopdt.py, slave_arx.py and slave_physical.py (the physical family and the
gate-law envelope of the other two); what they share with this class (CONFIG, PlantError) is
gatetwin/fmu/slave_config.py.
"""

from __future__ import annotations

import math
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

# BEGIN gatetwin.fmu.slave_guard
from gatetwin.fmu.slave_guard import GuardedSlave  # replaced by its source at export

# END gatetwin.fmu.slave_guard
# BEGIN gatetwin.fmu.slave_state
from gatetwin.fmu.slave_state import StateError, check_state  # replaced by its source at export

# END gatetwin.fmu.slave_state
# isort: split
# BEGIN gatetwin.fmu.slave_config
from gatetwin.fmu.slave_config import (  # replaced by its source at export
    CONFIG,
    CONFIG_JSON,
    PlantError,
    _g,
)

# END gatetwin.fmu.slave_config
# isort: split
# BEGIN gatetwin.plant.physical_kernel
from gatetwin.plant import physical_kernel  # replaced at export by the module's source

# END gatetwin.plant.physical_kernel
# isort: split
# BEGIN gatetwin.plant.blocks
from gatetwin.plant.blocks import (  # replaced by the module's source at export
    first_order,
    gain_map,
    move_toward,
    play,
    seiche_advance,
    seiche_equilibrium,
    seiche_output,
)

# END gatetwin.plant.blocks
# isort: split
# BEGIN gatetwin.fmu.slave_arx
from gatetwin.fmu.slave_arx import ArxFamily  # replaced by its source at export

# END gatetwin.fmu.slave_arx
# BEGIN gatetwin.fmu.slave_fopdt
from gatetwin.fmu.slave_fopdt import FopdtFamily  # replaced by its source at export

# END gatetwin.fmu.slave_fopdt
# BEGIN gatetwin.fmu.slave_physical
from gatetwin.fmu.slave_physical import PhysicalFamily  # replaced by its source at export

# END gatetwin.fmu.slave_physical

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

OK, WARNING, ERROR = 0, 1, 2


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


class GatetwinPlant(PhysicalFamily, FopdtFamily, ArxFamily, GuardedSlave):
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
