"""A long history read a chunk of rows at a time, never whole.

A *history* is one Parquet record (read ``rows`` at a time with ``iter_batches``) or a
folder of record files, one per day or any other span, taken in file-name order, each read
whole in turn (CSV or Parquet). The sidecar is the record's own (``NAME.json``), for a
folder ``FOLDER.json`` next to it, else that of the folder's first file. Each chunk's
columns pass the reader's type checks; the values are checked when rows become a record
(:func:`chunk_record`, which holds empty discharge cells from the rows before them, as
:func:`~gatetwin.records.read_record` does for the history read whole).

This module reads and builds records of rows; it identifies nothing.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records import checks, segments
from gatetwin.records.checks import Origin
from gatetwin.records.columns import (
    TableColumns,
    arrow_columns,
    gauge_names,
    is_record_column,
    record_table,
)
from gatetwin.records.limits import ReadLimits
from gatetwin.records.parquet import PARQUET_SUFFIXES
from gatetwin.records.record import Record, record_from_arrays
from gatetwin.records.sidecar import Sidecar, read_sidecar
from gatetwin.records.table import read_table

__all__ = [
    "HISTORY_SUFFIXES",
    "Chunk",
    "History",
    "chunk_record",
    "history_sample_period",
    "iter_chunks",
    "open_history",
]

#: File name endings of the record files a history folder may hold.
HISTORY_SUFFIXES = (".csv", *PARQUET_SUFFIXES)


@dataclass(frozen=True)
class Chunk:
    """Consecutive rows of a history: raw columns, ``hold`` from ``state``.

    ``opening_mm`` and ``flow_m3h`` are as logged (empty cells are still NaN);
    ``first_row`` is the global row number (from 0) of the chunk's first row;
    ``flow_before_m3h`` is the last discharge logged in the rows before it, m³/h (NaN:
    none), which its empty discharge cells before its first logged one hold. Columns are
    converted to mm and m³/h from the units their names carry, file by file.
    """

    first_row: int
    time_s: np.ndarray
    opening_mm: np.ndarray
    hold: np.ndarray
    flow_m3h: np.ndarray
    levels_mm: dict[str, np.ndarray]
    flow_before_m3h: float = np.nan

    @property
    def n_rows(self) -> int:
        return int(self.time_s.size)

    def last_flow_m3h(self, stop: int) -> float:
        """The last discharge logged before the chunk's row ``stop`` (from 0), in the chunk
        or before it, m³/h; NaN if none."""
        logged = np.flatnonzero(~np.isnan(self.flow_m3h[:stop]))
        return float(self.flow_m3h[logged[-1]]) if logged.size else self.flow_before_m3h


@dataclass(frozen=True)
class History:
    """Where a history's rows come from: its files, in order, and its sidecar."""

    path: str
    files: tuple[Path, ...]
    sidecar: Sidecar

    @property
    def is_folder(self) -> bool:
        return Path(self.path).is_dir()


def open_history(path: str | os.PathLike[str]) -> History:
    """The history at ``path``: one Parquet file, or a folder of record files.

    Raises
    ------
    RecordError
        No such file or folder, a single file that is not Parquet, or a folder without
        record files.
    """
    where = Path(path)
    if where.is_dir():
        files = tuple(sorted(p for p in where.iterdir()
                             if p.is_file() and p.suffix.lower() in HISTORY_SUFFIXES))  # fmt: skip
        if not files:
            raise RecordError(f"{path}: no record files (.csv, .parquet, .pq) in the folder; "
                              "expected one file per day of the history")  # fmt: skip
        own = where.with_suffix(".json") if where.name else None
        side = read_sidecar(where) if own is not None and own.is_file() else read_sidecar(files[0])
        return History(str(path), files, side)
    if not where.is_file():
        raise RecordError(f"{path}: no such file or folder")
    if where.suffix.lower() not in PARQUET_SUFFIXES:
        raise RecordError(f"{path}: a history read in chunks is a Parquet file (.parquet, "
                          ".pq) or a folder of record files")  # fmt: skip
    return History(str(path), (where,), read_sidecar(where))


def _chunk(origin: Origin, table: TableColumns, first_row: int) -> Chunk:
    state = table.words("state")
    return Chunk(
        first_row=first_row,
        time_s=table.floats("time_s"),
        opening_mm=table.floats("opening_mm"),
        hold=checks.hold_from_codes(origin, state.vocabulary, state.codes),
        flow_m3h=table.floats("flow_m3h"),
        levels_mm={g: table.floats(f"level_{g}_mm") for g in gauge_names(table.header)},
    )


def _parquet_chunks(path: Path, rows: int, first_row: int) -> Iterator[Chunk]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    name = str(path)
    try:
        parquet = pq.ParquetFile(path)
        header = tuple(parquet.schema_arrow.names)
        full = tuple(c.strip() for c in header)
        kept = [c for c in header if is_record_column(c.strip())]
        batches = parquet.iter_batches(batch_size=rows, columns=kept)
        for batch in batches:
            table = arrow_columns(name, pa.Table.from_batches([batch]), keep=is_record_column,
                                  text_columns=("state",), first_row=first_row + 1)  # fmt: skip
            table = record_table(replace(table, header=full))  # units named by every column
            yield _chunk(Origin(name, first_line=first_row + 1), table, first_row)
            first_row += table.n_rows
    except RecordError:
        raise
    except (pa.ArrowException, OSError, ValueError) as exc:
        text = " ".join(str(exc).split())[:160]
        raise RecordError(f"{name}: not a readable Parquet file ({text}); expected a Parquet "
                          "record with the columns of the data format") from None  # fmt: skip


def iter_chunks(history: History, rows: int,
                limits: ReadLimits | None = None) -> Iterator[Chunk]:  # fmt: skip
    """The history's rows, ``rows`` at a time from a Parquet file, a file at a time from a
    folder (a day file is read whole), each with the last discharge logged before it (for
    the rows before the history's first logged discharge, that one, as the history read
    whole holds them)."""
    if not rows >= 1:
        raise RecordError(f"{history.path}: chunk of {rows!r} rows; expected at least 1")
    before_m3h = _first_flow_m3h(history, rows, limits)
    for chunk in _file_chunks(history, rows, limits):
        chunk = replace(chunk, flow_before_m3h=before_m3h)
        yield chunk
        before_m3h = chunk.last_flow_m3h(chunk.n_rows)


def _first_flow_m3h(history: History, rows: int, limits: ReadLimits | None) -> float:
    """The history's first logged discharge, m³/h (NaN: none): its chunks read until one logs
    a discharge, the first one in a history whose meter logs from the start."""
    for chunk in _file_chunks(history, rows, limits):
        logged = chunk.flow_m3h[~np.isnan(chunk.flow_m3h)]
        if logged.size:
            return float(logged[0])
    return np.nan


def _file_chunks(history: History, rows: int, limits: ReadLimits | None) -> Iterator[Chunk]:
    first_row = 0
    for path in history.files:
        if path.suffix.lower() in PARQUET_SUFFIXES:
            for chunk in _parquet_chunks(path, rows, first_row):
                first_row += chunk.n_rows
                yield chunk
            continue
        table = read_table(path, keep=is_record_column, text_columns=("state",), limits=limits)
        table = record_table(table)
        chunk = _chunk(Origin(table.path, first_line=table.first_line), table, first_row)
        first_row += chunk.n_rows
        yield chunk


def chunk_record(history: History, rows: Chunk, sample_period_s: float,
                 test: str | None = None) -> Record:  # fmt: skip
    """The record of consecutive rows of ``history``, checked and segmented as
    :func:`~gatetwin.records.record_from_arrays` checks arrays (messages name samples from
    ``rows``' first), with its discharge held as the history read whole holds it: empty cells
    before the rows' first logged discharge hold ``rows.flow_before_m3h``.

    Parameters
    ----------
    history : History
        Where the rows come from: its path labels the record and its sidecar's contents are
        kept on it.
    rows : Chunk
        The rows.
    sample_period_s : float
        The history's nominal sample period, s.
    test : {"step", "prbs", "free", "routine"}, optional
        Test type; else the sidecar's, else detected.

    Raises
    ------
    RecordError
        As :func:`~gatetwin.records.record_from_arrays`; rows that log no discharge and carry
        none (a history that logs none at all) are refused naming the history's rows.
    """
    if np.isnan(rows.flow_before_m3h) and np.isnan(rows.flow_m3h).all():
        raise RecordError(f"{history.path}: rows {rows.first_row + 1}-"
                          f"{rows.first_row + rows.n_rows} of the history: no discharge "
                          "logged in these rows or before them; expected m³/h")  # fmt: skip
    return record_from_arrays(rows.time_s, rows.opening_mm, rows.hold, rows.flow_m3h,
                              rows.levels_mm, test=test, sample_period_s=sample_period_s,
                              metadata=history.sidecar.metadata, path=history.path,
                              flow_before_m3h=rows.flow_before_m3h)  # fmt: skip


def history_sample_period(history: History, rows: int) -> float:
    """The nominal sample period of the whole history, as :func:`read_record` finds it for
    one file (the sidecar's ``sample_period_s``, checked, else the median time step), from
    the time column alone, a chunk at a time.

    The median is exact: the time steps are counted by value (a logger has few distinct
    steps), so memory grows with the distinct steps, not with the rows.
    """
    counts: dict[float, int] = {}
    last = None
    for chunk in iter_chunks(history, rows):
        t = chunk.time_s if last is None else np.concatenate(([last], chunk.time_s))
        values, n = np.unique(np.diff(t), return_counts=True)
        for v, c in zip(values.tolist(), n.tolist(), strict=True):
            counts[v] = counts.get(v, 0) + c
        if chunk.n_rows:
            last = float(chunk.time_s[-1])
    total = sum(counts.values())
    if total < 1:
        raise RecordError(f"{history.path}: fewer than 2 samples; expected at least 2")
    ordered = sorted(counts.items())
    low, high = _ranked(ordered, (total - 1) // 2), _ranked(ordered, total // 2)
    median_s = float(np.mean([low, high]))
    given = history.sidecar.sample_period_s
    limits = history.sidecar.bounds.sample_period_s
    if given is None:
        checks.check_sample_period(history.path, median_s, "the median time step", limits)
        return median_s
    checks.check_sample_period(history.path, given, "sidecar field 'sample_period_s'", limits)
    segments.check_median_step(str(history.path), given, median_s)
    return given


def _ranked(ordered: list[tuple[float, int]], rank: int) -> float:
    """The value at 0-based ``rank`` in the sorted multiset ``ordered`` (value, count)."""
    seen = 0
    for value, count in ordered:
        seen += count
        if rank < seen:
            return value
    raise IndexError(rank)
