"""pythonfmu slave of one gatetwin plant FMU; copied into the FMU with its CONFIG filled in.

Self-contained on purpose: the FMU runs where gatetwin is not installed, so this file uses the
standard library and pythonfmu only. It mirrors gatetwin.plant.simulate.PlantSimulator and the
C FMU (fmu_templates/plant.c, model_fopdt.c, model_arx.c) operation by operation.

pythonfmu 0.7.0 maps ``do_step() -> False`` to fmi2Discard and any exception to fmi2Fatal, and
forwards log messages only when the importer turned logging on; refused steps therefore return
fmi2Discard with the reason logged at error level, and leave the state unchanged.
"""

from __future__ import annotations

import json
import math
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

CONFIG_JSON = "{}"  # replaced at export by gatetwin.fmu.python_build
CONFIG: dict[str, Any] = json.loads(CONFIG_JSON)

OK, WARNING, ERROR = 0, 1, 2


class PlantError(Exception):
    """An input, parameter or step the plant refuses (the message says why)."""


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


class GatetwinPlant(Fmi2Slave):
    author = "gatetwin"
    description = CONFIG.get("summary")

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
        self.parameters_changed = True
        self.dyn: dict[str, Any] = {"x": 0.0}
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
        if self.variables[vr]["kind"] != "output":
            return self.real[vr]
        try:
            return self._output()
        except PlantError as exc:
            self.log(f"fmi2GetReal: {exc}", Fmi2Status.error, "logStatusError")
            return math.nan

    def _set(self, vr: int, value: float) -> None:
        kind = self.variables[vr]["kind"]
        if kind == "fixed" and self.initialized:
            raise PlantError(
                f"fmi2SetReal: {self.variables[vr]['name']} is a fixed parameter, settable only "
                "before fmi2ExitInitializationMode"
            )
        self.real[vr] = float(value)
        if kind != "input":
            self.parameters_changed = True

    def _column(self, name: str) -> list[float]:
        first = self.columns[name]
        return self.real[first : first + self.n_knots]

    def _at(self, name: str, q: float) -> float:
        return interp_clamped(self._column("flow_m3h"), self._column(name), q)

    # -- FMI ------------------------------------------------------------------------------------
    def setup_experiment(self, start_time: float, stop_time: Any = None, tolerance: Any = None):
        self.time_s = float(start_time)

    def exit_initialization_mode(self) -> None:
        # pythonfmu turns this exception into fmi2Fatal carrying the message
        status, message = self._initialize()
        self._log_status(status, message)

    def do_step(self, current_time: float, step_size: float) -> bool:
        rtol = CONFIG["communication_point_rtol"]
        message = ""
        if not self.initialized:
            message = "fmi2DoStep must not be called before fmi2ExitInitializationMode"
        elif not abs(current_time - self.time_s) <= rtol * max(1.0, abs(self.time_s)):
            message = (
                f"fmi2DoStep: currentCommunicationPoint {_g(current_time)} s differs from the "
                f"FMU's time {_g(self.time_s)} s"
            )
        if message:
            self.log(message, Fmi2Status.error, "logStatusError")
            return False
        try:
            status, message = self._do_step(step_size)
        except PlantError as exc:
            self.log(str(exc), Fmi2Status.error, "logStatusError")
            return False
        self._log_status(status, message)
        return True

    def _log_status(self, status: int, message: str) -> None:
        if status == WARNING:
            self.log(message, Fmi2Status.warning, "logStatusWarning")

    def _get_fmu_state(self) -> dict[str, Any]:
        return json.loads(json.dumps(self._state()))  # a deep copy the caller may keep

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        state = json.loads(json.dumps(state))
        self.time_s = state["time_s"]
        self.real = state["real"]
        self.flow_in_force_m3h = state["flow_in_force_m3h"]
        self.initialized = state["initialized"]
        self.warned_flow_range = state["warned_flow_range"]
        self.parameters_changed = state["parameters_changed"]
        self.dyn = state["dyn"]

    def _state(self) -> dict[str, Any]:
        return {
            "time_s": self.time_s,
            "real": self.real,
            "flow_in_force_m3h": self.flow_in_force_m3h,
            "initialized": self.initialized,
            "warned_flow_range": self.warned_flow_range,
            "parameters_changed": self.parameters_changed,
            "dyn": self.dyn,
        }

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
        else:
            self._arx_check_parameters()

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
        if CONFIG["family"] == "fopdt":
            return self._at("gain_mm_per_mm", q) * u
        return self._arx_equilibrium(u, q)

    def _initialize(self) -> tuple[int, str]:
        opening_mm, flow_m3h = self.real[self.vr_opening], self.real[self.vr_flow]
        self._check_inputs(opening_mm, flow_m3h)
        self._check_parameters()
        u = opening_mm - self.real[self.vr_opening_ref]
        x0 = self._equilibrium(u, flow_m3h)
        if CONFIG["family"] == "fopdt":
            self._fopdt_initialize(u, x0)
        else:
            self._arx_initialize(u, x0)
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
        # ---- pipeline: u_eff = input_blocks(u); x = dynamics(u_eff); y = output_blocks(level)
        u = opening_mm - self.real[self.vr_opening_ref]
        if CONFIG["family"] == "fopdt":
            self._fopdt_check_step(u)
            self._fopdt_step(h, u, flow_m3h)
        else:
            n = self._arx_samples(h)
            self._arx_step(n, u, flow_m3h)
        status = self._check_flow_range(flow_m3h)
        self.flow_in_force_m3h = flow_m3h
        self.time_s += h
        return status

    def _output(self) -> float:
        if self.initialized:
            return self._at("level_ref_mm", self.flow_in_force_m3h) + self.dyn["x"]
        opening_mm, flow_m3h = self.real[self.vr_opening], self.real[self.vr_flow]
        self._check_inputs(opening_mm, flow_m3h)
        self._check_parameters()
        x0 = self._equilibrium(opening_mm - self.real[self.vr_opening_ref], flow_m3h)
        return self._at("level_ref_mm", flow_m3h) + x0

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
        self.dyn = {
            "x": x0,
            "change_t": [self.time_s],
            "change_u": [u],
            "max_dead_time_s": max(self._column("dead_time_s")),
        }

    def _fopdt_check_step(self, u: float) -> None:
        capacity = CONFIG["history_capacity"]
        if u != self.dyn["change_u"][-1] and len(self.dyn["change_u"]) >= capacity:
            raise PlantError(
                "input changes faster than the dead-time history can hold "
                f"({capacity} change points within the longest dead time)"
            )

    def _fopdt_step(self, h: float, u: float, q: float) -> None:
        d = self.dyn
        times, inputs = d["change_t"], d["change_u"]
        k = self._at("gain_mm_per_mm", q)
        tau = self._at("time_constant_s", q)
        delay = self._at("dead_time_s", q)
        t0 = self.time_s
        t1 = t0 + h
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
            target = k * inputs[j]
            d["x"] = target + (d["x"] - target) * math.exp(-(t_next - t) / tau)
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
        a, b = self._arx_coefficients(q)
        sum_a = 0.0
        for value in a:
            sum_a += value
        sum_b = 0.0
        for value in b:
            sum_b += value
        if sum_a == 1.0:
            raise PlantError(
                f"arx: no equilibrium at flow_m3h = {_g(self.real[self.vr_flow])} "
                "(sum of a coefficients is 1)"
            )
        return sum_b / (1.0 - sum_a) * u

    def _arx_initialize(self, u: float, x0: float) -> None:
        na, nb, nk = CONFIG["arx_orders"]
        self.dyn = {"x": x0, "x_hist": [x0] * na, "u_hist": [u] * (nk + nb - 1)}

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

    def _arx_step(self, n: int, u: float, q: float) -> None:
        _, _, nk = CONFIG["arx_orders"]
        a, b = self._arx_coefficients(q)
        d = self.dyn
        for _ in range(n):
            d["u_hist"] = [u, *d["u_hist"][:-1]]
            x_new = 0.0
            for i, a_i in enumerate(a):
                x_new += a_i * d["x_hist"][i]
            for j, b_j in enumerate(b):
                x_new += b_j * d["u_hist"][nk - 1 + j]
            d["x_hist"] = [x_new, *d["x_hist"][:-1]]
            d["x"] = x_new
