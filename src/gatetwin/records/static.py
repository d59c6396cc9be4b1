"""Quasi-steady rating tables: one row per steady operating point.

:func:`read_static_table` reads and checks the table of ``docs/record_format.md``;
:func:`detect_table_kind` tells a rating table from a time-series record by its header.
This module does not fit the rating; :mod:`gatetwin.identification.rating` does.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.records import checks
from gatetwin.records.checks import FLOW_MAX_M3H, OPENING_MAX_MM
from gatetwin.records.columns import (
    frozen,
    gauge_names,
    is_static_column,
    static_table,
    value_range,
)
from gatetwin.records.limits import ReadLimits
from gatetwin.records.table import read_header, read_table
from gatetwin.records.units import INTERNAL_UNITS, parse_column

__all__ = ["StaticTable", "detect_table_kind", "read_static_table"]


@dataclass(frozen=True)
class StaticTable:
    """A quasi-steady rating table: one row per steady operating point.

    Attributes
    ----------
    flow_m3h : ndarray
        Discharge of each point, m³/h.
    opening_mm : ndarray
        Gate opening of each point, mm.
    levels_mm : dict[str, ndarray]
        Steady mean level per gauge, mm (NaN where not measured).
    level_sd_mm : dict[str, ndarray]
        Standard deviation of the level per gauge, mm, for the gauges whose
        ``level_<G>_sd_mm`` column is present.
    path : str
        File the table was read from.
    sha256 : str
        Hash of the file's bytes.
    units : dict
        The units the file came in (as :attr:`Record.units`); arrays are in mm and m³/h.
    """

    flow_m3h: np.ndarray
    opening_mm: np.ndarray
    levels_mm: dict[str, np.ndarray]
    level_sd_mm: dict[str, np.ndarray]
    path: str = ""
    sha256: str = ""
    units: dict[str, Any] = field(default_factory=lambda: dict(INTERNAL_UNITS))

    @property
    def n_points(self) -> int:
        return int(self.flow_m3h.size)

    @property
    def gauges(self) -> tuple[str, ...]:
        return tuple(self.levels_mm)

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary (what ``gatetwin check`` reports)."""
        return _static_summary(self)


def read_static_table(path: str | Path, *, limits: ReadLimits | None = None) -> StaticTable:
    """Read and check a quasi-steady rating table.

    Parameters
    ----------
    path : str or Path
        CSV (or Parquet) with ``flow_m3h``, ``opening_mm``, one or more ``level_<G>_mm``
        and optional ``level_<G>_sd_mm`` columns, one row per steady operating point, in
        these or any other units of :mod:`gatetwin.records.units` (``flow_m3s``,
        ``opening_m``, ``level_<G>_cm``, ...).
    limits : ReadLimits, optional
        File size and line length limits; default from the environment.

    Raises
    ------
    RecordError
        With a one-line message naming the file, row or column, as
        :func:`~gatetwin.records.read_record`.
    """
    table = static_table(read_table(path, keep=is_static_column, text_columns=(), limits=limits))
    origin = table.origin()
    flow = table.floats("flow_m3h")
    opening = table.floats("opening_mm")
    for name, values, unit, top in (("flow_m3h", flow, "m³/h", FLOW_MAX_M3H),
                                    ("opening_mm", opening, "mm", OPENING_MAX_MM)):  # fmt: skip
        checks.check_no_missing(origin, name, values)
        checks.check_non_negative(origin, name, values, unit)
        checks.check_bounds(origin, name, values, top, unit)
    levels = {g: table.floats(f"level_{g}_mm") for g in gauge_names(table.header)}
    for gauge, values in levels.items():
        in_mm = origin.columns.get(f"level_{gauge}_mm", "").endswith("_mm")
        checks.check_level(origin, f"level_{gauge}_mm", values, logged_in_mm=in_mm)
    sds = {
        g: table.floats(f"level_{g}_sd_mm") for g in levels if f"level_{g}_sd_mm" in table.columns
    }
    for gauge, values in sds.items():
        checks.check_non_negative(origin, f"level_{gauge}_sd_mm", values, "mm")
        checks.check_bounds(origin, f"level_{gauge}_sd_mm", values, OPENING_MAX_MM, "mm")
    return StaticTable(
        flow_m3h=frozen(flow),
        opening_mm=frozen(opening),
        levels_mm={g: frozen(v) for g, v in levels.items()},
        level_sd_mm={g: frozen(v) for g, v in sds.items()},
        path=table.path,
        sha256=table.sha256,
        units=table.units.filled(list(levels)),
    )


def detect_table_kind(path: str | Path, *, limits: ReadLimits | None = None) -> str:
    """``"static"`` if the header is that of a rating table, else ``"record"``.

    A rating table has no ``time_s`` and no ``state`` column but ``flow_m3h``,
    ``opening_mm`` and a level column (a time series whose time column is misnamed keeps
    its ``state``, and is a record :func:`~gatetwin.records.read_record` refuses naming
    the missing ``time_s``). Anything unreadable is called a ``"record"`` so that
    :func:`~gatetwin.records.read_record` reports what is wrong with it.
    """
    header = read_header(path, limits)
    found = {p.quantity for p in map(parse_column, header) if p is not None and p.known}
    if "time_s" in header or "state" in header or not {"flow", "opening", "level"} <= found:
        return "record"
    return "static"


def _static_summary(table: StaticTable) -> dict[str, Any]:
    """Summarise a :class:`~gatetwin.records.StaticTable`."""
    return {
        "kind": "static",
        "path": table.path,
        "sha256": table.sha256,
        "n_points": table.n_points,
        "units": table.units,
        "flow_m3h": value_range(table.flow_m3h),
        "opening_mm": value_range(table.opening_mm),
        "gauges": [
            {
                "name": g,
                "level_mm": value_range(table.levels_mm[g]),
                "has_sd": g in table.level_sd_mm,
            }
            for g in table.gauges
        ],
    }
