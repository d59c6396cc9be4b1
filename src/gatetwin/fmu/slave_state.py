"""Checks of an FMU state restored into the pythonfmu slave, before any of it is used.

Embedded into the slave at export like slave_guard.py (standard library only). A state is
plain JSON data (``GatetwinPlant._snapshot``); ``config`` is the slave's CONFIG (family,
ARX orders, history capacity, validity envelope). Not the handles (slave_guard.py) and not
the parameter checks (the slave runs those on the checked state).
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["FX_KEYS", "STATE_KEYS", "StateError", "check_state"]


class StateError(ValueError):
    """A restored state that does not fit this model (the message names the first fault)."""


#: The keys of a state and of its effect-block part (as _effects_initialize makes them).
STATE_KEYS = ("time_s", "real", "flow_in_force_m3h", "initialized", "warned_flow_range",
              "warned_validity", "parameters_changed", "dyn", "fx")  # fmt: skip
FX_KEYS = ("seiche_x1", "seiche_x2", "inflow_mm", "drift_mm", "actuator_mm", "gate_mm",
           "held_gate_mm", "grid_origin_s", "sensed_mm")  # fmt: skip


def _number(value: Any, where: str) -> float:
    if type(value) not in (int, float) or not math.isfinite(value):
        raise StateError(f"FMU state: {where} = {value!r} is not a finite number")
    return float(value)


def _numbers(value: Any, where: str, size: tuple[int, int]) -> list[float]:
    if type(value) is not list or not size[0] <= len(value) <= size[1]:
        raise StateError(f"FMU state: {where} must be a list of {size[0]}..{size[1]} numbers")
    return [_number(v, f"{where}[{i}]") for i, v in enumerate(value)]


def _flag(value: Any, where: str) -> bool:
    if type(value) is not bool:
        raise StateError(f"FMU state: {where} = {value!r} is not true or false")
    return value


def _keys(value: Any, where: str, keys: Any) -> None:
    if type(value) is not dict or set(value) != set(keys):
        found = sorted(value) if type(value) is dict else type(value).__name__
        raise StateError(f"FMU state: {where} must have the keys {sorted(keys)}, got {found}")


def _dyn_sizes(config: dict[str, Any]) -> dict[str, tuple[int, int] | None]:
    """The family's dynamic state: None for a number, (fewest, most) for a list."""
    if config["family"] == "fopdt":
        history = (1, config["history_capacity"])
        return {"x": None, "change_t": history, "change_u": history, "max_dead_time_s": None,
                "tail_m": None}  # fmt: skip
    if config["family"] == "physical":
        return {"x": None, "depth_m": None, "tail_m": None, "gate_mm": None}
    na, nb, nk = config["arx_orders"]
    return {"x": None, "x_hist": (na, na), "u_hist": (nk + nb - 1, nk + nb - 1)}


def _checked_dyn(dyn: Any, config: dict[str, Any]) -> dict[str, Any]:
    sizes = _dyn_sizes(config)
    _keys(dyn, "dyn", sizes)
    out = {key: _number(dyn[key], f"dyn.{key}") if size is None
           else _numbers(dyn[key], f"dyn.{key}", size) for key, size in sizes.items()}  # fmt: skip
    if config["family"] == "fopdt":
        times = out["change_t"]
        if len(times) != len(out["change_u"]):
            raise StateError("FMU state: dyn.change_t and dyn.change_u differ in length")
        ordered = all(a <= b for a, b in zip(times, times[1:], strict=False))
        if not ordered or out["max_dead_time_s"] < 0.0:
            raise StateError("FMU state: the input-change history is not in time order")
    return out


def check_state(state: Any, n_real: int, config: dict[str, Any]) -> dict[str, Any]:
    """A complete, validated copy of a restored state; StateError naming the first fault."""
    _keys(state, "state", STATE_KEYS)
    warned = state["warned_validity"]
    if (
        type(warned) is not list
        or len(set(warned)) != len(warned)
        or any(q not in config["validity"] for q in warned)
    ):
        raise StateError(f"FMU state: warned_validity = {warned!r} is not a list of quantities")
    out = {
        "time_s": _number(state["time_s"], "time_s"),
        "real": _numbers(state["real"], "real", (n_real, n_real)),
        "flow_in_force_m3h": _number(state["flow_in_force_m3h"], "flow_in_force_m3h"),
        "initialized": _flag(state["initialized"], "initialized"),
        "warned_flow_range": _flag(state["warned_flow_range"], "warned_flow_range"),
        "warned_validity": list(warned),
        "parameters_changed": _flag(state["parameters_changed"], "parameters_changed"),
    }
    if out["initialized"]:
        out["dyn"] = _checked_dyn(state["dyn"], config)
        _keys(state["fx"], "fx", FX_KEYS)
        out["fx"] = {key: _number(state["fx"][key], f"fx.{key}") for key in FX_KEYS}
    else:
        _keys(state["dyn"], "dyn", ("x",))
        _keys(state["fx"], "fx", ())
        out["dyn"], out["fx"] = {"x": _number(state["dyn"]["x"], "dyn.x")}, {}
    return out
