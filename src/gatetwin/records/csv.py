"""Fast CSV reading with Arrow, behind a pre-scan that keeps the data format's rules.

The file is read twice from one open descriptor. The pre-scan streams it in blocks: it
hashes the bytes, enforces the line-length limit (so a 50 MB line is refused before any
parser sees it) and flags what Arrow would read differently from the format (NUL bytes,
invalid UTF-8, quotes, blank lines inside, lone carriage returns). A clean file is then parsed by
Arrow's multi-threaded CSV reader into typed columns. Anything Arrow refuses or reads
loosely (ragged rows, quoted newlines, ``nan``/``inf`` words, a header without data) is
handed to :mod:`gatetwin.records.csvtext`, which accepts what the format allows and
otherwise names the row and column at fault, so both paths give the same answers.

This module reads; it does not check values against physics.
"""

from __future__ import annotations

import codecs
import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.columns import TableColumns, Words
from gatetwin.records.csvtext import parse_header, parse_table
from gatetwin.records.limits import ENV_MAX_LINE_BYTES

#: Bytes the pre-scan reads at a time.
_BLOCK_BYTES = 8 << 20
#: Bytes Arrow parses per block (and per thread).
_ARROW_BLOCK_BYTES = 4 << 20


@dataclass
class _Scan:
    """What the pre-scan learnt about a file."""

    digest: hashlib._Hash
    header: bytes = b""
    header_done: bool = False
    clean: bool = True
    first_blank: int = -1
    last_content: int = -1
    line_start: int = 0
    line_no: int = 1
    offset: int = 0
    pending_cr: bool = False


def read_csv(
    name: str,
    handle: BinaryIO,
    max_line_bytes: int,
    *,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> TableColumns:
    """Read the kept columns of an open CSV file.

    Parameters
    ----------
    name : str
        The file, for messages.
    handle : binary file
        Open at its start, seekable.
    max_line_bytes : int
        Longest line accepted, bytes.
    keep, text_columns
        As :func:`gatetwin.records.csvtext.parse_table`.

    Raises
    ------
    RecordError
        For a line over the limit or anything :mod:`~gatetwin.records.csvtext` refuses.
    """
    scan = _prescan(name, handle, max_line_bytes)
    sha256 = scan.digest.hexdigest()
    if scan.clean:
        header = parse_header(name, scan.header.decode("utf-8-sig").rstrip("\r"))
        handle.seek(0)
        table = _read_arrow(name, handle, header, sha256, keep, text_columns)
        if table is not None:
            return table
    handle.seek(0)
    data = handle.read()
    return parse_table(name, data, sha256, keep=keep, text_columns=text_columns)


def _prescan(name: str, handle: BinaryIO, max_line_bytes: int) -> _Scan:
    scan = _Scan(hashlib.sha256())
    decoder = codecs.getincrementaldecoder("utf-8")()
    while block := handle.read(_BLOCK_BYTES):
        scan.digest.update(block)
        if scan.clean and not _plain_text(block, decoder):
            scan.clean = False
        _scan_lines(name, scan, block, max_line_bytes)
        stripped = len(block.rstrip())
        if stripped:
            scan.last_content = scan.offset + stripped - 1
        scan.offset += len(block)
    if scan.offset - scan.line_start > max_line_bytes:
        _refuse_line(name, scan.line_no, scan.offset - scan.line_start, max_line_bytes)
    if scan.pending_cr or scan.last_content < 0:
        scan.clean = False
    if 0 <= scan.first_blank < scan.last_content:
        scan.clean = False
    return scan


def _plain_text(block: bytes, decoder: codecs.IncrementalDecoder) -> bool:
    """No NUL byte, no quote (a quoted newline would pass Arrow), and valid UTF-8 so far."""
    if b"\x00" in block or b'"' in block:
        return False
    if block.isascii() and not decoder.getstate()[0]:
        return True
    try:
        decoder.decode(block)
    except UnicodeDecodeError:
        return False
    return True


def _scan_lines(name: str, scan: _Scan, block: bytes, max_line_bytes: int) -> None:
    """Line lengths, blank lines and lone carriage returns of one block."""
    raw = np.frombuffer(block, dtype=np.uint8)
    newlines = np.flatnonzero(raw == 10)
    returns = np.flatnonzero(raw == 13)
    if scan.pending_cr and raw[0] != 10:
        scan.clean = False
    inner = returns[returns + 1 < raw.size]
    if np.any(raw[inner + 1] != 10):
        scan.clean = False
    scan.pending_cr = bool(returns.size and returns[-1] == raw.size - 1)
    ends = newlines + scan.offset
    starts = np.concatenate(([scan.line_start], ends[:-1] + 1))
    lengths = ends - starts
    too_long = np.flatnonzero(lengths > max_line_bytes)
    if too_long.size:
        k = int(too_long[0])
        _refuse_line(name, scan.line_no + k, int(lengths[k]), max_line_bytes)
    if not scan.header_done:
        _take_header(scan, block, newlines)
    if scan.first_blank < 0 and newlines.size:
        _find_blank(scan, raw, newlines, lengths)
    if newlines.size:
        scan.line_start = int(ends[-1]) + 1
        scan.line_no += int(newlines.size)


def _take_header(scan: _Scan, block: bytes, newlines: np.ndarray) -> None:
    if newlines.size:
        scan.header += block[: int(newlines[0])]
        scan.header_done = True
    else:
        scan.header += block


def _find_blank(scan: _Scan, raw: np.ndarray, newlines: np.ndarray, lengths: np.ndarray) -> None:
    """Remember where the first blank line (empty, or a lone ``\\r``) ends."""
    blank = lengths == 0
    ones = np.flatnonzero(lengths == 1)
    blank[ones] = raw[newlines[ones] - 1] == 13
    hits = np.flatnonzero(blank[1:] if scan.line_no == 1 else blank)
    if hits.size:
        k = int(hits[0]) + (1 if scan.line_no == 1 else 0)
        scan.first_blank = int(newlines[k]) + scan.offset


def _refuse_line(name: str, line_no: int, length: int, limit: int) -> None:
    raise RecordError(
        f"{name}: row {line_no}: line of {length} bytes, longer than the limit of {limit} "
        f"bytes; expected one sample per line (raise --max-line-bytes or "
        f"{ENV_MAX_LINE_BYTES} for very wide records)"
    )


def _read_arrow(
    name: str,
    handle: BinaryIO,
    header: tuple[str, ...],
    sha256: str,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> TableColumns | None:
    """The kept columns parsed by Arrow, or None if Arrow cannot read them as the format says."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    labels = [f"c{j}" for j in range(len(header))]
    kept = {labels[j]: col for j, col in enumerate(header) if keep(col)}
    types = {label: pa.string() if col in text_columns else pa.float64()
             for label, col in kept.items()}  # fmt: skip
    try:
        table = pacsv.read_csv(
            handle,
            read_options=pacsv.ReadOptions(
                column_names=labels, skip_rows=1, block_size=_ARROW_BLOCK_BYTES
            ),
            parse_options=pacsv.ParseOptions(newlines_in_values=False),
            convert_options=pacsv.ConvertOptions(
                column_types=types, include_columns=list(kept), null_values=[""],
                strings_can_be_null=False, quoted_strings_can_be_null=True,
            ),
        )  # fmt: skip
    except (pa.ArrowException, ValueError):
        return None
    if table.num_rows == 0:
        return None
    parts = {label: table.column(label) for label in kept}
    del table
    columns: dict[str, np.ndarray | Words] = {}
    for label, col in kept.items():
        data = parts.pop(label)
        if col in text_columns:
            columns[col] = _words(data)
            continue
        values = _floats(data)
        if values is None:
            return None
        columns[col] = values
    return TableColumns(name, header, columns, sha256)


def _floats(data: object) -> np.ndarray | None:
    """A float column with nulls as NaN; None if a cell was a ``nan``/``inf`` word."""
    values = np.asarray(data.to_numpy(), dtype=np.float64)  # type: ignore[attr-defined]
    if not values.flags.writeable:
        values = values.copy()
    finite = np.isfinite(values)
    if not finite.all() and np.count_nonzero(~finite) != data.null_count:  # type: ignore[attr-defined]
        return None
    return values


def _words(data: object) -> Words:
    import pyarrow.compute as pc

    coded = pc.dictionary_encode(data).combine_chunks()
    vocabulary = tuple(str(word).strip() for word in coded.dictionary.to_pylist())
    codes = coded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    return Words(vocabulary, codes)
