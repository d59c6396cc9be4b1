"""Validate any FMU, not only gatetwin's: which of its variables plays each record column.

gatetwin's own plant FMUs have Real inputs ``opening_mm`` and ``flow_m3h`` and outputs
``level_<G>_mm``. Any other co-simulation FMU of a gate (FMI 2.0 or 3.0) is validated
against the same records once a small TOML file names, for each of those columns, the FMU's
variable and the unit that variable is in::

    [opening_mm]          # the record's gate opening drives ...
    variable = "u_gate"   # ... this Real input of the FMU,
    unit = "m"            # in metres (openings and levels: mm, cm, m)
    [flow_m3h]
    variable = "Q_in"
    unit = "m3s"          # flows: m3h, m3s, ls
    [level_3F_mm]         # the record's level at gauge 3F is compared with ...
    variable = "h_up"     # ... this Real output,
    unit = "m"

``opening_mm`` and ``flow_m3h`` are required, and at least one ``level_<G>_mm``. The units
are the record format's (:data:`gatetwin.records.units.FACTORS`): the harness converts each
input from the record's mm and m³/h to the FMU's unit, and each output back to mm, so the
metrics, plots and reports are the same as for gatetwin's FMUs.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gatetwin.errors import ValidationError
from gatetwin.records import gauge_of_column
from gatetwin.records.limits import open_regular
from gatetwin.records.units import FACTORS

#: The columns the harness drives the FMU with, in the order it sets them.
INPUT_ROLES = ("opening_mm", "flow_m3h")
#: Largest map file read, bytes (a map has a few lines).
MAX_MAP_BYTES = 64 * 1024


@dataclass(frozen=True)
class VariableMap:
    """The FMU variable and unit behind each record column.

    Attributes
    ----------
    variables : dict[str, str]
        Record column (``opening_mm``, ``flow_m3h``, ``level_<G>_mm``) to FMU variable.
    units : dict[str, str]
        Record column to the unit its FMU variable is in (``mm``, ``cm``, ``m``; ``m3h``,
        ``m3s``, ``ls``).
    source : str
        Where the map was read from (for messages and provenance).
    """

    variables: dict[str, str]
    units: dict[str, str]
    source: str = ""

    def scale(self, column: str) -> float:
        """FMU value per record value of ``column`` (the record is in mm and m³/h)."""
        return 1.0 / FACTORS[_dimension(column)][self.units[column]]

    def to_dict(self) -> dict[str, Any]:
        return {c: {"variable": v, "unit": self.units[c]} for c, v in self.variables.items()}


def _dimension(column: str) -> str:
    """``flow`` or ``length``: the row of :data:`~gatetwin.records.units.FACTORS`."""
    return "flow" if column == "flow_m3h" else "length"


def parse_variable_map(doc: Any, source: str = "") -> VariableMap:
    """A :class:`VariableMap` from the parsed TOML (a mapping of tables).

    Raises
    ------
    ValidationError
        Not a table of tables, an unknown column, a missing ``variable`` or ``unit``, a unit
        of the wrong kind, no ``opening_mm``, ``flow_m3h`` or level column, or one FMU
        variable named twice.
    """
    where = f"{source}: " if source else ""
    if not isinstance(doc, dict) or not doc:
        raise ValidationError(f"{where}a variable map is a TOML file of [column] tables")
    variables, units = {}, {}
    for column, entry in doc.items():
        if column not in INPUT_ROLES and gauge_of_column(column) is None:
            raise ValidationError(f"{where}[{column}] is not a record column the harness "
                                  "uses (opening_mm, flow_m3h, level_<G>_mm)")  # fmt: skip
        if not isinstance(entry, dict) or set(entry) != {"variable", "unit"}:
            raise ValidationError(f"{where}[{column}] needs exactly 'variable' and 'unit'")
        variable, unit = entry["variable"], entry["unit"]
        allowed = FACTORS[_dimension(column)]
        if not isinstance(variable, str) or not variable.strip():
            raise ValidationError(f"{where}[{column}] variable must be a variable's name")
        if unit not in allowed:
            raise ValidationError(f"{where}[{column}] unit {unit!r} is not one of "
                                  f"{', '.join(allowed)}")  # fmt: skip
        variables[column], units[column] = variable, unit
    missing = [c for c in INPUT_ROLES if c not in variables]
    if missing or not any(gauge_of_column(c) for c in variables):
        raise ValidationError(f"{where}the map needs [opening_mm], [flow_m3h] and at least "
                              "one [level_<G>_mm]")  # fmt: skip
    if len(set(variables.values())) != len(variables):
        raise ValidationError(f"{where}one FMU variable is named for two columns")
    return VariableMap(variables, units, source)


def read_variable_map(path: str | Path) -> VariableMap:
    """:func:`parse_variable_map` of a TOML file (a regular file of at most 64 KiB).

    Raises
    ------
    ValidationError
        One line naming the file: missing, not a regular file, too large, not TOML, or a
        map :func:`parse_variable_map` refuses.
    """
    if sys.version_info < (3, 11):  # pragma: no cover - Python 3.10
        raise ValidationError(f"{path}: TOML variable maps need Python >= 3.11 (tomllib)")
    import tomllib

    with open_regular(path, MAX_MAP_BYTES, "a variable map (TOML)", ValidationError) as f:
        data = f.read()
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValidationError(f"{path}: not a TOML file ({' '.join(str(exc).split())})") from None
    return parse_variable_map(doc, str(path))


__all__ = ["INPUT_ROLES", "VariableMap", "parse_variable_map", "read_variable_map"]
