"""Parquet records: the same columns, sidecar and checks as CSV, in a binary container.

A Parquet record holds the columns of ``docs/record_format.md`` with numeric types (any integer
or floating type) and ``state`` as text; null and NaN are missing values. Its rows are
counted from 1 in messages (there is no header line). Both the file and its decoded
columns (rows × kept columns × 8 bytes) must respect the byte limit of a CSV, so a small,
highly compressed file cannot expand without bound.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable, Sequence
from typing import Any, BinaryIO

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.checks import QUOTE_CHARS
from gatetwin.records.columns import TableColumns, Words, arrow_columns, check_header
from gatetwin.records.limits import ENV_MAX_BYTES

__all__ = ["PARQUET_SUFFIXES", "parquet_header", "read_parquet"]

#: File name endings read as Parquet.
PARQUET_SUFFIXES = (".parquet", ".pq")
#: Rows decoded at a time (a batch at a time keeps the decoded file out of memory).
_BATCH_ROWS = 65536


def read_parquet(
    name: str,
    handle: BinaryIO,
    max_bytes: int,
    *,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> TableColumns:
    """Read the kept columns of an open Parquet file.

    Raises
    ------
    RecordError
        For a file Arrow cannot read as Parquet, one whose data would exceed
        ``max_bytes`` uncompressed, a file without rows, or a column of the wrong type.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    data = handle.read()
    sha256 = hashlib.sha256(data).hexdigest()
    try:
        parquet = pq.ParquetFile(pa.BufferReader(data))
        header = check_header(name, parquet.schema_arrow.names)
        kept = [col for col in header if keep(col)]
        rows = parquet.metadata.num_rows
        _check_size(name, rows * max(len(kept), 1) * 8, max_bytes)
        batches = parquet.iter_batches(batch_size=_BATCH_ROWS, columns=kept)
        columns = _joined(name, batches, rows, keep, text_columns)
    except RecordError:
        raise
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise RecordError(
            f"{name}: not a readable Parquet file ({_short(exc)}); expected a Parquet "
            "record with the columns of the data format"
        ) from None
    if rows == 0 or not columns:
        raise RecordError(f"{name}: no data rows; expected one row per sample")
    return TableColumns(name, header, columns, sha256, first_line=1)


def _joined(
    name: str,
    batches: Iterable[Any],
    rows: int,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> dict[str, np.ndarray | Words]:
    """The kept columns of consecutive batches, each checked and copied out in turn."""
    import pyarrow as pa

    floats: dict[str, np.ndarray] = {}
    words: dict[str, list[Words]] = {}
    start = 0
    for batch in batches:
        part = arrow_columns(name, pa.Table.from_batches([batch]), keep=keep,
                             text_columns=text_columns, first_row=start + 1)  # fmt: skip
        for col, values in part.columns.items():
            if isinstance(values, Words):
                words.setdefault(col, []).append(values)
            else:
                floats.setdefault(col, np.empty(rows))[start : start + values.size] = values
        start += part.n_rows
    columns: dict[str, np.ndarray | Words] = dict(floats)
    columns.update({col: Words.concatenate(parts) for col, parts in words.items()})
    return columns


def parquet_header(handle: BinaryIO) -> tuple[str, ...]:
    """Column names of an open Parquet file; empty if it cannot be read."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        return tuple(pq.ParquetFile(handle).schema_arrow.names)
    except (pa.ArrowException, OSError, ValueError):
        return ()


def _check_size(name: str, decoded_bytes: int, max_bytes: int) -> None:
    """Refuse a file whose kept columns would decode to more than ``max_bytes``."""
    if decoded_bytes > max_bytes:
        raise RecordError(
            f"{name}: {decoded_bytes} bytes of data decoded (rows x columns x 8), more than "
            f"the limit of {max_bytes} bytes; raise it with --max-bytes or {ENV_MAX_BYTES} "
            "for a longer history"
        )


def _short(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 2 * QUOTE_CHARS else text[: 2 * QUOTE_CHARS] + "..."
