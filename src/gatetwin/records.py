"""Test records: the one reader every command uses.

A record is a CSV file in the format of ``docs/record_format.md`` (plus an optional JSON sidecar
of the same stem). :func:`read_record` turns it into a frozen :class:`Record` with its hold
segments and step onsets found, or refuses it with a :class:`~gatetwin.errors.RecordError`
whose one-line message names the file and the row or column at fault.
:func:`record_from_arrays` does the same for in-memory arrays (synthetic data), and
:func:`read_static_table` reads a quasi-steady rating table.

This module does not identify anything; it only reads, checks and segments.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin import _checks, _segments
from gatetwin._checks import Origin
from gatetwin._segments import (
    GAP_FACTOR,
    PRBS_MIN_STEPS,
    PRBS_MIN_USABLE_SAMPLES,
    RESOLUTION_MM,
    STEP_WINDOW_SAMPLES,
)
from gatetwin._sidecar import TEST_TYPES, Sidecar, read_sidecar, sidecar_from_dict
from gatetwin._summary import record_summary, static_summary
from gatetwin._table import TableColumns, read_header, read_table
from gatetwin.errors import RecordError

_REQUIRED = ("time_s", "opening_mm", "state", "flow_m3h")


@dataclass(frozen=True)
class HoldSegment:
    """A run of consecutive ``hold`` samples at one constant opening.

    Attributes
    ----------
    start, stop : int
        Sample indices, ``stop`` exclusive (Python slice convention).
    opening_mm : float
        The (median) opening over the segment, mm.
    """

    start: int
    stop: int
    opening_mm: float

    @property
    def n_samples(self) -> int:
        return self.stop - self.start

    @property
    def slice(self) -> slice:
        """The segment as a slice into the record's arrays."""
        return slice(self.start, self.stop)


@dataclass(frozen=True)
class StepOnset:
    """A change of gate opening between two hold segments.

    Attributes
    ----------
    index : int
        Index of the first sample after the last sample of the previous hold segment
        (the first ``open`` sample when the logger saw the motion).
    time_s : float
        Onset time, s: the time of that sample (start of gate motion as logged).
    before, after : HoldSegment
        The hold segments on either side of the step.
    """

    index: int
    time_s: float
    before: HoldSegment
    after: HoldSegment

    @property
    def delta_e_mm(self) -> float:
        return self.after.opening_mm - self.before.opening_mm


@dataclass(frozen=True)
class Record:
    """A read, checked and segmented time-series record.

    Arrays are read-only numpy float arrays of equal length ``n``; missing values are NaN.

    Attributes
    ----------
    path : str
        File the record was read from ("" for in-memory records).
    time_s : ndarray
        Sample times, s, strictly increasing.
    opening_mm : ndarray
        Gate opening, mm; NaN where the logger left it empty during gate motion. Empty
        openings of ``hold`` samples are filled with their segment's median opening (see
        ``opening_filled``).
    hold : ndarray of bool
        True where ``state`` is ``hold`` (actuator still), False for ``open``.
    flow_m3h : ndarray
        Inflow discharge, m³/h.
    levels_mm : dict[str, ndarray]
        Upstream level per gauge name (``"3F"`` for column ``level_3F_mm``), mm.
    gauges_m : dict[str, float]
        Distance of each gauge upstream of the gate, m, where known (sidecar).
    test : str
        ``"step"``, ``"prbs"`` or ``"free"``.
    test_source : str
        Where ``test`` came from: ``"option"``, ``"sidecar"`` or ``"detected"``.
    sample_period_s : float
        Nominal sample period, s (sidecar, else median time step).
    holds : tuple[HoldSegment, ...]
        Hold segments in time order. They never bridge a logging gap.
    steps : tuple[StepOnset, ...]
        Opening changes between consecutive hold segments that the logger saw (no
        logging gap between the two segments).
    metadata : dict
        The sidecar's contents (empty without a sidecar).
    sha256 : str
        Hash of the CSV bytes, for provenance.
    opening_filled : ndarray of bool or None
        True for hold samples whose empty opening was filled from their segment.
    unobserved_steps : int
        Opening changes between hold segments that fall inside a logging gap (onset
        unknown, so not in ``steps``).
    """

    path: str
    time_s: np.ndarray
    opening_mm: np.ndarray
    hold: np.ndarray
    flow_m3h: np.ndarray
    levels_mm: dict[str, np.ndarray]
    gauges_m: dict[str, float]
    test: str
    test_source: str
    sample_period_s: float
    holds: tuple[HoldSegment, ...]
    steps: tuple[StepOnset, ...]
    metadata: dict[str, Any] = field(default_factory=dict)
    sha256: str = ""
    opening_filled: np.ndarray | None = None
    unobserved_steps: int = 0

    @property
    def n_samples(self) -> int:
        return int(self.time_s.size)

    @property
    def gauges(self) -> tuple[str, ...]:
        return tuple(self.levels_mm)

    def valid_samples(self, segment: HoldSegment, gauge: str) -> int:
        """Number of samples of ``segment`` with a finite level at ``gauge``."""
        return int(np.count_nonzero(np.isfinite(self.levels_mm[gauge][segment.slice])))

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary (what ``gatetwin check`` reports)."""
        return record_summary(self)


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
        Hash of the CSV bytes.
    """

    flow_m3h: np.ndarray
    opening_mm: np.ndarray
    levels_mm: dict[str, np.ndarray]
    level_sd_mm: dict[str, np.ndarray]
    path: str = ""
    sha256: str = ""

    @property
    def n_points(self) -> int:
        return int(self.flow_m3h.size)

    @property
    def gauges(self) -> tuple[str, ...]:
        return tuple(self.levels_mm)

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary (what ``gatetwin check`` reports)."""
        return static_summary(self)


@dataclass(frozen=True)
class _Columns:
    """Raw, unchecked columns of a time-series record (float arrays, bool ``hold``)."""

    time_s: np.ndarray
    opening_mm: np.ndarray
    hold: np.ndarray
    flow_m3h: np.ndarray
    levels_mm: dict[str, np.ndarray]


# --------------------------------------------------------------------------- public API


def read_record(path: str | Path, test: str | None = None) -> Record:
    """Read, check and segment a time-series record.

    Parameters
    ----------
    path : str or Path
        The record's CSV file; a sidecar ``NAME.json`` next to it is read if present.
    test : {"step", "prbs", "free"}, optional
        Test type from the command line; overrides the sidecar and detection.

    Returns
    -------
    Record
        With read-only arrays, hold segments and step onsets.

    Raises
    ------
    RecordError
        With a one-line message naming the file, the row or column, and what was
        expected, if the record breaks the data-format contract or is too short for the
        method of its test type.

    Notes
    -----
    * Hold segments are maximal runs of ``hold`` samples, split where a time step exceeds
      ``GAP_FACTOR`` (1.5) nominal sample periods and where the opening moves by at least
      ``RESOLUTION_MM`` (1 mm) from the segment's first opening. Empty openings of hold
      samples take their segment's median; a segment without any opening is refused.
    * A step is an opening change of at least 1 mm between consecutive hold segments with
      no logging gap between them; its onset is the first sample after the earlier
      segment.
    * Test type: ``test`` argument, else sidecar, else detected (no step: ``free``; 1–3
      steps between holds of ≥ 40 samples: ``step``; ≥ 4 steps: ``prbs``; else ``free``).
    * A ``step`` record needs ≥ 40 valid (finite-level) hold samples at every gauge
      before and after its first step; a ``prbs`` record ≥ 2 steps and ≥ 30 usable hold
      samples at every gauge (the first 2 of each hold segment are not usable).
    """
    table = read_table(path, keep=_is_record_column, text_columns=("state",))
    _require_record_columns(table)
    origin = Origin(table.path, first_line=2)
    columns = _record_columns(origin, table)
    sidecar = read_sidecar(path)
    return _build_record(origin, columns, sidecar, test, table.sha256, table.path)


def record_from_arrays(
    time_s: Any,
    opening_mm: Any,
    hold: Any,
    flow_m3h: Any,
    levels_mm: dict[str, Any],
    *,
    test: str | None = None,
    sample_period_s: float | None = None,
    gauges_m: dict[str, float] | None = None,
    metadata: dict[str, Any] | None = None,
    path: str = "",
) -> Record:
    """Build a checked, segmented :class:`Record` from in-memory arrays.

    Applies the same checks and segmentation as :func:`read_record`; messages name
    samples by index (``sample 7``) instead of file rows.

    Parameters
    ----------
    time_s : array_like
        Sample times, s, strictly increasing.
    opening_mm : array_like
        Gate opening, mm; NaN where missing.
    hold : array_like of bool
        True for ``hold`` samples (actuator still), False for ``open``.
    flow_m3h : array_like
        Inflow discharge, m³/h (no NaN).
    levels_mm : dict[str, array_like]
        Upstream level per gauge name, mm; NaN where missing.
    test : {"step", "prbs", "free"}, optional
        Test type (``test_source="option"``); else ``metadata["test"]``, else detected.
    sample_period_s : float, optional
        Nominal sample period, s; else ``metadata["sample_period_s"]``, else median step.
    gauges_m : dict[str, float], optional
        Gauge distance upstream of the gate, m; else ``metadata["gauges"]``.
    metadata : dict, optional
        Sidecar-like contents kept on the record.
    path : str, optional
        Label for error messages and ``Record.path``.

    Raises
    ------
    RecordError
        As :func:`read_record`.
    """
    origin = Origin(path or "<arrays>")
    meta = dict(metadata or {})
    if sample_period_s is not None:
        meta["sample_period_s"] = sample_period_s
    if gauges_m is not None:
        meta["gauges"] = dict(gauges_m)
    sidecar = sidecar_from_dict(origin.name, meta)
    columns = _array_columns(origin, time_s, opening_mm, hold, flow_m3h, levels_mm)
    return _build_record(origin, columns, sidecar, test, "", path)


def read_static_table(path: str | Path) -> StaticTable:
    """Read and check a quasi-steady rating table.

    Parameters
    ----------
    path : str or Path
        CSV with ``flow_m3h``, ``opening_mm``, one or more ``level_<G>_mm`` and optional
        ``level_<G>_sd_mm`` columns, one row per steady operating point.

    Raises
    ------
    RecordError
        With a one-line message naming the file, row or column, as :func:`read_record`.
    """
    table = read_table(path, keep=_is_static_column, text_columns=())
    origin = Origin(table.path, first_line=2)
    _require_static_columns(table)
    flow = table.columns["flow_m3h"]
    opening = table.columns["opening_mm"]
    for name, values, unit in (("flow_m3h", flow, "m³/h"), ("opening_mm", opening, "mm")):
        _checks.check_no_missing(origin, name, values)
        _checks.check_non_negative(origin, name, values, unit)
    levels = {g: table.columns[f"level_{g}_mm"] for g in _gauge_names(table.header)}
    for gauge, values in levels.items():
        _checks.check_level(origin, f"level_{gauge}_mm", values)
    sds = {
        g: table.columns[f"level_{g}_sd_mm"]
        for g in levels
        if f"level_{g}_sd_mm" in table.columns
    }
    for gauge, values in sds.items():
        _checks.check_non_negative(origin, f"level_{gauge}_sd_mm", values, "mm")
    return StaticTable(
        flow_m3h=_frozen(flow),
        opening_mm=_frozen(opening),
        levels_mm={g: _frozen(v) for g, v in levels.items()},
        level_sd_mm={g: _frozen(v) for g, v in sds.items()},
        path=table.path,
        sha256=table.sha256,
    )


def detect_table_kind(path: str | Path) -> str:
    """``"static"`` if the header is that of a rating table, else ``"record"``.

    A rating table has no ``time_s`` column but ``flow_m3h``, ``opening_mm`` and a level
    column. Anything unreadable is called a ``"record"`` so that :func:`read_record`
    reports what is wrong with it.
    """
    header = read_header(path)
    names = set(header)
    if "time_s" in names or not {"flow_m3h", "opening_mm"} <= names:
        return "record"
    return "static" if _gauge_names(header) else "record"


# --------------------------------------------------------------------------- columns


def gauge_of_column(name: str) -> str | None:
    """The gauge name of a level column (``"level_3F_mm"`` → ``"3F"``), else None.

    ``level_<G>_sd_mm`` columns are not level columns.
    """
    if not (name.startswith("level_") and name.endswith("_mm")):
        return None
    gauge = name[len("level_") : -len("_mm")]
    if not gauge or gauge.endswith("_sd"):
        return None
    return gauge


def _gauge_names(header: tuple[str, ...]) -> list[str]:
    return [g for g in map(gauge_of_column, header) if g is not None]


def _is_record_column(name: str) -> bool:
    return name in _REQUIRED or gauge_of_column(name) is not None


def _is_static_column(name: str) -> bool:
    if name in ("flow_m3h", "opening_mm") or gauge_of_column(name) is not None:
        return True
    return name.startswith("level_") and name.endswith("_sd_mm")


def _require_record_columns(table: TableColumns) -> None:
    for name in _REQUIRED:
        if name not in table.columns:
            raise RecordError(
                f"{table.path}: column '{name}': missing; expected columns time_s, "
                f"opening_mm, state, flow_m3h and level_<G>_mm (found {_listing(table)})"
            )
    if not _gauge_names(table.header):
        raise RecordError(
            f"{table.path}: column 'level_<G>_mm': missing; expected at least one level "
            f"column such as level_3F_mm (found {_listing(table)})"
        )


def _require_static_columns(table: TableColumns) -> None:
    for name in ("flow_m3h", "opening_mm"):
        if name not in table.columns:
            raise RecordError(
                f"{table.path}: column '{name}': missing; expected a rating table with "
                f"columns flow_m3h, opening_mm and level_<G>_mm (found {_listing(table)})"
            )
    if not _gauge_names(table.header):
        raise RecordError(
            f"{table.path}: column 'level_<G>_mm': missing; expected at least one level "
            f"column such as level_3F_mm (found {_listing(table)})"
        )


def _listing(table: TableColumns) -> str:
    text = ", ".join(table.header)
    return text if len(text) <= 120 else text[:117] + "..."


def _record_columns(origin: Origin, table: TableColumns) -> _Columns:
    cols = table.columns
    return _Columns(
        time_s=cols["time_s"],
        opening_mm=cols["opening_mm"],
        hold=_checks.hold_from_state(origin, cols["state"]),
        flow_m3h=cols["flow_m3h"],
        levels_mm={g: cols[f"level_{g}_mm"] for g in _gauge_names(table.header)},
    )


def _array_columns(
    origin: Origin, time_s: Any, opening_mm: Any, hold: Any, flow_m3h: Any, levels: Any
) -> _Columns:
    if not isinstance(levels, dict) or not levels:
        raise origin.error("levels_mm: expected a dict of gauge name to level array, mm")
    floats = {"time_s": time_s, "opening_mm": opening_mm, "flow_m3h": flow_m3h}
    floats.update({f"level_{g}_mm": v for g, v in levels.items()})
    arrays = {name: _float_array(origin, name, v) for name, v in floats.items()}
    hold_arr = np.asarray(hold)
    if hold_arr.dtype != bool:
        raise origin.error(_checks.column("state"), "hold: expected an array of bool")
    n = arrays["time_s"].size
    for name, values in [*arrays.items(), ("state", hold_arr)]:
        if values.shape != (n,):
            raise origin.error(
                _checks.column(name), f"shape {values.shape}; expected ({n},) like time_s"
            )
    for name, values in arrays.items():
        _checks.check_finite_or_missing(origin, name, values)
    return _Columns(
        time_s=arrays["time_s"],
        opening_mm=arrays["opening_mm"],
        hold=hold_arr.copy(),
        flow_m3h=arrays["flow_m3h"],
        levels_mm={g: arrays[f"level_{g}_mm"] for g in levels},
    )


def _float_array(origin: Origin, name: str, values: Any) -> np.ndarray:
    try:
        return np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise origin.error(_checks.column(name), "expected an array of numbers") from None


# --------------------------------------------------------------------------- building


def _build_record(
    origin: Origin, cols: _Columns, sidecar: Sidecar, test: str | None, sha256: str, path: str
) -> Record:
    _check_values(origin, cols)
    period = _sample_period(origin, cols.time_s, sidecar.sample_period_s)
    seg = _segments.segment_holds(origin, cols.time_s, cols.opening_mm, cols.hold, period)
    holds = tuple(
        HoldSegment(int(a), int(b), float(e))
        for a, b, e in zip(seg.starts, seg.stops, seg.openings_mm, strict=True)
    )
    pairs, unobserved = _segments.find_steps(seg, cols.time_s, period)
    steps = tuple(
        StepOnset(
            holds[k].stop, float(cols.time_s[holds[k].stop]), holds[k], holds[k + 1]
        )
        for k in pairs
    )
    chosen, source = _segments.choose_test(origin, test, sidecar.test, steps)
    record = Record(
        path=path,
        time_s=_frozen(cols.time_s),
        opening_mm=_frozen(seg.opening_mm),
        hold=_frozen(cols.hold),
        flow_m3h=_frozen(cols.flow_m3h),
        levels_mm={g: _frozen(v) for g, v in cols.levels_mm.items()},
        gauges_m={g: d for g, d in sidecar.gauges_m.items() if g in cols.levels_mm},
        test=chosen,
        test_source=source,
        sample_period_s=period,
        holds=holds,
        steps=steps,
        metadata=dict(sidecar.metadata),
        sha256=sha256,
        opening_filled=_frozen(seg.filled),
        unobserved_steps=unobserved,
    )
    _segments.check_method(origin, record)
    return record


def _sample_period(origin: Origin, time_s: np.ndarray, given_s: float | None) -> float:
    """The nominal sample period: as given, else the median time step."""
    median_s = float(np.median(np.diff(time_s)))
    if given_s is None:
        return median_s
    if median_s > _segments.GAP_FACTOR * given_s:
        raise origin.error(
            f"sample period {given_s:g} s (sidecar field 'sample_period_s') but the median "
            f"time step is {median_s:g} s; expected the nominal sample period"
        )
    return given_s


def _frozen(values: np.ndarray) -> np.ndarray:
    out = np.array(values, copy=True)
    out.flags.writeable = False
    return out


def _check_values(origin: Origin, cols: _Columns) -> None:
    n = cols.time_s.size
    if n < 2:
        raise origin.error(f"{n} sample(s); expected at least 2")
    _checks.check_no_missing(origin, "time_s", cols.time_s)
    _checks.check_time(origin, cols.time_s)
    _checks.check_no_missing(origin, "flow_m3h", cols.flow_m3h)
    _checks.check_non_negative(origin, "flow_m3h", cols.flow_m3h, "m³/h")
    _checks.check_non_negative(origin, "opening_mm", cols.opening_mm, "mm")
    for gauge, values in cols.levels_mm.items():
        _checks.check_level(origin, f"level_{gauge}_mm", values)
    _checks.check_hold_words(origin, cols.hold)


__all__ = [
    "GAP_FACTOR",
    "PRBS_MIN_STEPS",
    "PRBS_MIN_USABLE_SAMPLES",
    "RESOLUTION_MM",
    "STEP_WINDOW_SAMPLES",
    "TEST_TYPES",
    "HoldSegment",
    "Record",
    "StaticTable",
    "StepOnset",
    "detect_table_kind",
    "gauge_of_column",
    "read_record",
    "read_static_table",
    "record_from_arrays",
]
