"""What an FMU component's interface is made of, whatever the component: its Real variables
(:class:`VariableSpec`), the units and log categories every modelDescription.xml declares,
and what the renderings need of a component (:class:`ComponentInterface`).

A plant's description (:class:`gatetwin.fmu.description.FmuDescription`), a controller's and
an observer's are built of these. Nothing here decides a variable or renders a file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

__all__ = [
    "COMMUNICATION_POINT_RTOL",
    "LOG_CATEGORIES",
    "UNITS",
    "ComponentInterface",
    "VariableSpec",
]

#: doStep refuses a currentCommunicationPoint further than this (relative) from the FMU's time.
COMMUNICATION_POINT_RTOL = 1e-9
#: Log categories both backends declare.
LOG_CATEGORIES = {
    "logStatusWarning": "Warnings (an input or the level outside the model's validity, or the "
    "discharge outside the schedule's knots)",
    "logStatusError": "Errors: refused inputs, parameters and communication steps",
    "logAll": "Everything, including informational messages",
}
#: name -> (description, SI base-unit exponents, factor to SI)
UNITS: dict[str, tuple[str, dict[str, int], float]] = {
    "mm": ("millimetre", {"m": 1}, 0.001),
    "m3/h": ("cubic metre per hour", {"m": 3, "s": -1}, 1.0 / 3600.0),
    "s": ("second", {"s": 1}, 1.0),
    "mm/mm": ("millimetre per millimetre (dimensionless)", {}, 1.0),
    "mm/s": ("millimetre per second", {"m": 1, "s": -1}, 0.001),
    "1/mm": ("per millimetre", {"m": -1}, 1000.0),
    "h/m3": ("per cubic metre per hour", {"m": -3, "s": 1}, 3600.0),
    "mm/(m3/h)": ("millimetre per cubic metre per hour", {"m": -2, "s": 1}, 3.6),
    "1": ("dimensionless", {}, 1.0),
    "m": ("metre", {"m": 1}, 1.0),
    "m2": ("square metre", {"m": 2}, 1.0),
}


@dataclass(frozen=True)
class VariableSpec:
    """One FMI Real variable. ``kind`` is ``input``, ``output``, ``tunable`` or ``fixed``."""

    name: str
    vr: int
    causality: str
    variability: str
    initial: str | None
    unit: str
    description: str
    start: float | None
    initial_dependency: bool = True

    @property
    def kind(self) -> str:
        if self.causality == "parameter":
            return self.variability
        return self.causality


class ComponentInterface(Protocol):
    """What the renderings of an FMU's interface (``modelDescription.xml``, the head and the
    variable table of ``model_config.h``) need of a component: a plant
    (:class:`FmuDescription`) or a controller (:mod:`gatetwin.fmu.controller`)."""

    @property
    def model_identifier(self) -> str: ...

    @property
    def guid(self) -> str: ...

    @property
    def summary(self) -> str: ...

    @property
    def step_size_s(self) -> float: ...

    @property
    def variables(self) -> tuple[VariableSpec, ...]: ...

    @property
    def output(self) -> VariableSpec: ...
