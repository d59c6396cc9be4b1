"""Units carried by column names, and the one table that converts them to the internal units.

A record's numeric columns name their unit in a suffix: ``opening_<u>`` and
``level_<G>_<u>`` (and a rating table's ``level_<G>_sd_<u>``) in ``mm``, ``cm`` or ``m``;
``flow_<u>`` in ``m3h``, ``m3s`` or ``ls`` (litres per second); ``time_s`` stays in
seconds. Every reader (CSV, Parquet, DataFrame, rating table, chunked history) hands its
columns to :func:`to_internal`, which checks the header (one column per quantity, a known
unit on every level column), renames the columns to their internal names (``opening_mm``,
``flow_m3h``, ``level_<G>_mm``, ``level_<G>_sd_mm``) and scales the values by
:data:`FACTORS`, so everything after the reader works in mm and m³/h. This module does
not check values.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.checks import column

__all__ = [
    "DIMENSION",
    "FACTORS",
    "INTERNAL",
    "INTERNAL_UNITS",
    "HeaderUnits",
    "UnitColumn",
    "header_units",
    "parse_column",
    "to_internal",
]

#: Factor from each accepted unit to the internal unit of its dimension (mm, m³/h).
FACTORS: dict[str, dict[str, float]] = {
    "length": {"mm": 1.0, "cm": 10.0, "m": 1000.0},
    "flow": {"m3h": 1.0, "m3s": 3600.0, "ls": 3.6},
}
#: The dimension of each quantity a column may hold.
DIMENSION = {"opening": "length", "flow": "flow", "level": "length", "level_sd": "length"}
#: The internal unit of each dimension (the first entry of its factor table).
INTERNAL = {"length": "mm", "flow": "m3h"}
#: The units of a record built from arrays in the internal units.
INTERNAL_UNITS = {"opening": "mm", "flow": "m3h", "level": "mm"}


@dataclass(frozen=True)
class UnitColumn:
    """One numeric column of a header, parsed.

    Attributes
    ----------
    name : str
        The column's name in the file.
    quantity : str
        ``"opening"``, ``"flow"``, ``"level"`` or ``"level_sd"``.
    gauge : str
        The gauge of a level column ("" otherwise).
    unit : str
        The unit suffix (``"m"``, ``"m3s"``, ...); "" when not one of :data:`FACTORS`.
    """

    name: str
    quantity: str
    gauge: str
    unit: str

    @property
    def known(self) -> bool:
        return self.unit in FACTORS[DIMENSION[self.quantity]]

    @property
    def factor(self) -> float:
        """Factor to the internal unit (mm or m³/h)."""
        return FACTORS[DIMENSION[self.quantity]][self.unit]

    @property
    def internal(self) -> str:
        """The column's internal name (``level_3F_mm`` for ``level_3F_m``)."""
        unit = INTERNAL[DIMENSION[self.quantity]]
        if self.quantity == "level":
            return f"level_{self.gauge}_{unit}"
        if self.quantity == "level_sd":
            return f"level_{self.gauge}_sd_{unit}"
        return f"{self.quantity}_{unit}"


def parse_column(name: str) -> UnitColumn | None:
    """Parse a numeric column name; None if it is no opening, flow or level column.

    ``opening_<u>`` and ``flow_<u>`` count only with a known unit (``flow_out`` is some
    other column); ``level_<G>_<u>`` counts whatever its suffix, so that a level in an
    unknown unit is refused rather than ignored.
    """
    head, _, unit = name.rpartition("_")
    if head in ("opening", "flow"):
        parsed = UnitColumn(name, head, "", unit)
        return parsed if parsed.known else None
    if not head.startswith("level_") or not unit:
        return None
    gauge = head[len("level_") :]
    if gauge.endswith("_sd") and gauge != "_sd":
        return UnitColumn(name, "level_sd", gauge[: -len("_sd")], unit)
    return UnitColumn(name, "level", gauge, unit) if gauge else None


@dataclass(frozen=True)
class HeaderUnits:
    """The unit columns of a header, by internal name.

    Attributes
    ----------
    columns : dict[str, UnitColumn]
        Internal name (``opening_mm``, ``level_3F_mm``, ...) to the file's column.
    """

    columns: dict[str, UnitColumn] = field(default_factory=dict)

    def names(self) -> dict[str, str]:
        """The file's name of each column, by internal name (for messages)."""
        return {internal: c.name for internal, c in self.columns.items()}

    def units(self) -> dict[str, object]:
        """The units the file came in: ``{"opening": "m", "flow": "m3s", "level": "m"}``.

        ``"level"`` is ``"mixed"`` when the gauges differ; ``"levels"`` gives each gauge's.
        """
        out: dict[str, object] = {}
        levels = {c.gauge: c.unit for c in self.columns.values() if c.quantity == "level"}
        for c in self.columns.values():
            if c.quantity in ("opening", "flow"):
                out[c.quantity] = c.unit
        if levels:
            distinct = set(levels.values())
            out["level"] = distinct.pop() if len(distinct) == 1 else "mixed"
            out["levels"] = levels
        return out

    def filled(self, gauges: Sequence[str]) -> dict[str, object]:
        """:meth:`units`, with the internal unit for any quantity the header lacks
        (all of them for arrays built in memory)."""
        out: dict[str, object] = dict(INTERNAL_UNITS)
        out["levels"] = {g: INTERNAL["length"] for g in gauges}
        out.update(self.units())
        return out


def header_units(path: str, header: Sequence[str]) -> HeaderUnits:
    """Parse the unit columns of ``header``.

    Raises
    ------
    RecordError
        One line naming the columns, for a level column in an unknown unit or two
        columns of the same quantity (``opening_mm`` and ``opening_m``).
    """
    found: dict[str, UnitColumn] = {}
    for name in header:
        parsed = parse_column(name)
        if parsed is None:
            continue
        if not parsed.known:
            units = ", ".join(FACTORS[DIMENSION[parsed.quantity]])
            raise RecordError(
                f"{path}: {column(name)}: unknown unit {parsed.unit!r}; expected a level "
                f"column level_<G>_<unit> with unit {units}"
            )
        twin = found.get(parsed.internal)
        if twin is not None:
            raise RecordError(
                f"{path}: {column(twin.name)} and {column(name)}: the same quantity twice; "
                "expected one column per quantity, in one unit"
            )
        found[parsed.internal] = parsed
    return HeaderUnits(found)


def to_internal(path: str, header: Sequence[str], columns: dict) -> tuple[tuple, dict, HeaderUnits]:
    """Rename and scale ``columns`` to the internal names and units.

    Parameters
    ----------
    path : str
        Label for error messages.
    header : sequence of str
        All column names of the file, in order.
    columns : dict[str, ndarray or Words]
        The kept columns by file name; numeric ones are float arrays.

    Returns
    -------
    header : tuple[str, ...]
        ``header`` with unit columns renamed to their internal names.
    columns : dict
        The columns by internal name; unit columns scaled to mm or m³/h (new arrays; a
        factor of 1 keeps the array itself).
    units : HeaderUnits
        What was found, for messages and reports.
    """
    units = header_units(path, header)
    rename = {c.name: internal for internal, c in units.columns.items()}
    scaled: dict = {}
    for name, values in columns.items():
        parsed = units.columns.get(rename.get(name, ""))
        if parsed is not None and parsed.factor != 1.0:
            values = np.multiply(values, parsed.factor)
        scaled[rename.get(name, name)] = values
    return tuple(rename.get(name, name) for name in header), scaled, units
