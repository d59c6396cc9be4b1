"""Open a record file and hand over its columns, whichever container it is in.

:func:`read_table` opens the file as :mod:`~gatetwin.records.limits` allows (a regular
file within the size limit) and reads it as Parquet (``.parquet``, ``.pq``) or CSV
(anything else). :func:`read_header` peeks at the column names without reading data.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path

from gatetwin.errors import RecordError
from gatetwin.records.arrow_csv import read_csv
from gatetwin.records.columns import TableColumns
from gatetwin.records.limits import ReadLimits, open_regular, resolve_limits
from gatetwin.records.parquet import PARQUET_SUFFIXES, parquet_header, read_parquet

__all__ = ["is_parquet", "read_header", "read_table"]


def is_parquet(path: str | Path) -> bool:
    """Whether ``path`` names a Parquet record (by its ending)."""
    return str(path).lower().endswith(PARQUET_SUFFIXES)


def read_table(
    path: str | Path,
    *,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
    limits: ReadLimits | None = None,
) -> TableColumns:
    """Read the columns ``keep`` accepts from a CSV or Parquet record file.

    Raises
    ------
    RecordError
        One line naming the file and the row or column, for a file that is not a regular
        file within ``limits`` or not a well-formed table of finite numbers.
    """
    limits = resolve_limits(limits)
    name = str(path)
    what = "a Parquet record" if is_parquet(name) else "a CSV record"
    with open_regular(name, limits.max_bytes, what) as handle:
        if is_parquet(name):
            return read_parquet(name, handle, limits.max_bytes, keep=keep,
                                text_columns=text_columns)  # fmt: skip
        return read_csv(name, handle, limits.max_line_bytes, keep=keep,
                        text_columns=text_columns)  # fmt: skip


def read_header(path: str | Path, limits: ReadLimits | None = None) -> tuple[str, ...]:
    """The stripped column names of a record file; empty if it cannot be read as one."""
    limits = resolve_limits(limits)
    try:
        with open_regular(path, limits.max_bytes) as handle:
            if is_parquet(path):
                return tuple(name.strip() for name in parquet_header(handle))
            first = handle.readline(min(limits.max_line_bytes + 2, 1 << 20))
    except RecordError:
        return ()
    try:
        text = first.decode("utf-8-sig")
        rows = list(csv.reader([text.rstrip("\r\n")]))
    except (UnicodeDecodeError, csv.Error):
        return ()
    return tuple(cell.strip() for cell in rows[0]) if rows else ()
