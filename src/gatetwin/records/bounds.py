"""The bounds a record's values must respect: physical defaults, or a sidecar's own.

The defaults (constants of :mod:`gatetwin.records.checks`) span lab flumes to large
canals. A record whose values lie outside them for a good reason (levels logged as
elevations above a datum, a slow SCADA log) states its own in the sidecar::

    "bounds": {"level_m": [410.0, 435.0], "sample_period_s": [60, 900]}

Keys name a quantity and a unit as column names do (``level_<u>``, ``opening_<u>``,
``flow_<u>`` in the units of :mod:`gatetwin.records.units`) plus ``sample_period_s`` and
``gap_max_s`` (the longest logging gap, s, a number). Ranges are ``[low, high]`` of finite
numbers, low < high. This module parses and holds bounds; the checks apply them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gatetwin.errors import RecordError
from gatetwin.records.checks import (
    FLOW_MAX_M3H,
    GAP_MAX_S,
    LEVEL_RANGE_MM,
    OPENING_MAX_MM,
    SAMPLE_PERIOD_RANGE_S,
)
from gatetwin.records.units import parse_column

__all__ = ["Bounds", "bounds_from_sidecar"]

#: Quantities whose range a sidecar may set, with their internal field name.
_RANGE_FIELDS = {"level": "level_mm", "opening": "opening_mm", "flow": "flow_m3h"}


@dataclass(frozen=True)
class Bounds:
    """Accepted ranges of a record's values, in the internal units.

    Attributes
    ----------
    level_mm : tuple[float, float]
        Upstream levels, mm.
    opening_mm : tuple[float, float]
        Gate openings, mm.
    flow_m3h : tuple[float, float]
        Discharges, m³/h.
    sample_period_s : tuple[float, float]
        Nominal sample period, s.
    gap_max_s : float
        Longest time step, s.
    """

    level_mm: tuple[float, float] = LEVEL_RANGE_MM
    opening_mm: tuple[float, float] = (0.0, OPENING_MAX_MM)
    flow_m3h: tuple[float, float] = (0.0, FLOW_MAX_M3H)
    sample_period_s: tuple[float, float] = SAMPLE_PERIOD_RANGE_S
    gap_max_s: float = GAP_MAX_S

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready, in the internal units."""
        return {
            "level_mm": list(self.level_mm),
            "opening_mm": list(self.opening_mm),
            "flow_m3h": list(self.flow_m3h),
            "sample_period_s": list(self.sample_period_s),
            "gap_max_s": self.gap_max_s,
        }


def bounds_from_sidecar(name: str, value: Any) -> Bounds:
    """The sidecar field ``bounds`` checked; the defaults where it says nothing.

    Raises
    ------
    RecordError
        One line naming the sidecar and the key, for an unknown key, two keys of one
        quantity, or a range that is not two finite increasing numbers.
    """
    if value is None:
        return Bounds()
    if not isinstance(value, dict):
        raise _error(name, "", f"{value!r}; expected an object such as {{'level_m': [0, 5]}}")
    fields: dict[str, Any] = {}
    for key, given in value.items():
        field_name, parsed = _field(name, str(key), given)
        if field_name in fields:
            raise _error(name, key, "a second bound of the same quantity; expected one")
        fields[field_name] = parsed
    return Bounds(**fields)


def _field(name: str, key: str, given: Any) -> tuple[str, Any]:
    if key == "gap_max_s":
        if not (_is_number(given) and math.isfinite(given) and given > 0):
            raise _error(name, key, f"{given!r}; expected a positive number of seconds")
        return key, float(given)
    if key == "sample_period_s":
        return key, _range(name, key, given, 1.0)
    quantity, _, unit = key.partition("_")
    parsed = parse_column(f"level_G_{unit}" if quantity == "level" else key)
    if parsed is None or not parsed.known or parsed.quantity not in _RANGE_FIELDS:
        raise _error(
            name, key, "unknown bound; expected level_<unit>, opening_<unit>, flow_<unit>, "
            "sample_period_s or gap_max_s (units mm, cm, m; m3h, m3s, ls)",
        )  # fmt: skip
    return _RANGE_FIELDS[parsed.quantity], _range(name, key, given, parsed.factor)


def _range(name: str, key: str, given: Any, factor: float) -> tuple[float, float]:
    ok = isinstance(given, list) and len(given) == 2 and all(_is_number(v) for v in given)
    if not ok or not all(math.isfinite(v) for v in given) or not given[0] < given[1]:
        raise _error(name, key, f"{given!r}; expected [low, high], finite numbers, low < high")
    return float(given[0]) * factor, float(given[1]) * factor


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _error(name: str, key: str, what: str) -> RecordError:
    where = f"sidecar field 'bounds.{key}'" if key else "sidecar field 'bounds'"
    return RecordError(f"{name}: {where}: {what}")
