"""Value checks shared by the record readers (files and in-memory arrays).

Each check looks at one column and raises a :class:`~gatetwin.errors.RecordError` whose
one-line message names the source, the row (file line) or sample, the column and what was
expected. This module knows nothing about files or segmentation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gatetwin.errors import RecordError

#: Physically possible upstream levels, mm (anything outside is a unit or logger error).
LEVEL_RANGE_MM = (-100.0, 2000.0)
#: A gauge whose every finite value is below this looks like it was logged in metres.
METRES_SUSPECT_BELOW = 2.0


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
    """

    name: str
    first_line: int = 0

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
    return f"column '{name}'"


def check_finite_or_missing(origin: Origin, name: str, values: np.ndarray) -> None:
    """Refuse infinite values (NaN stands for a missing value and passes)."""
    bad = np.flatnonzero(np.isinf(values))
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i), column(name), f"{values[i]} is not a finite number; expected mm, s "
            "or m³/h as a plain number (empty cells are the only missing values)"
        )


def check_no_missing(origin: Origin, name: str, values: np.ndarray) -> None:
    """Refuse missing (NaN) values in a column that must be complete."""
    bad = np.flatnonzero(np.isnan(values))
    if bad.size:
        raise origin.error(origin.row(bad[0]), column(name), "empty cell; expected a number")


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
        column("time_s"),
        f"{word} ({time_s[i]:g} s after {time_s[i - 1]:g} s); expected strictly increasing "
        "times",
    )


def check_non_negative(origin: Origin, name: str, values: np.ndarray, unit: str) -> None:
    """Refuse negative values (missing values pass)."""
    bad = np.flatnonzero(values < 0)
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i), column(name), f"negative value {values[i]:g} {unit}; expected ≥ 0"
        )


def check_level(origin: Origin, name: str, values: np.ndarray) -> None:
    """Refuse a level column that is empty, out of range or apparently in metres."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        raise origin.error(column(name), "no values; expected upstream levels in mm")
    low, high = LEVEL_RANGE_MM
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        i = bad[0]
        raise origin.error(
            origin.row(i),
            column(name),
            f"level {values[i]:g} mm outside the physical range {low:g}..{high:g} mm",
        )
    top = float(finite.max())
    if top < METRES_SUSPECT_BELOW and top > float(finite.min()):
        raise origin.error(
            column(name),
            f"every value is below {METRES_SUSPECT_BELOW:g} (largest {top:g}): looks like "
            "metres; expected mm",
        )


def check_hold_words(origin: Origin, hold: np.ndarray) -> None:
    """Refuse a record without a single ``hold`` sample."""
    if not np.any(hold):
        raise origin.error(
            column("state"),
            "no 'hold' samples (the actuator never stands still); expected hold segments "
            "at a constant opening",
        )


def hold_from_state(origin: Origin, words: np.ndarray) -> np.ndarray:
    """Turn ``state`` words into the ``hold`` flag, refusing empty or unknown words.

    ``hold`` and ``open`` are accepted in any letter case.
    """
    hold = words == "hold"
    known = hold | (words == "open")
    if not known.all():
        lowered = np.char.lower(words)
        hold = lowered == "hold"
        known = hold | (lowered == "open")
    bad = np.flatnonzero(~known)
    if bad.size:
        i = bad[0]
        found = f"unknown state {str(words[i])!r}" if words[i] else "empty cell"
        raise origin.error(origin.row(i), column("state"), f"{found}; expected 'hold' or 'open'")
    return hold
