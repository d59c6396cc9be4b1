"""Value checks shared by the record readers (files and in-memory arrays).

Each check looks at one column and raises a :class:`~gatetwin.errors.RecordError` whose
one-line message names the source, the row (file line) or sample, the column and what was
expected. This module knows nothing about files or segmentation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from gatetwin.errors import RecordError

__all__ = [
    "FLOW_MAX_M3H",
    "GAP_MAX_S",
    "LEVEL_RANGE_MM",
    "METRES_SUSPECT_BELOW",
    "OPENING_MAX_MM",
    "QUOTE_CHARS",
    "SAMPLE_PERIOD_RANGE_S",
    "TIME_ABS_MAX_S",
    "Origin",
    "check_bounds",
    "check_finite_or_missing",
    "check_gaps",
    "check_hold_words",
    "check_level",
    "check_no_missing",
    "check_non_negative",
    "check_range",
    "check_sample_period",
    "check_time",
    "column",
    "hold_from_codes",
    "hold_from_state",
    "quote",
]

#: Physically possible upstream levels, mm: a gauge zero up to 1 m above the sill or bed,
#: up to 100 m of water (beyond any canal or river gate; outside is a unit or logger
#: error). Levels logged as elevations above a datum set their own range in the sidecar.
LEVEL_RANGE_MM = (-1e3, 1e5)
#: A gauge whose every finite value is below this looks like it was logged in metres.
METRES_SUSPECT_BELOW = 2.0
#: Largest sample time magnitude, s (about 317 years: Unix time in seconds fits, a
#: value near 1e300 is a logger or unit error and would overflow later arithmetic).
TIME_ABS_MAX_S = 1e10
#: Largest gate opening, mm (100 m: beyond any gate; larger is a unit error).
OPENING_MAX_MM = 1e5
#: Largest discharge, m³/h (1e5 m³/s, half the Amazon's mean discharge: beyond any gate
#: structure; larger is a unit error).
FLOW_MAX_M3H = 3.6e8
#: Largest logging gap, s (one day at the nominal period; longer breaks a simulation
#: that steps through the record).
GAP_MAX_S = 86400.0
#: Accepted nominal sample periods, s: 1 ms is faster than any gate logger (a shorter
#: median step is a time unit error, e.g. hours logged as seconds); an hour is the slowest
#: SCADA log that still sees a canal pool respond (its time constants are tens of minutes).
SAMPLE_PERIOD_RANGE_S = (1e-3, 3600.0)
#: Characters of a cell an error message quotes at most.
QUOTE_CHARS = 60


@dataclass(frozen=True)
class Origin:
    """Where data came from, for error messages.

    Attributes
    ----------
    name : str
        File path, or a label such as ``"<arrays>"`` for in-memory data.
    first_line : int
        File line number of sample 0 (2 for a CSV with one header row); 0 for in-memory
        data, whose samples are then named by index (``sample 7``).
    columns : Mapping[str, str]
        The file's name of each column known by its internal name (``level_3F_mm`` →
        ``level_3F_m``); messages name the file's column. Empty: names as they are.
    """

    name: str
    first_line: int = 0
    columns: Mapping[str, str] = field(default_factory=dict)

    def column(self, name: str) -> str:
        """Quote column ``name`` (internal) by the name the file gave it."""
        return column(self.columns.get(name, name))

    def row(self, index: int) -> str:
        """Name sample ``index`` as a file row (1-based line) or an array sample."""
        if self.first_line:
            return f"row {int(index) + self.first_line}"
        return f"sample {int(index)}"

    def error(self, *parts: str) -> RecordError:
        """Build the one-line error ``"<name>: part: part: ..."``."""
        return RecordError(": ".join((self.name, *parts)))


def column(name: str) -> str:
    """Quote a column name the way every message does."""
    short = name if len(name) <= QUOTE_CHARS else name[:QUOTE_CHARS] + "..."
    return f"column '{short}'"


def quote(text: str) -> str:
    """``repr`` of a cell, cut to :data:`QUOTE_CHARS` characters (a huge cell is not echoed)."""
    if len(text) <= QUOTE_CHARS:
        return repr(text)
    return repr(text[:QUOTE_CHARS]) + f"... ({len(text)} characters)"


def check_finite_or_missing(origin: Origin, name: str, values: np.ndarray) -> None:
    """Refuse infinite values (NaN stands for a missing value and passes)."""
    bad = np.flatnonzero(np.isinf(values))
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i),
            origin.column(name),
            f"{values[i]} is not a finite number; expected mm, s "
            "or m³/h as a plain number (empty cells are the only missing values)",
        )


def check_no_missing(origin: Origin, name: str, values: np.ndarray) -> None:
    """Refuse missing (NaN) values in a column that must be complete."""
    bad = np.flatnonzero(np.isnan(values))
    if bad.size:
        raise origin.error(origin.row(bad[0]), origin.column(name), "empty cell; expected a number")


def check_time(origin: Origin, time_s: np.ndarray) -> None:
    """Refuse sample times that are not strictly increasing."""
    dt = np.diff(time_s)
    bad = np.flatnonzero(~(dt > 0))
    if not bad.size:
        return
    i = int(bad[0]) + 1
    word = "duplicated time" if dt[i - 1] == 0 else "time goes backwards"
    raise origin.error(
        origin.row(i),
        origin.column("time_s"),
        f"{word} ({time_s[i]:g} s after {time_s[i - 1]:g} s); expected strictly increasing times",
    )


def check_non_negative(origin: Origin, name: str, values: np.ndarray, unit: str) -> None:
    """Refuse negative values (missing values pass)."""
    bad = np.flatnonzero(values < 0)
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i), origin.column(name), f"negative value {values[i]:g} {unit}; expected ≥ 0"
        )


def check_level(
    origin: Origin,
    name: str,
    values: np.ndarray,
    limits: tuple[float, float] = LEVEL_RANGE_MM,
    *,
    logged_in_mm: bool = True,
) -> None:
    """Refuse a level column that is empty, outside ``limits`` (mm) or apparently in metres.

    ``values`` are in mm; the metres test applies only to a column the file says is in
    mm (``logged_in_mm``).
    """
    finite = values[np.isfinite(values)]
    if not finite.size:
        raise origin.error(origin.column(name), "no values; expected upstream levels in mm")
    low, high = limits
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i),
            origin.column(name),
            f"level {values[i]:g} mm outside the physical range {low:g}..{high:g} mm",
        )
    top = float(finite.max())
    if logged_in_mm and top < METRES_SUSPECT_BELOW and top > float(finite.min()):
        raise origin.error(
            origin.column(name),
            f"every value is below {METRES_SUSPECT_BELOW:g} (largest {top:g}): looks like "
            "metres; expected mm",
        )


def check_hold_words(origin: Origin, hold: np.ndarray) -> None:
    """Refuse a record without a single ``hold`` sample."""
    if not np.any(hold):
        raise origin.error(
            origin.column("state"),
            "no 'hold' samples (the actuator never stands still); expected hold segments "
            "at a constant opening",
        )


def hold_from_state(origin: Origin, words: np.ndarray) -> np.ndarray:
    """Turn ``state`` words into the ``hold`` flag, refusing empty or unknown words.

    ``hold`` and ``open`` are accepted in any letter case.
    """
    vocabulary, codes = np.unique(np.asarray(words, dtype=str), return_inverse=True)
    return hold_from_codes(origin, tuple(str(w) for w in vocabulary), codes.ravel())


def hold_from_codes(origin: Origin, vocabulary: tuple[str, ...], codes: np.ndarray) -> np.ndarray:
    """The ``hold`` flag of dictionary-coded ``state`` words (``vocabulary[codes]``).

    Words are compared stripped and in any letter case; empty or unknown words are
    refused naming the first row that has one.
    """
    lowered = [word.strip().lower() for word in vocabulary]
    is_hold = np.array([word == "hold" for word in lowered] or [False])
    is_known = np.array([word in ("hold", "open") for word in lowered] or [False])
    if not is_known.all():
        bad = np.flatnonzero(~is_known[codes])
        if bad.size:
            i = int(bad[0])
            word = vocabulary[int(codes[i])].strip()
            found = f"unknown state {quote(word)}" if word else "empty cell"
            raise origin.error(
                origin.row(i), origin.column("state"), f"{found}; expected 'hold' or 'open'"
            )
    return is_hold[codes]


def check_bounds(origin: Origin, name: str, values: np.ndarray, limit: float, unit: str) -> None:
    """Refuse magnitudes above ``limit`` (missing values pass)."""
    bad = np.flatnonzero(np.abs(values) > limit)
    if bad.size:
        raise _beyond(origin, name, values, int(bad[0]), limit, unit)


def _beyond(
    origin: Origin, name: str, values: np.ndarray, i: int, limit: float, unit: str
) -> RecordError:
    return origin.error(
        origin.row(i), origin.column(name),
        f"{values[i]:g} {unit} is beyond the physical bound of {limit:g} {unit}; "
        "expected a value in the record's units",
    )  # fmt: skip


def check_range(
    origin: Origin, name: str, values: np.ndarray, limits: tuple[float, float], unit: str
) -> None:
    """Refuse values outside ``limits`` (missing values pass); the message for a value
    above is that of :func:`check_bounds`."""
    low, high = limits
    above = np.flatnonzero(values > high)
    if above.size:
        raise _beyond(origin, name, values, int(above[0]), high, unit)
    bad = np.flatnonzero(values < low)
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i), origin.column(name),
            f"{values[i]:g} {unit} is below the bound of {low:g} {unit}; expected a value in "
            "the record's units (or 'bounds' in the sidecar)",
        )  # fmt: skip


def check_gaps(origin: Origin, time_s: np.ndarray, max_gap_s: float = GAP_MAX_S) -> None:
    """Refuse a logging gap longer than ``max_gap_s`` between consecutive samples."""
    bad = np.flatnonzero(np.diff(time_s) > max_gap_s)
    if bad.size:
        i = int(bad[0]) + 1
        raise origin.error(
            origin.row(i), origin.column("time_s"),
            f"gap of {time_s[i] - time_s[i - 1]:g} s after {time_s[i - 1]:g} s, longer than "
            f"{max_gap_s:g} s; expected a continuous log (split it into records at the gap)",
        )  # fmt: skip


def check_sample_period(
    name: str, period_s: float, source: str, limits: tuple[float, float] = SAMPLE_PERIOD_RANGE_S
) -> None:
    """Refuse a nominal sample period outside ``limits`` (s); ``source`` says where it came from.

    ``name`` labels the message (the record's file or label).
    """
    low, high = limits
    if not low <= period_s <= high:
        raise RecordError(
            f"{name}: sample period {period_s:g} s ({source}) outside the accepted range "
            f"{low:g}..{high:g} s; expected the logger's period in seconds (set "
            "'bounds': {'sample_period_s': [lo, hi]} in the sidecar for another range)"
        )
