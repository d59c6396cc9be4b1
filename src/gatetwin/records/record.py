"""Time-series records: the one reader every command uses.

A record is a CSV (or Parquet) file in the format of ``docs/record_format.md`` plus an optional
JSON sidecar of the same stem. :func:`read_record` turns it into a frozen :class:`Record`
with its hold segments and step onsets found, or refuses it with a
:class:`~gatetwin.errors.RecordError` whose one-line message names the file and the row
or column at fault. :func:`record_from_arrays` does the same for in-memory arrays, and
:meth:`Record.from_pandas` for a DataFrame.

This module does not identify anything; it only reads, checks and segments.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records import checks, segments
from gatetwin.records.bounds import Bounds
from gatetwin.records.checks import TIME_ABS_MAX_S, Origin
from gatetwin.records.columns import (
    TableColumns,
    frozen,
    gauge_names,
    is_record_column,
    record_table,
    value_range,
)
from gatetwin.records.frame import frame_columns, import_pandas, is_frame
from gatetwin.records.limits import ReadLimits
from gatetwin.records.segments import HoldSegment, StepOnset
from gatetwin.records.sidecar import Sidecar, read_sidecar, sidecar_from_dict
from gatetwin.records.table import read_table
from gatetwin.records.units import INTERNAL_UNITS, HeaderUnits

__all__ = [
    "MEMO_SIZE",
    "Record",
    "content_digest",
    "per_record_memo",
    "read_record",
    "record_from_arrays",
]


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
        Inflow discharge, m³/h. An empty cell (a flow meter's dropout) holds the last logged
        value; before the first logged one, the last one logged before the record's rows
        (a record of some rows of a history, :func:`~gatetwin.records.chunks.chunk_record`),
        else the first logged one (see ``flow_filled``).
    levels_mm : dict[str, ndarray]
        Upstream level per gauge name (``"3F"`` for column ``level_3F_mm``), mm.
    gauges_m : dict[str, float]
        Distance of each gauge upstream of the gate, m, where known (sidecar).
    test : str
        ``"step"``, ``"prbs"``, ``"free"`` or ``"routine"``.
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
    flow_filled : ndarray of bool or None
        True for samples whose empty discharge was filled by holding the last logged one.
    unobserved_steps : int
        Opening changes between hold segments that fall inside a logging gap (onset
        unknown, so not in ``steps``).
    units : dict
        The units the record came in, e.g. ``{"opening": "m", "flow": "m3s", "level":
        "m", "levels": {"3F": "m"}}`` (``"level"`` is ``"mixed"`` if the gauges differ);
        the arrays are in mm and m³/h whatever these say.
    gate_width_m : float or None
        Width of the gate, m (sidecar ``gate_width_m``), where known.
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
    flow_filled: np.ndarray | None = None
    unobserved_steps: int = 0
    units: dict[str, Any] = field(default_factory=lambda: dict(INTERNAL_UNITS))
    gate_width_m: float | None = None

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
        return _record_summary(self)

    def to_pandas(self) -> Any:
        """The record as a ``pandas.DataFrame`` in the columns of the data format.

        Columns ``time_s``, ``opening_mm``, ``state`` (``"hold"``/``"open"``),
        ``flow_m3h`` and ``level_<G>_mm``; missing values are NaN.

        Raises
        ------
        GatetwinError
            If pandas is not installed (it is not a dependency of gatetwin).
        """
        pandas = import_pandas("Record.to_pandas")
        data: dict[str, Any] = {
            "time_s": self.time_s,
            "opening_mm": self.opening_mm,
            "state": np.where(self.hold, "hold", "open"),
            "flow_m3h": self.flow_m3h,
        }
        data.update({f"level_{g}_mm": v for g, v in self.levels_mm.items()})
        return pandas.DataFrame({name: np.array(v) for name, v in data.items()})

    @classmethod
    def from_pandas(
        cls,
        frame: Any,
        *,
        sample_period_s: float | None = None,
        gauges: dict[str, float] | None = None,
        test: str | None = None,
        metadata: dict[str, Any] | None = None,
        path: str = "<DataFrame>",
    ) -> Record:
        """Check and segment a DataFrame holding the columns of the data format.

        Parameters
        ----------
        frame : pandas.DataFrame
            Columns ``time_s``, ``opening_mm``, ``state``, ``flow_m3h`` and one or more
            ``level_<G>_mm`` (numbers; NaN or None for missing values), or the same in other
            units (``opening_m``, ``flow_m3s``, ``level_<G>_cm``, ...; see
            :mod:`gatetwin.records.units`); others ignored.
        sample_period_s : float, optional
            Nominal sample period, s; else ``metadata["sample_period_s"]``, else the
            median time step.
        gauges : dict[str, float], optional
            Gauge distance upstream of the gate, m.
        test : {"step", "prbs", "free", "routine"}, optional
            Test type; else ``metadata["test"]``, else detected.
        metadata : dict, optional
            Sidecar-like contents kept on the record.
        path : str, optional
            Label for error messages (rows are counted from 1).

        Raises
        ------
        RecordError
            As :func:`read_record`.
        """
        table = frame_columns(frame, path)
        meta = dict(metadata or {})
        if sample_period_s is not None:
            meta["sample_period_s"] = sample_period_s
        if gauges is not None:
            meta["gauges"] = dict(gauges)
        return _record_from_table(table, sidecar_from_dict(path, meta), test)


@dataclass(frozen=True)
class _Columns:
    """Raw, unchecked columns of a time-series record (float arrays, bool ``hold``)."""

    time_s: np.ndarray
    opening_mm: np.ndarray
    hold: np.ndarray
    flow_m3h: np.ndarray
    levels_mm: dict[str, np.ndarray]
    sources: HeaderUnits = field(default_factory=HeaderUnits)
    #: Discharge the rows before sample 0 leave held (their last logged one), m³/h; NaN for
    #: a file or arrays read whole, which have no rows before.
    flow_before_m3h: float = np.nan

    def in_mm(self, gauge: str) -> bool:
        """Whether the file logged ``gauge``'s level in mm."""
        found = self.sources.columns.get(f"level_{gauge}_mm")
        return found is None or found.unit == "mm"

    def units(self) -> dict[str, Any]:
        """The units the columns came in (internal units for arrays)."""
        return self.sources.filled(list(self.levels_mm))


# --------------------------------------------------------------------------- public API


_Result = TypeVar("_Result")
#: Results each :func:`per_record_memo` function keeps (a record's floor or step fits are a
#: few floats; the oldest result goes first).
MEMO_SIZE = 256


def content_digest(record: Record) -> bytes:
    """A digest of everything ``record`` holds (arrays, segments, metadata, path): equal
    for two reads of the same file, different as soon as one value differs. Arrays are
    hashed where they lie (a month of samples is not copied)."""
    digest = hashlib.blake2b(digest_size=16)
    for item in dataclasses.fields(record):
        _feed(digest, item.name, getattr(record, item.name))
    return digest.digest()


def _feed(digest: Any, name: str, value: Any) -> None:
    digest.update(name.encode() + b"\0")
    if isinstance(value, np.ndarray):
        digest.update(f"{value.dtype.str}{value.shape}".encode())
        digest.update(np.ascontiguousarray(value).data)
    elif isinstance(value, dict):
        digest.update(b"{%d}" % len(value))
        for key in sorted(value, key=str):
            _feed(digest, str(key), value[key])
    else:
        digest.update(pickle.dumps(value, protocol=5))


def per_record_memo(func: Callable[..., _Result]) -> Callable[..., _Result]:
    """``func(record, *args)`` computed once per record content and ``args`` (hashable) in
    this process: for what depends on the measured record only, which validating many FMUs
    against the same records asks for again and again. ``func``'s results must not be
    mutated by its callers."""
    memo: dict[tuple[bytes, tuple[Any, ...]], _Result] = {}

    @functools.wraps(func)
    def cached(record: Record, *args: Any) -> _Result:
        key = (content_digest(record), args)
        if key not in memo:
            if len(memo) >= MEMO_SIZE:
                del memo[next(iter(memo))]
            memo[key] = func(record, *args)
        return memo[key]

    return cached


def read_record(
    path: str | os.PathLike[str] | Any,
    test: str | None = None,
    *,
    limits: ReadLimits | None = None,
) -> Record:
    """Read, check and segment a time-series record.

    Parameters
    ----------
    path : str, os.PathLike or pandas.DataFrame
        The record's CSV file (Parquet if it ends in ``.parquet`` or ``.pq``); a sidecar
        ``NAME.json`` next to it is read if present. Columns may carry any unit of
        :mod:`gatetwin.records.units` (``opening_m``, ``flow_m3s``, ``level_3F_cm``);
        the record holds mm and m³/h and says in ``units`` what the file had. A
        DataFrame is taken as :meth:`Record.from_pandas` takes it.
    test : {"step", "prbs", "free", "routine"}, optional
        Test type from the command line; overrides the sidecar and detection.
    limits : ReadLimits, optional
        File size and line length limits; default :class:`ReadLimits` with the
        ``GATETWIN_MAX_BYTES``/``GATETWIN_MAX_LINE_BYTES`` overrides.

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
    * Values beyond physics are refused unless the sidecar's ``bounds`` allow them:
      ``|time_s|`` above 1e10 s, a time step above one day (``GAP_MAX_S``), a sample
      period outside 1e-3..3600 s, an opening above 1e5 mm, a flow above 3.6e8 m³/h
      (1e5 m³/s), a level outside -1000..1e5 mm.
    * A ``step`` record needs ≥ 40 valid (finite-level) hold samples at every gauge
      before and after its first step (after it: counted to where the gate next moved or
      the inflow changed, across logging gaps, :attr:`StepOnset.held_after`); a ``prbs``
      record ≥ 2 steps and ≥ 30 usable hold samples at every gauge (the first 2 of each
      hold segment are not usable).
    """
    if is_frame(path):
        return Record.from_pandas(path, test=test)
    if not isinstance(path, (str, os.PathLike)):
        raise RecordError(
            f"{type(path).__name__} given as a record; expected a file path or a DataFrame"
        )
    table = read_table(path, keep=is_record_column, text_columns=("state",), limits=limits)
    return _record_from_table(table, read_sidecar(path), test)


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
    flow_before_m3h: float = np.nan,
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
        Inflow discharge, m³/h; NaN where missing (held as :func:`read_record` holds an
        empty cell).
    levels_mm : dict[str, array_like]
        Upstream level per gauge name, mm; NaN where missing.
    test : {"step", "prbs", "free", "routine"}, optional
        Test type (``test_source="option"``); else ``metadata["test"]``, else detected.
    sample_period_s : float, optional
        Nominal sample period, s; else ``metadata["sample_period_s"]``, else median step.
    gauges_m : dict[str, float], optional
        Gauge distance upstream of the gate, m; else ``metadata["gauges"]``.
    metadata : dict, optional
        Sidecar-like contents kept on the record.
    path : str, optional
        Label for error messages and ``Record.path``.
    flow_before_m3h : float, optional
        The last discharge logged before these rows (some rows of a longer history), m³/h:
        the empty discharge cells before the rows' first logged one hold it (NaN, the
        default: they hold that first logged one).

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
    columns = dataclasses.replace(columns, flow_before_m3h=float(flow_before_m3h))
    return _build_record(origin, columns, sidecar, test, "", path)


def _record_from_table(table: TableColumns, sidecar: Sidecar, test: str | None) -> Record:
    table = record_table(table)
    origin = table.origin()
    columns = _record_columns(origin, table)
    return _build_record(origin, columns, sidecar, test, table.sha256, table.path)


def _record_columns(origin: Origin, table: TableColumns) -> _Columns:
    state = table.words("state")
    return _Columns(
        time_s=table.floats("time_s"),
        opening_mm=table.floats("opening_mm"),
        hold=checks.hold_from_codes(origin, state.vocabulary, state.codes),
        flow_m3h=table.floats("flow_m3h"),
        levels_mm={g: table.floats(f"level_{g}_mm") for g in gauge_names(table.header)},
        sources=table.units,
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
        raise origin.error(checks.column("state"), "hold: expected an array of bool")
    n = arrays["time_s"].size
    for name, values in [*arrays.items(), ("state", hold_arr)]:
        if values.shape != (n,):
            raise origin.error(
                checks.column(name), f"shape {values.shape}; expected ({n},) like time_s"
            )
    for name, values in arrays.items():
        checks.check_finite_or_missing(origin, name, values)
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
        raise origin.error(checks.column(name), "expected an array of numbers") from None


# --------------------------------------------------------------------------- building


def _build_record(
    origin: Origin, cols: _Columns, sidecar: Sidecar, test: str | None, sha256: str, path: str
) -> Record:
    _check_values(origin, cols, sidecar.bounds)
    flow_m3h, flow_filled = _held_flow(cols.flow_m3h, cols.flow_before_m3h)
    period = _sample_period(origin, cols.time_s, sidecar)
    seg = segments.segment_holds(origin, cols.time_s, cols.opening_mm, cols.hold, period)
    holds = tuple(
        HoldSegment(int(a), int(b), float(e))
        for a, b, e in zip(seg.starts, seg.stops, seg.openings_mm, strict=True)
    )
    pairs, unobserved = segments.find_steps(seg, cols.time_s, period)
    logged_flow = np.where(flow_filled, np.nan, flow_m3h)  # the inflow test's discharges
    steps = tuple(
        StepOnset(
            holds[k].stop,
            float(cols.time_s[holds[k].stop]),
            holds[k],
            holds[k + 1],
            segments.held_after(holds, k + 1, logged_flow),
        )  # fmt: skip
        for k in pairs
    )
    chosen, source = segments.choose_test(origin, test, sidecar.test, steps)
    record = Record(
        path=path,
        time_s=frozen(cols.time_s),
        opening_mm=frozen(seg.opening_mm),
        hold=frozen(cols.hold),
        flow_m3h=frozen(flow_m3h),
        levels_mm={g: frozen(v) for g, v in cols.levels_mm.items()},
        gauges_m={g: d for g, d in sidecar.gauges_m.items() if g in cols.levels_mm},
        test=chosen,
        test_source=source,
        sample_period_s=period,
        holds=holds,
        steps=steps,
        metadata=dict(sidecar.metadata),
        sha256=sha256,
        opening_filled=frozen(seg.filled),
        flow_filled=frozen(flow_filled),
        unobserved_steps=unobserved,
        units=cols.units(),
        gate_width_m=sidecar.gate_width_m,
    )
    segments.check_method(origin, segments.Segmented(
        record.test, record.test_source, record.holds, record.steps, record.unobserved_steps,
        record.levels_mm,
    ))  # fmt: skip
    return record


def _held_flow(flow_m3h: np.ndarray, before_m3h: float = np.nan) -> tuple[np.ndarray, np.ndarray]:
    """The discharge with each empty cell holding the last logged value, and where that was
    done: what a flow meter's dropout leaves is taken as unchanged, as the logger holds every
    other input between samples. Empty cells before the first logged one hold
    ``before_m3h``, the last value of the rows before (NaN: none; they then hold the first
    logged one)."""
    missing = np.isnan(flow_m3h)
    if not missing.any():
        return flow_m3h, missing
    last = np.maximum.accumulate(np.where(missing, -1, np.arange(flow_m3h.size)))
    held = flow_m3h[np.maximum(last, 0)]
    if np.isnan(before_m3h):
        before_m3h = flow_m3h[np.flatnonzero(~missing)[0]]
    held[last < 0] = before_m3h
    return held, missing


def _sample_period(origin: Origin, time_s: np.ndarray, sidecar: Sidecar) -> float:
    """The nominal sample period: the sidecar's, else the median time step."""
    median_s = float(np.median(np.diff(time_s)))
    given_s, limits = sidecar.sample_period_s, sidecar.bounds.sample_period_s
    if given_s is None:
        checks.check_sample_period(origin.name, median_s, "the median time step", limits)
        return median_s
    checks.check_sample_period(origin.name, given_s, "sidecar field 'sample_period_s'", limits)
    segments.check_median_step(origin.name, given_s, median_s)
    return given_s


def _check_values(origin: Origin, cols: _Columns, bounds: Bounds) -> None:
    """Check the values (in mm and m³/h) against ``bounds``; ``origin`` names the columns
    as the file does."""
    n = cols.time_s.size
    if n < 2:
        raise origin.error(f"{n} sample(s); expected at least 2")
    checks.check_no_missing(origin, "time_s", cols.time_s)
    checks.check_bounds(origin, "time_s", cols.time_s, TIME_ABS_MAX_S, "s")
    checks.check_time(origin, cols.time_s)
    checks.check_gaps(origin, cols.time_s, bounds.gap_max_s)
    if np.isnan(cols.flow_m3h).all() and np.isnan(cols.flow_before_m3h):
        raise origin.error(origin.column("flow_m3h"), "every cell is empty; expected m³/h")
    checks.check_non_negative(origin, "flow_m3h", cols.flow_m3h, "m³/h")
    checks.check_range(origin, "flow_m3h", cols.flow_m3h, bounds.flow_m3h, "m³/h")
    checks.check_non_negative(origin, "opening_mm", cols.opening_mm, "mm")
    checks.check_range(origin, "opening_mm", cols.opening_mm, bounds.opening_mm, "mm")
    for gauge, values in cols.levels_mm.items():
        checks.check_level(origin, f"level_{gauge}_mm", values, bounds.level_mm,
                           logged_in_mm=cols.in_mm(gauge))  # fmt: skip
    checks.check_hold_words(origin, cols.hold)


def _record_summary(record: Record) -> dict[str, Any]:
    """Summarise a :class:`~gatetwin.records.Record`."""
    lengths = np.array([h.n_samples for h in record.holds])
    return {
        "kind": "record",
        "path": record.path,
        "sha256": record.sha256,
        "test": record.test,
        "test_source": record.test_source,
        "n_samples": record.n_samples,
        "sample_period_s": record.sample_period_s,
        "time_s": {"start": float(record.time_s[0]), "stop": float(record.time_s[-1])},
        "duration_s": float(record.time_s[-1] - record.time_s[0]),
        "gauges": [_gauge_summary(record, g) for g in record.gauges],
        "flow_m3h": value_range(record.flow_m3h),
        "opening_mm": value_range(record.opening_mm),
        "hold_segments": {
            "count": int(lengths.size),
            "samples_total": int(lengths.sum()),
            "samples_min": int(lengths.min()),
            "samples_median": float(np.median(lengths)),
            "samples_max": int(lengths.max()),
        },
        "opening_filled_samples": int(np.count_nonzero(record.opening_filled))
        if record.opening_filled is not None
        else 0,
        "flow_filled_samples": int(np.count_nonzero(record.flow_filled))
        if record.flow_filled is not None
        else 0,
        "steps": [
            {
                "index": s.index,
                "time_s": s.time_s,
                "opening_before_mm": s.before.opening_mm,
                "opening_after_mm": s.after.opening_mm,
                "delta_e_mm": s.delta_e_mm,
            }
            for s in record.steps
        ],
        "unobserved_steps": record.unobserved_steps,
        "units": record.units,
        "gate_width_m": record.gate_width_m,
        "metadata": record.metadata,
    }


def _gauge_summary(record: Record, gauge: str) -> dict[str, Any]:
    level = record.levels_mm[gauge]
    return {
        "name": gauge,
        "distance_m": record.gauges_m.get(gauge),
        "valid_samples": int(np.count_nonzero(np.isfinite(level))),
        "level_mm": value_range(level),
    }
