"""What a gatetwin C FMU refuses, and the validity envelope it warns about.

The limits are generated into ``model_config.h`` (:func:`gatetwin.fmu.description.
model_config_header`); :func:`check_parameter_values` and :func:`validity_ranges` refuse at
export what the FMU would refuse or could not carry. See ``fmu_templates/README.md`` for the
table of limits. This module builds nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from gatetwin.errors import ExportError

__all__ = [
    "MAX_COMMUNICATION_STEP_S",
    "MAX_TIME_S",
    "PARAMETER_MAX_ABS",
    "VALIDITY_QUANTITIES",
    "check_parameter_values",
    "validity_ranges",
]

#: Longest communication step the C FMU takes, s (11.6 days; a gate log is sampled in seconds).
MAX_COMMUNICATION_STEP_S = 1e6
#: Largest |time| the C FMU keeps, s (317 years): start times and communication points beyond
#: it are refused, so that the actuator grid's index stays an exact integer in a double.
MAX_TIME_S = 1e10
#: Largest |value| of any parameter, in its unit: far beyond any gate, canal or fitted value,
#: and small enough that level_ref + K * (opening - opening_ref) cannot overflow.
PARAMETER_MAX_ABS = 1e9
#: The quantities of a validity envelope (provenance ``validity``): (variable, unit in
#: messages, macro stem in model_config.h); the level is the FMU's output.
VALIDITY_QUANTITIES = (("opening_mm", "mm", "OPENING"), ("flow_m3h", "m3/h", "FLOW"),
                       ("level_mm", "mm", "LEVEL"))  # fmt: skip


def check_parameter_values(specs: Iterable[Any]) -> None:
    """Every parameter (a :class:`~gatetwin.fmu.description.VariableSpec` of causality
    ``parameter``) finite and within :data:`PARAMETER_MAX_ABS`, else :class:`ExportError`
    naming it; the C FMU checks the same at run time."""
    for v in specs:
        if v.causality != "parameter" or v.start is None:
            continue
        if not abs(v.start) <= PARAMETER_MAX_ABS:
            raise ExportError(
                f"parameter {v.name} = {v.start:g} is beyond the FMU's limit "
                f"|value| <= {PARAMETER_MAX_ABS:g} (the level would not stay finite)"
            )


def validity_ranges(provenance: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """The validity envelope ``provenance["validity"]`` states, checked: ``{quantity: (low,
    high)}`` for the quantities of :data:`VALIDITY_QUANTITIES` it gives (others are ignored).

    Raises
    ------
    ExportError
        ``validity`` is not an object, or a range is not two finite numbers with low <= high.
    """
    stated = provenance.get("validity")
    if stated is None:
        return {}
    if not isinstance(stated, dict):
        raise ExportError(f"provenance.validity must be an object, got {type(stated).__name__}")
    out: dict[str, tuple[float, float]] = {}
    for name, _, _ in VALIDITY_QUANTITIES:
        if name not in stated:
            continue
        value = stated[name]
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ExportError(
                f"provenance.validity.{name} must be [low, high], got {value!r}"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ExportError(
                f"provenance.validity.{name} [{lo:g}, {hi:g}] must be finite with low <= high"
            )
        out[name] = (lo, hi)
    return out
