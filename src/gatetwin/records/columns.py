"""Named columns as every record reader hands them over, and which columns a record needs.

:class:`TableColumns` is the common result of the CSV, Parquet and DataFrame readers:
float arrays (NaN for missing values) and dictionary-coded text (:class:`Words`).
:func:`arrow_columns` makes one from an Arrow table (Parquet files and DataFrames), and
the ``require_*`` functions refuse a header without the columns of the data format. This
module does not open files and does not check values.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.checks import QUOTE_CHARS, Origin, column
from gatetwin.records.units import HeaderUnits, parse_column, to_internal

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = [
    "REQUIRED",
    "TableColumns",
    "Words",
    "arrow_codes",
    "arrow_columns",
    "arrow_floats",
    "check_header",
    "frozen",
    "gauge_names",
    "gauge_of_column",
    "is_record_column",
    "is_static_column",
    "record_table",
    "require_record_columns",
    "require_static_columns",
    "static_table",
    "value_range",
]

#: The columns every time-series record has besides its level columns (internal names:
#: ``opening_<unit>`` and ``flow_<unit>`` in any unit of :mod:`gatetwin.records.units`).
REQUIRED = ("time_s", "opening_mm", "state", "flow_m3h")
#: What a missing-column message says the units may be.
_UNIT_HINT = "(openings and levels in mm, cm or m; flow in m3h, m3s or ls)"


@dataclass(frozen=True)
class Words:
    """A text column, dictionary coded: row ``i`` holds ``vocabulary[codes[i]]``.

    Coding keeps a million ``hold``/``open`` cells to one small integer each, and a
    hostile long cell to one copy.
    """

    vocabulary: tuple[str, ...]
    codes: np.ndarray

    @property
    def size(self) -> int:
        return int(self.codes.size)

    @classmethod
    def from_cells(cls, cells: Sequence[str]) -> Words:
        """Code stripped text cells."""
        index: dict[str, int] = {}
        codes = np.fromiter(
            (index.setdefault(cell.strip(), len(index)) for cell in cells), np.int64, len(cells)
        )
        return cls(tuple(index), codes)

    @classmethod
    def concatenate(cls, parts: Sequence[Words]) -> Words:
        """One column from consecutive chunks."""
        index: dict[str, int] = {}
        coded = []
        for part in parts:
            remap = np.array([index.setdefault(w, len(index)) for w in part.vocabulary] or [0])
            coded.append(remap[part.codes])
        codes = np.concatenate(coded) if coded else np.zeros(0, np.int64)
        return cls(tuple(index), codes)


@dataclass(frozen=True)
class TableColumns:
    """Columns read from a record file or table.

    Attributes
    ----------
    path : str
        The file, as given.
    header : tuple[str, ...]
        All column names, stripped, in file order.
    columns : dict[str, ndarray or Words]
        The kept columns: float64 (NaN for missing values) or, for text columns,
        :class:`Words`.
    sha256 : str
        Hash of the file's bytes ("" for in-memory tables).
    first_line : int
        File line of the first data row (2 for CSV); Parquet and DataFrame rows are
        counted from 1.
    units : HeaderUnits
        The unit columns as the file named them (empty until :meth:`in_internal_units`).
    """

    path: str
    header: tuple[str, ...]
    columns: dict[str, np.ndarray | Words]
    sha256: str
    first_line: int = 2
    units: HeaderUnits = field(default_factory=HeaderUnits)

    def in_internal_units(self) -> TableColumns:
        """The table with its unit columns renamed and scaled to mm and m³/h.

        Raises
        ------
        RecordError
            For two columns of one quantity or a level column in an unknown unit.
        """
        header, columns, units = to_internal(self.path, self.header, self.columns)
        return replace(self, header=header, columns=columns, units=units)

    def origin(self) -> Origin:
        """Where the columns came from, naming them as the file does."""
        return Origin(self.path, first_line=self.first_line, columns=self.units.names())

    @property
    def n_rows(self) -> int:
        return int(next(iter(self.columns.values())).size) if self.columns else 0

    def floats(self, name: str) -> np.ndarray:
        """A numeric column."""
        values = self.columns[name]
        if not isinstance(values, np.ndarray):
            raise TypeError(f"column '{name}' was read as text, not as numbers")
        return values

    def words(self, name: str) -> Words:
        """A text column."""
        values = self.columns[name]
        if not isinstance(values, Words):
            raise TypeError(f"column '{name}' was read as numbers, not as text")
        return values


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


def gauge_names(header: Sequence[str]) -> list[str]:
    """Gauge names of the level columns of ``header``, in order."""
    return [g for g in map(gauge_of_column, header) if g is not None]


def is_record_column(name: str) -> bool:
    """Whether a time-series record reader keeps column ``name`` (in any unit)."""
    if name in ("time_s", "state"):
        return True
    parsed = parse_column(name)
    return parsed is not None and parsed.known and parsed.quantity != "level_sd"


def is_static_column(name: str) -> bool:
    """Whether a rating-table reader keeps column ``name`` (in any unit)."""
    parsed = parse_column(name)
    return parsed is not None and parsed.known


def require_record_columns(
    path: str, header: Sequence[str], present: Sequence[str], listed: Sequence[str] = ()
) -> None:
    """Refuse a record header without the required and at least one level column.

    ``header`` and ``present`` are internal names; ``listed``, if given, is the header as
    the file has it, for the message.
    """
    for name in REQUIRED:
        if name not in present:
            raise RecordError(
                f"{path}: column '{name}': missing; expected columns time_s, "
                f"opening_mm, state, flow_m3h and level_<G>_mm {_UNIT_HINT} "
                f"(found {_listing(listed or header)})"
            )
    if not gauge_names(header):
        raise RecordError(
            f"{path}: column 'level_<G>_mm': missing; expected at least one level "
            f"column such as level_3F_mm or level_3F_m (found {_listing(listed or header)})"
        )


def require_static_columns(
    path: str, header: Sequence[str], present: Sequence[str], listed: Sequence[str] = ()
) -> None:
    """Refuse a rating-table header without flow, opening and a level column (arguments
    as :func:`require_record_columns`)."""
    for name in ("flow_m3h", "opening_mm"):
        if name not in present:
            raise RecordError(
                f"{path}: column '{name}': missing; expected a rating table with "
                f"columns flow_m3h, opening_mm and level_<G>_mm {_UNIT_HINT} "
                f"(found {_listing(listed or header)})"
            )
    if not gauge_names(header):
        raise RecordError(
            f"{path}: column 'level_<G>_mm': missing; expected at least one level "
            f"column such as level_3F_mm or level_3F_m (found {_listing(listed or header)})"
        )


def record_table(table: TableColumns) -> TableColumns:
    """``table`` in internal names and units, refused without a record's columns."""
    internal = table.in_internal_units()
    require_record_columns(table.path, internal.header, tuple(internal.columns), table.header)
    return internal


def static_table(table: TableColumns) -> TableColumns:
    """``table`` in internal names and units, refused without a rating table's columns."""
    internal = table.in_internal_units()
    require_static_columns(table.path, internal.header, tuple(internal.columns), table.header)
    return internal


def _listing(header: Sequence[str]) -> str:
    text = ", ".join(name[:QUOTE_CHARS] for name in header)
    return text if len(text) <= 120 else text[:117] + "..."


def check_header(path: str, header: Sequence[str]) -> tuple[str, ...]:
    """Strip column names and refuse an empty header or a name that appears twice."""
    names = tuple(str(name).strip() for name in header)
    if not any(names):
        raise RecordError(f"{path}: row 1: empty header; expected the column names")
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise RecordError(f"{path}: {column(name)}: appears twice in the header")
        seen.add(name)
    return names


def arrow_columns(
    path: str,
    table: pa.Table,
    *,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
    sha256: str = "",
    first_row: int = 1,
) -> TableColumns:
    """Columns of an Arrow table (Parquet file or DataFrame), typed as the CSV reader's.

    ``first_row`` is the row number messages give the table's first row.

    Numeric columns may be of any integer or floating type; null and NaN are missing
    values (a binary float has no text to tell them apart), infinities are refused.
    Text columns must be strings.

    Raises
    ------
    RecordError
        For a repeated column name, a numeric column of another type, an infinite value,
        or a text column that is not text.
    """
    header = check_header(path, table.column_names)
    columns: dict[str, np.ndarray | Words] = {}
    for j, name in enumerate(header):
        if not keep(name):
            continue
        data = table.column(j)
        if name in text_columns:
            columns[name] = _arrow_words(path, name, data)
        else:
            columns[name] = _arrow_floats(path, name, data, first_row)
    return TableColumns(path, header, columns, sha256, first_line=first_row)


def _arrow_words(path: str, name: str, data: pa.ChunkedArray) -> Words:
    import pyarrow as pa_

    kind = data.type
    if pa_.types.is_dictionary(kind):
        data = data.cast(kind.value_type)
        kind = data.type
    if not (pa_.types.is_string(kind) or pa_.types.is_large_string(kind)
            or pa_.types.is_null(kind)):  # fmt: skip
        raise RecordError(f"{path}: {column(name)}: values of type {kind}; expected text")
    if pa_.types.is_null(kind):
        return Words(("",), np.zeros(len(data), np.int64))
    data = data.cast(pa_.string())
    return Words.concatenate([arrow_codes(chunk) for chunk in data.chunks])


def _arrow_floats(path: str, name: str, data: pa.ChunkedArray, first_row: int) -> np.ndarray:
    import pyarrow as pa_

    kind = data.type
    if not (pa_.types.is_integer(kind) or pa_.types.is_floating(kind)
            or pa_.types.is_decimal(kind) or pa_.types.is_null(kind)):  # fmt: skip
        raise RecordError(f"{path}: {column(name)}: values of type {kind}; expected numbers")
    values = np.empty(len(data))
    start = 0
    for chunk in data.cast(pa_.float64()).chunks:
        arrow_floats(chunk, values[start : start + len(chunk)])
        start += len(chunk)
    bad = np.flatnonzero(np.isinf(values))
    if bad.size:
        i = int(bad[0])
        raise RecordError(
            f"{path}: row {i + first_row}: {column(name)}: {values[i]} is not a finite number; "
            "expected a number (null or NaN for missing values)"
        )
    return values


def frozen(values: np.ndarray) -> np.ndarray:
    """``values`` made read-only; freshly read arrays are frozen in place, others copied."""
    out = values if values.flags.owndata and values.base is None else np.array(values)
    out.flags.writeable = False
    return out


def arrow_floats(array: pa.Array, out: np.ndarray) -> int:
    """Copy a float64 Arrow array into ``out`` with NaN for nulls; returns the null count.

    Reads the array's buffers directly: Arrow's own conversion of an array with nulls
    imports pandas, which gatetwin does not depend on.
    """
    size = len(array)
    validity, data = array.buffers()[:2]
    stop = array.offset + size
    out[:] = np.frombuffer(data, dtype=np.float64, count=stop)[array.offset :]
    nulls = int(array.null_count)
    if nulls and validity is not None:
        bits = np.frombuffer(validity, dtype=np.uint8)
        valid = np.unpackbits(bits, count=stop, bitorder="little")[array.offset :]
        out[valid == 0] = np.nan
    return nulls


def arrow_codes(array: pa.Array) -> Words:
    """Dictionary-code a string Arrow array (nulls as empty words), vocabulary stripped."""
    import pyarrow.compute as pc

    coded = pc.dictionary_encode(pc.fill_null(array, "") if array.null_count else array)
    indices = coded.indices
    stop = indices.offset + len(indices)
    width = indices.type.bit_width // 8
    codes = np.frombuffer(indices.buffers()[1], dtype=f"<i{width}", count=stop)
    vocabulary = tuple(str(word).strip() for word in coded.dictionary.to_pylist())
    return Words(vocabulary, codes[indices.offset :].astype(np.int64))


def value_range(values: np.ndarray) -> dict[str, float] | None:
    """Mean, min and max of the finite values; None if there are none."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return None
    return {
        "mean": float(finite.mean()),
        "min": float(finite.min()),
        "max": float(finite.max()),
    }
