"""The diagnosing CSV parser: reads any file the fast reader balks at, or says why not.

:mod:`gatetwin.records.arrow_csv` parses well-formed files with Arrow; whatever it refuses or
the pre-scan flags (NUL bytes, invalid UTF-8, blank lines inside, lone carriage returns,
ragged rows, quoted newlines, cells outside the number grammar) comes here. This parser
accepts exactly what the data format allows and otherwise raises a one-line
:class:`~gatetwin.errors.RecordError` naming the file and the row (1-based file line,
header = row 1) or column: an empty, binary or non-UTF-8 file, a header without data, a
wrong separator, duplicated column names, rows of the wrong width, and cells that are not
finite numbers of the grammar ``[+-]digits[.digits][e[+-]digits]`` (ASCII digits, ``.``
decimal point, surrounding spaces allowed).

Rows are parsed in chunks; the parser is slower than Arrow but only sees unusual files.
"""

from __future__ import annotations

import codecs
import csv
import math
import re
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.checks import quote
from gatetwin.records.columns import TableColumns, Words, check_header

__all__ = ["parse_header", "parse_table"]

_CHUNK_ROWS = 65536
_FOREIGN_SEPARATORS = (";", "\t", "|")
#: One cell of a numeric column: empty, or a number of the format's grammar.
#: Written so that a cell matches in one way only: an ambiguous pattern backtracks
#: exponentially over a chunk of cells when one of them fails.
_NUMBER = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
_CELL = re.compile(rf"[ \t]*(?:{_NUMBER}[ \t]*)?")
_CELLS = re.compile(rf"(?:{_CELL.pattern}\n)*{_CELL.pattern}")


def parse_table(
    name: str,
    data: bytes,
    sha256: str,
    *,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> TableColumns:
    """Read the columns ``keep`` accepts from the bytes of a comma-separated UTF-8 file.

    Parameters
    ----------
    name : str
        The file, for messages.
    data : bytes
        Its contents.
    sha256 : str
        Hash of ``data`` (kept on the result).
    keep : callable
        Predicate on a column name; other columns are ignored (never parsed).
    text_columns : sequence of str
        Kept columns read as text; the others are read as numbers.

    Raises
    ------
    RecordError
        For anything that is not a well-formed CSV of finite numbers.
    """
    lines = _text_lines(name, data)
    header = parse_header(name, lines[0])
    if len(lines) < 2:
        raise RecordError(f"{name}: header only, no data rows; expected one row per sample")
    wanted = [(j, col) for j, col in enumerate(header) if keep(col)]
    floats: dict[str, list[np.ndarray]] = {col: [] for _, col in wanted}
    words: dict[str, list[Words]] = {col: [] for _, col in wanted}
    for first_line, cells in _column_chunks(name, lines, len(header)):
        for j, col in wanted:
            if col in text_columns:
                words[col].append(Words.from_cells(cells[j]))
            else:
                floats[col].append(_to_float(name, col, cells[j], first_line))
    columns: dict[str, np.ndarray | Words] = {
        col: Words.concatenate(words[col]) if col in text_columns
        else np.concatenate(floats[col])
        for _, col in wanted
    }  # fmt: skip
    return TableColumns(name, header, columns, sha256)


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


def parse_header(name: str, line: str) -> tuple[str, ...]:
    """The column names of header ``line``, refusing a foreign separator or a repeated name."""
    try:
        cells = next(csv.reader([line]), [])
    except csv.Error as exc:
        raise RecordError(f"{name}: row 1: header is not valid CSV ({exc})") from None
    header = tuple(cell.strip() for cell in cells)
    if not any(header):
        raise RecordError(f"{name}: row 1: empty header; expected the column names")
    if len(header) == 1:
        for sep in _FOREIGN_SEPARATORS:
            if sep in header[0]:
                raise RecordError(
                    f"{name}: row 1: header is one column split by {sep!r}; expected "
                    "comma-separated columns"
                )
    return check_header(name, header)


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
            _refuse_width(
                name, [line.split(",") if line else [] for line in chunk], width, first_line
            )
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
    try:
        for row in reader:
            if reader.line_num != len(rows) + 1:
                raise RecordError(
                    f"{name}: row {first_line + len(rows)}: a quoted field runs past the end "
                    "of the line; expected one row per line"
                )
            rows.append(row)
    except csv.Error as exc:
        raise RecordError(
            f"{name}: row {first_line + len(rows)}: not valid CSV ({exc}); expected "
            "comma-separated fields"
        ) from None
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
    if _CELLS.fullmatch("\n".join(cells)) is None:
        _refuse_cell(name, col, cells, first_line)
    stripped = [cell.strip() or "nan" for cell in cells]
    values = np.fromiter(map(float, stripped), np.float64, len(cells))
    for k in np.flatnonzero(np.isinf(values)):
        _refuse_not_finite(name, col, cells[k], first_line + int(k))
    return values


def _refuse_cell(name: str, col: str, cells: Sequence[str], first_line: int) -> None:
    """Name the first cell outside the number grammar."""
    for k, cell in enumerate(cells):
        if _CELL.fullmatch(cell) is None:
            stripped = cell.strip()
            try:
                value = float(stripped)
            except ValueError:
                value = 0.0
            if not math.isfinite(value):
                _refuse_not_finite(name, col, cell, first_line + k)
            raise RecordError(
                f"{name}: row {first_line + k}: column '{col}': {quote(stripped)} is not a "
                "number; expected ASCII digits with '.' as decimal point and an optional "
                "exponent"
            )


def _refuse_not_finite(name: str, col: str, cell: str, line: int) -> None:
    raise RecordError(
        f"{name}: row {line}: column '{col}': {quote(cell.strip())} is not a finite number; "
        "expected a number (empty cells are the only missing values)"
    )
