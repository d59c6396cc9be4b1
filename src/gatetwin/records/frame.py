"""pandas DataFrames as records, without making pandas a dependency.

A DataFrame goes through Arrow exactly as a Parquet file does, so it meets the same
column and value checks; pandas is imported only when a DataFrame is converted from a
record.
"""

from __future__ import annotations

from typing import Any

from gatetwin.errors import GatetwinError, RecordError
from gatetwin.records.columns import TableColumns, arrow_columns, is_record_column

__all__ = ["frame_columns", "import_pandas", "is_frame"]


def is_frame(value: Any) -> bool:
    """Whether ``value`` is a pandas DataFrame (without importing pandas)."""
    kind = type(value)
    return kind.__name__ == "DataFrame" and kind.__module__.split(".")[0] == "pandas"


def import_pandas(what: str) -> Any:
    try:
        import pandas
    except ImportError:
        raise GatetwinError(
            f"{what} needs pandas, which is not installed; expected 'pip install pandas'"
        ) from None
    return pandas


def frame_columns(frame: Any, path: str) -> TableColumns:
    """The record columns of a DataFrame, through Arrow like a Parquet file."""
    import pyarrow as pa

    if not is_frame(frame):
        raise RecordError(f"{path}: {type(frame).__name__}; expected a pandas DataFrame")
    names = [str(name) for name in frame.columns]
    kept = [k for k, name in enumerate(names) if is_record_column(name.strip())]
    try:
        table = pa.Table.from_pandas(frame.iloc[:, kept], preserve_index=False)
    except (pa.ArrowException, TypeError, ValueError) as exc:
        text = " ".join(str(exc).split())[:120]
        raise RecordError(
            f"{path}: a column cannot be read as numbers or text ({text}); "
            "expected the columns of the data format"
        ) from None
    table = table.rename_columns([names[k] for k in kept])
    columns = arrow_columns(path, table, keep=is_record_column, text_columns=("state",))
    return TableColumns(path, tuple(n.strip() for n in names), columns.columns, "", 1)
