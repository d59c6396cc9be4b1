"""Routine identification of a history too long to hold: window by window, chunk by chunk.

:func:`identify_routine_chunked` gives what
:func:`~gatetwin.identification.routine.identify_routine` gives for the whole history read at
once, window for window, while holding a bounded part of it: the rows still undecided plus
one chunk. Rows arrive a chunk at a time
(:mod:`gatetwin.records.chunks`); the rows held so far become a record, segmented as the
whole history's would be because the held rows always begin where a hold segment begins.
A move event is decided once the hold segment after its last move, and the one after that,
are complete (neither can grow with the next chunk): its window is screened and fitted as
the whole-history path does, on the same samples. Rows before the first undecided event
are dropped; an event that spans a chunk boundary is carried over into the next record.
The rows held carry the last discharge logged before them (before the history's first
logged discharge, that one), which their leading empty discharge cells hold, as the whole
history read at once holds them.

Memory: one chunk, plus the undecided rows, which reach back to the start of the hold
segment before the earliest undecided move. A gate held still for days keeps that hold's
rows until it moves again; a history with moves every few hours holds a few hours.

What this is not: a reader of CSV files larger than memory (a single CSV is read whole; a
folder of day files is read a file at a time).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from gatetwin.errors import IdentificationError, NoWindowError, RecordError
from gatetwin.identification.routine import (
    RoutineIdentification,
    RoutineWindow,
    WindowCriteria,
    assemble,
    gauge_of,
    has_level_controller,
    move_events,
    no_window_message,
    tally_event,
)
from gatetwin.records import Record
from gatetwin.records.chunks import (
    Chunk,
    History,
    chunk_record,
    history_sample_period,
    iter_chunks,
)
from gatetwin.records.chunks import open_history as open_history
from gatetwin.records.segments import RESOLUTION_MM, is_gap

__all__ = [
    "BASE_MEMORY_MIB",
    "DEFAULT_CHUNK_ROWS",
    "MAX_MEMORY_MIB",
    "ChunkedScan",
    "chunk_rows_for",
    "identify_routine_chunked",
    "scan_routine_history",
]

#: Rows per chunk by default: about 1.6 h at 1 Hz (a few MiB of columns).
DEFAULT_CHUNK_ROWS = 65536
#: Float64 columns beside the levels: time, opening, flow (and the one byte of ``hold``).
_BASE_COLUMNS = 3
#: Copies of a row the scan holds at its peak: the carried rows, the new chunk, the record
#: built from them (checked copies, filled opening, segment indices, the gap and hold
#: masks), Arrow's batch and its decoded columns (measured: about 400 bytes a row for one
#: gauge, 12 copies of its 33 bytes; 16 leaves a margin).
_WORKING_COPIES = 16
#: Resident memory of ``gatetwin routine`` before it reads a row (interpreter, numpy,
#: scipy, pyarrow, numba and the fit's compiled kernels), MiB, as measured.
BASE_MEMORY_MIB = 300.0
#: Largest budget taken, MiB: an exbibyte, beyond any machine's memory (a larger number, or
#: infinity, is a mistake, not a budget).
MAX_MEMORY_MIB = 2.0**40


def chunk_rows_for(max_memory_mib: float, n_gauges: int = 1) -> int:
    """Rows per chunk that keep a scan within ``max_memory_mib`` (see module doc), at least
    one hour at 1 Hz.

    Raises
    ------
    IdentificationError
        A budget not above :data:`BASE_MEMORY_MIB`, or above :data:`MAX_MEMORY_MIB` (which
        also refuses infinity and NaN).
    """
    if not max_memory_mib > BASE_MEMORY_MIB:
        raise IdentificationError(f"memory budget {max_memory_mib:g} MiB: expected more than "
                                  f"the {BASE_MEMORY_MIB:g} MiB the interpreter and its "
                                  "libraries take")  # fmt: skip
    if not max_memory_mib <= MAX_MEMORY_MIB:
        raise IdentificationError(f"memory budget {max_memory_mib:g} MiB: expected at most "
                                  f"{MAX_MEMORY_MIB:g} MiB (an exbibyte)")  # fmt: skip
    row_bytes = 8 * (_BASE_COLUMNS + n_gauges) + 1
    free = (max_memory_mib - BASE_MEMORY_MIB) * 2**20
    return max(3600, int(free / (_WORKING_COPIES * row_bytes) / 2))


@dataclass
class _Scan:
    """What the scan has decided so far."""

    gauge: str | None
    crit: WindowCriteria
    windows: list[RoutineWindow] = field(default_factory=list)
    rejected: dict[str, int] = field(default_factory=dict)
    n_moves: int = 0
    unobserved: int = 0
    #: Global row of the later segment of the last consecutive pair counted.
    counted_row: int = -1
    controller: bool = False


def _check_gauges(path: str, held: list[Chunk], new: Chunk) -> None:
    if held and set(held[0].levels_mm) != set(new.levels_mm):
        expected = ", ".join(sorted(held[0].levels_mm))
        raise RecordError(f"{path}: row {new.first_row + 1} of the history: gauges "
                          f"{', '.join(sorted(new.levels_mm))}; expected {expected} like the "
                          "rows before")  # fmt: skip


def _lengthens_last_hold(last: Chunk, new: Chunk, period_s: float) -> bool:
    """Whether the rows of ``new`` only lengthen the hold segment the rows before end in:
    held throughout, logged at exactly that segment's last opening (or not logged), with no
    gap. The segmentation then has the same segments but a longer last one, and a scan
    would decide nothing more (an event waits for two segments after its last move)."""
    opening = last.opening_mm[-1]
    if not (last.hold[-1] and np.isfinite(opening) and bool(np.all(new.hold))):
        return False
    same = np.isnan(new.opening_mm) | (new.opening_mm == opening)
    times = np.concatenate(([last.time_s[-1]], new.time_s))
    return bool(np.all(same)) and not bool(np.any(is_gap(times, period_s)))


def _concat(chunks: list[Chunk]) -> Chunk:
    if len(chunks) == 1:
        return chunks[0]
    return Chunk(
        chunks[0].first_row,
        np.concatenate([c.time_s for c in chunks]),
        np.concatenate([c.opening_mm for c in chunks]),
        np.concatenate([c.hold for c in chunks]),
        np.concatenate([c.flow_m3h for c in chunks]),
        {g: np.concatenate([c.levels_mm[g] for c in chunks]) for g in chunks[0].levels_mm},
        chunks[0].flow_before_m3h,
    )  # fmt: skip


def _tail(rows: Chunk, start: int) -> Chunk:
    """Rows from ``start`` on (copies, so the dropped rows are freed), with the last
    discharge logged before them, which their leading empty discharge cells hold."""
    return Chunk(rows.first_row + start, rows.time_s[start:].copy(),
                 rows.opening_mm[start:].copy(), rows.hold[start:].copy(),
                 rows.flow_m3h[start:].copy(),
                 {g: v[start:].copy() for g, v in rows.levels_mm.items()},
                 rows.last_flow_m3h(start))  # fmt: skip


def _record(history: History, rows: Chunk, period_s: float) -> Record:
    return chunk_record(history, rows, period_s, test="routine")


def _count_pairs(scan: _Scan, record: Record, first_row: int, upto: int) -> None:
    """Count the opening changes hidden in logging gaps between consecutive hold segments
    ``k``, ``k + 1`` for ``k + 1 < upto`` not counted yet."""
    holds = record.holds
    gap_rows = np.concatenate(([0], np.cumsum(is_gap(record.time_s, record.sample_period_s))))
    for k in range(min(upto, len(holds)) - 1):
        row = first_row + holds[k + 1].start
        if row <= scan.counted_row:
            continue
        scan.counted_row = row
        change = abs(holds[k + 1].opening_mm - holds[k].opening_mm) >= RESOLUTION_MM - 1e-9
        gapped = gap_rows[holds[k + 1].start] - gap_rows[holds[k].stop - 1] > 0
        scan.unobserved += int(change and gapped)


def _scan(scan: _Scan, record: Record, first_row: int, final: bool) -> int:
    """Decide the events that no later row can change; the row (of ``record``) from which
    the rows must be kept."""
    name = gauge_of(record, scan.gauge)
    holds = record.holds
    last = len(holds) - 1
    index = {h.start: k for k, h in enumerate(holds)}
    keep = holds[max(last - 1, 0)].start if holds else max(record.n_samples - 1, 0)
    for event in move_events(record, scan.crit.post_min_s):
        if not final and index[event[-1].after.start] > last - 2:
            keep = min(keep, event[0].before.start)
            break
        tally_event(record, event, name, scan.crit, scan.controller, scan.windows,
                    scan.rejected)  # fmt: skip
        scan.n_moves += len(event)
    _count_pairs(scan, record, first_row, last + 1 if final else last)
    return keep


@dataclass(frozen=True)
class ChunkedScan:
    """What one pass over a history found.

    Attributes
    ----------
    n_rows : int
        Rows of the whole history (every file of a folder).
    identification : RoutineIdentification | None
        The result; ``None`` without an informative window.
    no_window : str
        Why there is none (the one line :class:`~gatetwin.errors.NoWindowError` carries);
        empty with a result.
    """

    n_rows: int
    identification: RoutineIdentification | None
    no_window: str = ""

    def result(self) -> RoutineIdentification:
        """The identification, or :class:`~gatetwin.errors.NoWindowError` saying why none."""
        if self.identification is None:
            raise NoWindowError(self.no_window)
        return self.identification


def identify_routine_chunked(
    path: str | os.PathLike[str],
    gauge: str | None = None,
    criteria: WindowCriteria | None = None,
    *,
    chunk_rows: int = DEFAULT_CHUNK_ROWS,
) -> RoutineIdentification:
    """:func:`~gatetwin.identification.routine.identify_routine` of a history read a chunk at a
    time.

    Parameters
    ----------
    path : str or PathLike
        A Parquet history, or a folder of record files (one per day) taken in name order.
    gauge : str, optional
        Gauge to identify (default the history's only gauge).
    criteria : WindowCriteria, optional
        What makes a window informative.
    chunk_rows : int
        Rows read at a time from a Parquet file (a day file of a folder is read whole).

    Returns
    -------
    RoutineIdentification
        Equal to the whole-history result.

    Raises
    ------
    RecordError
        A chunk breaks the data-format contract (messages count samples from the start of
        the rows held, not file rows), or the history logs no discharge at all (named by
        the first rows held).
    IdentificationError
        As :func:`~gatetwin.identification.routine.identify_routine`.
    """
    return scan_routine_history(path, gauge, criteria, chunk_rows=chunk_rows).result()


def scan_routine_history(
    path: str | os.PathLike[str],
    gauge: str | None = None,
    criteria: WindowCriteria | None = None,
    *,
    chunk_rows: int = DEFAULT_CHUNK_ROWS,
) -> ChunkedScan:
    """:func:`identify_routine_chunked` with the history's row count, and a history without
    an informative window told apart as a result rather than raised.

    Raises
    ------
    RecordError, IdentificationError
        As :func:`identify_routine_chunked`, except :class:`~gatetwin.errors.NoWindowError`.
    """
    history = open_history(path)
    period_s = history_sample_period(history, chunk_rows)
    scan = _Scan(gauge, criteria or WindowCriteria())
    pending: list[Chunk] = []  # the rows held: the undecided rows, then the chunks since
    record: Record | None = None
    n_rows = 0
    for chunk in iter_chunks(history, chunk_rows):
        n_rows += chunk.n_rows
        _check_gauges(history.path, pending, chunk)
        if pending and _lengthens_last_hold(pending[-1], chunk, period_s):
            # the last hold only grows: nothing can be decided that was not already (a gate
            # held for days would otherwise copy and segment its whole hold at every chunk)
            pending.append(chunk)
            continue
        held = _concat([*pending, chunk])
        pending = [held]
        if held.n_rows < 2:
            continue
        record = _record(history, held, period_s)
        scan.controller = has_level_controller(record)
        pending = [_tail(held, _scan(scan, record, held.first_row, final=False))]
    held = _concat(pending) if pending else None
    if held is not None and held.n_rows >= 2:
        record = _record(history, held, period_s)
        _scan(scan, record, held.first_row, final=True)
    if record is None:
        raise IdentificationError(f"{history.path}: fewer than 2 samples; expected a history")
    name = gauge_of(record, gauge)
    if not scan.windows:
        why = no_window_message(history.path, scan.n_moves, scan.unobserved, scan.rejected)
        return ChunkedScan(n_rows, None, why)
    return ChunkedScan(n_rows, assemble(
        history.path,
        scan.n_moves,
        scan.unobserved,
        name,
        scan.windows,
        scan.rejected,
        scan.crit,
        scan.controller,
    ))  # fmt: skip
