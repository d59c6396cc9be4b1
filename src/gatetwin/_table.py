"""Low-level CSV reading for records and rating tables.

Turns a file into named columns (float arrays with NaN for empty cells, or stripped text)
while refusing what no reader can make sense of: a missing, empty, binary or non-UTF-8
file, a header without data, a wrong separator, duplicated column names, rows of the wrong
width, and cells that are not finite numbers. Every refusal is a one-line
:class:`~gatetwin.errors.RecordError` naming the file and the row (1-based file line,
header = row 1) or column. Which columns a record needs is decided by the caller.

Rows are parsed in chunks so that a million-row record stays within a few seconds and a
modest amount of memory.
"""

from __future__ import annotations

import codecs
import csv
import hashlib
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gatetwin.errors import RecordError

_CHUNK_ROWS = 65536
_FOREIGN_SEPARATORS = (";", "\t", "|")


@dataclass(frozen=True)
class TableColumns:
    """Columns read from a CSV file.

    Attributes
    ----------
    path : str
        The file, as given.
    header : tuple[str, ...]
        All column names, stripped, in file order.
    columns : dict[str, ndarray]
        The kept columns: float64 (NaN for empty cells) or, for text columns, stripped
        strings.
    sha256 : str
        Hash of the file's bytes.
    """

    path: str
    header: tuple[str, ...]
    columns: dict[str, np.ndarray]
    sha256: str

    @property
    def n_rows(self) -> int:
        return int(next(iter(self.columns.values())).size) if self.columns else 0


def read_table(
    path: str | Path, *, keep: Callable[[str], bool], text_columns: Sequence[str]
) -> TableColumns:
    """Read the columns ``keep`` accepts from a comma-separated UTF-8 file.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    keep : callable
        Predicate on a column name; other columns are ignored (never parsed).
    text_columns : sequence of str
        Kept columns read as text; the others are read as numbers.

    Raises
    ------
    RecordError
        For anything that is not a well-formed CSV of finite numbers.
    """
    name = str(path)
    data = _read_bytes(name)
    lines = _text_lines(name, data)
    header = _parse_header(name, lines[0])
    if len(lines) < 2:
        raise RecordError(f"{name}: header only, no data rows; expected one row per sample")
    wanted = [(j, col) for j, col in enumerate(header) if keep(col)]
    parts: dict[str, list[np.ndarray]] = {col: [] for _, col in wanted}
    for first_line, cells in _column_chunks(name, lines, len(header)):
        for j, col in wanted:
            convert = _to_text if col in text_columns else _to_float
            parts[col].append(convert(name, col, cells[j], first_line))
    columns = {col: np.concatenate(chunks) for col, chunks in parts.items()}
    return TableColumns(name, header, columns, hashlib.sha256(data).hexdigest())


def read_header(path: str | Path) -> tuple[str, ...]:
    """The stripped column names of a CSV file; empty if it cannot be read as text."""
    try:
        with open(path, "rb") as handle:
            first = handle.readline(1 << 16)
        text = first.decode("utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return ()
    rows = list(csv.reader([text.rstrip("\r\n")]))
    return tuple(cell.strip() for cell in rows[0]) if rows else ()


def _read_bytes(name: str) -> bytes:
    path = Path(name)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise RecordError(f"{name}: no such file; expected a CSV record") from None
    except IsADirectoryError:
        raise RecordError(f"{name}: is a directory; expected a CSV file") from None
    except OSError as exc:
        raise RecordError(f"{name}: cannot be read ({exc.strerror})") from None


def _text_lines(name: str, data: bytes) -> list[str]:
    """Decode strictly as UTF-8 and split into lines, dropping trailing blank lines."""
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8) :]
    if not data.strip():
        raise RecordError(f"{name}: empty file; expected a header row and data rows")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise RecordError(
            f"{name}: row {_line_of(data, nul)}: NUL byte (binary data); expected UTF-8 text"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RecordError(
            f"{name}: row {_line_of(data, exc.start)}: byte 0x{data[exc.start]:02x} is not "
            "UTF-8 (binary data?); expected UTF-8 text"
        ) from None
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def _line_of(data: bytes, offset: int) -> int:
    """1-based line number of byte ``offset``."""
    return data.count(b"\n", 0, offset) + 1


def _parse_header(name: str, line: str) -> tuple[str, ...]:
    header = tuple(cell.strip() for cell in next(csv.reader([line]), []))
    if not any(header):
        raise RecordError(f"{name}: row 1: empty header; expected the column names")
    if len(header) == 1:
        for sep in _FOREIGN_SEPARATORS:
            if sep in header[0]:
                raise RecordError(
                    f"{name}: row 1: header is one column split by {sep!r}; expected "
                    "comma-separated columns"
                )
    seen: set[str] = set()
    for col in header:
        if col in seen:
            raise RecordError(f"{name}: column '{col}': appears twice in the header")
        seen.add(col)
    return header


def _column_chunks(
    name: str, lines: list[str], width: int
) -> Iterable[tuple[int, list[Sequence[str]]]]:
    """Yield ``(file line of the chunk's first row, cells per column)`` for the data rows."""
    for offset in range(1, len(lines), _CHUNK_ROWS):
        chunk = lines[offset : offset + _CHUNK_ROWS]
        first_line = offset + 1
        blob = "\n".join(chunk)
        if '"' in blob:
            yield first_line, _quoted_columns(name, chunk, width, first_line)
            continue
        if not _all_widths_are(blob, width):
            _refuse_width(name, [line.split(",") if line else [] for line in chunk], width,
                          first_line)
        cells = blob.replace("\n", ",").split(",")
        yield first_line, [cells[j::width] for j in range(width)]


def _all_widths_are(blob: str, width: int) -> bool:
    """Whether every line of ``blob`` (no quotes) has ``width`` comma-separated fields."""
    raw = np.frombuffer(blob.encode("utf-8"), dtype=np.uint8)
    line_ends = np.concatenate((np.flatnonzero(raw == ord("\n")), [raw.size]))
    commas_before_end = np.searchsorted(np.flatnonzero(raw == ord(",")), line_ends)
    per_line = np.diff(commas_before_end, prepend=0)
    return bool(np.all(per_line == width - 1))


def _quoted_columns(
    name: str, chunk: list[str], width: int, first_line: int
) -> list[Sequence[str]]:
    """Columns of a chunk with quoted fields, parsed by the csv module."""
    reader = csv.reader(chunk)
    rows = []
    for row in reader:
        if reader.line_num != len(rows) + 1:
            raise RecordError(
                f"{name}: row {first_line + len(rows)}: a quoted field runs past the end of "
                "the line; expected one row per line"
            )
        rows.append(row)
    if any(len(row) != width for row in rows):
        _refuse_width(name, rows, width, first_line)
    return list(zip(*rows, strict=True))


def _refuse_width(name: str, rows: list[list[str]], width: int, first_line: int) -> None:
    for k, row in enumerate(rows):
        if len(row) != width:
            raise RecordError(
                f"{name}: row {first_line + k}: {_describe_fields(row)}; expected {width} "
                "comma-separated fields as in the header"
            )


def _describe_fields(row: list[str]) -> str:
    if not row:
        return "empty line"
    if len(row) > 1:
        return f"{len(row)} fields"
    foreign = [sep for sep in _FOREIGN_SEPARATORS if sep in row[0]]
    return f"1 field (separated by {foreign[0]!r}?)" if foreign else "1 field"


def _to_float(name: str, col: str, cells: Sequence[str], first_line: int) -> np.ndarray:
    original = cells
    try:
        if "" in cells:
            cells = [cell or "nan" for cell in cells]
        values = np.fromiter(map(float, cells), np.float64, len(cells))
    except ValueError:
        values = _to_float_slowly(name, col, original, first_line)
    for k in np.flatnonzero(~np.isfinite(values)):
        if original[k].strip():
            raise RecordError(
                f"{name}: row {first_line + k}: column '{col}': {original[k].strip()!r} is not "
                "a finite number; expected a number (empty cells are the only missing values)"
            )
    return values


def _to_float_slowly(
    name: str, col: str, cells: Sequence[str], first_line: int
) -> np.ndarray:
    """Cell-by-cell conversion that names the first cell that is not a number."""
    values = np.empty(len(cells))
    for k, cell in enumerate(cells):
        stripped = cell.strip()
        try:
            values[k] = float(stripped) if stripped else math.nan
        except ValueError:
            raise RecordError(
                f"{name}: row {first_line + k}: column '{col}': {stripped!r} is not a "
                "number; expected a number with '.' as decimal point"
            ) from None
    return values


def _to_text(name: str, col: str, cells: Sequence[str], first_line: int) -> np.ndarray:
    del name, col, first_line  # text cells cannot be malformed here
    return np.char.strip(np.array(cells, dtype=str))
