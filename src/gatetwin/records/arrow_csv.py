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
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, BinaryIO

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.columns import TableColumns, Words, arrow_codes, arrow_floats
from gatetwin.records.csvtext import parse_header, parse_table
from gatetwin.records.limits import ENV_MAX_LINE_BYTES

__all__ = ["read_csv"]

#: Bytes the pre-scan reads at a time (alone, and while Arrow parses).
_BLOCK_BYTES = 8 << 20
_SMALL_BLOCK = 2 << 20
#: Bytes Arrow parses per block (small blocks keep the transient memory small).
_ARROW_BLOCK_BYTES = 256 << 10


@dataclass
class _Scan:
    """What the pre-scan learnt about a file (offsets in bytes from its start)."""

    digest: Any
    header: bytes = b""
    header_done: bool = False
    clean: bool = True
    first_blank: int = -1
    last_content: int = -1
    rows_before_last: int = 0
    line_start: int = 0
    newlines: int = 0
    offset: int = 0
    pending_cr: bool = False
    sha256: str = ""

    @property
    def n_rows(self) -> int:
        """Data rows of a clean file (line breaks before its last content)."""
        return self.rows_before_last


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
    header = _plain_header(handle, max_line_bytes)
    if header is not None and hasattr(os, "pread"):
        table = _read_concurrently(name, handle, header, max_line_bytes, keep, text_columns)
        if table is not None:
            return table
    scan = _prescan(name, handle, max_line_bytes)
    if scan.clean:
        header = parse_header(name, scan.header.decode("utf-8-sig").rstrip("\r"))
        handle.seek(0)
        table = _read_arrow(name, handle, scan.n_rows, header, keep, text_columns, scan.sha256)
        if table is not None and table.n_rows == scan.n_rows:
            return table
    handle.seek(0)
    data = handle.read()
    return parse_table(name, data, scan.sha256, keep=keep, text_columns=text_columns)


def _plain_header(handle: BinaryIO, max_line_bytes: int) -> tuple[str, ...] | None:
    """The header if it is plain ASCII within the line limit; else None (no refusal here)."""
    first = handle.readline(max_line_bytes + 2)
    handle.seek(0)
    if not first.endswith(b"\n") or not first.isascii() or b'"' in first:
        return None
    try:
        return parse_header("", first.decode("ascii").rstrip("\r\n"))
    except RecordError:
        return None


class _Positional:
    """A second reader of an open file, at its own position (``os.pread``)."""

    def __init__(self, handle: BinaryIO) -> None:
        self._fd = handle.fileno()
        self._offset = 0

    def read(self, size: int) -> bytes:
        data = os.pread(self._fd, size, self._offset)
        self._offset += len(data)
        return data


def _read_concurrently(
    name: str,
    handle: BinaryIO,
    header: tuple[str, ...],
    max_line_bytes: int,
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
) -> TableColumns | None:
    """Pre-scan on a second thread while Arrow parses; the Arrow result stands if the scan
    finds the file clean and counts the same rows, else None (the careful path decides).

    Raises
    ------
    RecordError
        For a line over the limit (from the scan).
    """
    size = os.fstat(handle.fileno()).st_size
    most_rows = size // max(len(header), 1) + 1
    with ThreadPoolExecutor(max_workers=1) as scanner:
        job = scanner.submit(_prescan, name, _Positional(handle), max_line_bytes, _SMALL_BLOCK)
        try:
            table = _read_arrow(name, handle, most_rows, header, keep, text_columns, "")
        finally:
            scan = job.result()
    if not scan.clean or table is None or table.n_rows != scan.n_rows:
        handle.seek(0)
        return None
    return TableColumns(name, header, table.columns, scan.sha256)


def _prescan(
    name: str, handle: BinaryIO | _Positional, max_line_bytes: int, block_bytes: int = 0
) -> _Scan:
    scan = _Scan(hashlib.sha256())
    with ThreadPoolExecutor(max_workers=1) as hasher:  # hashing releases the GIL
        hashed = _scan_blocks(
            name, handle, max_line_bytes, scan, hasher, block_bytes or _BLOCK_BYTES
        )
        for job in hashed:
            job.result()
    if scan.offset - scan.line_start > max_line_bytes:
        _refuse_line(name, scan, b"", scan.line_start, scan.offset - scan.line_start,
                     max_line_bytes)  # fmt: skip
    if scan.pending_cr or scan.last_content < 0:
        scan.clean = False
    if 0 <= scan.first_blank < scan.last_content:
        scan.clean = False
    scan.sha256 = scan.digest.hexdigest()
    return scan


def _scan_blocks(
    name: str,
    handle: BinaryIO | _Positional,
    max_line_bytes: int,
    scan: _Scan,
    hasher: ThreadPoolExecutor,
    block_bytes: int,
) -> list[Future[None]]:
    """Scan the file block by block while ``hasher`` hashes the same blocks in order."""
    hashed = []
    decoder = codecs.getincrementaldecoder("utf-8")()
    tail = b""
    while block := handle.read(block_bytes):
        hashed.append(hasher.submit(scan.digest.update, block))
        if scan.clean and not _plain_text(block, decoder):
            scan.clean = False
        raw = np.frombuffer(block, dtype=np.uint8)
        newline = raw == 10
        has_cr = b"\r" in block
        ends = newline | (raw == 13) if has_cr else newline
        _check_line_lengths(name, scan, block, ends, max_line_bytes)
        _scan_breaks(scan, tail, block, newline, has_cr)
        _last_content(scan, block, newline)
        scan.newlines += int(np.count_nonzero(newline))
        scan.offset += len(block)
        tail = block[-2:]
    return hashed


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


def _check_line_lengths(name: str, scan: _Scan, block: bytes, ends: np.ndarray, limit: int) -> None:
    """Refuse a line longer than ``limit`` bytes (``ends`` marks line ends in ``block``)."""
    raw = ends
    if not scan.header_done:
        stop = block.find(b"\n")
        scan.header += block if stop < 0 else block[:stop]
        scan.header_done = stop >= 0
    chunk = max((limit + 1) // 2, 1)
    whole = raw.size // chunk * chunk
    if whole and ends[:whole].reshape(-1, chunk).any(axis=1).all():
        if _line_before(scan, ends) <= limit:
            scan.line_start = scan.offset + int(raw.size - 1 - np.argmax(ends[::-1])) + 1
            return
    positions = np.flatnonzero(ends) + scan.offset
    starts = np.concatenate(([scan.line_start], positions + 1))
    stops = np.concatenate((positions, [scan.offset + raw.size]))
    too_long = np.flatnonzero(stops[:-1] - starts[:-1] > limit)
    if too_long.size:
        k = int(too_long[0])
        _refuse_line(name, scan, block, int(starts[k]), int(stops[k] - starts[k]), limit)
    scan.line_start = int(starts[-1])
    if int(stops[-1] - starts[-1]) > limit:
        _refuse_line(name, scan, block, int(starts[-1]), int(stops[-1] - starts[-1]), limit)


def _line_before(scan: _Scan, ends: np.ndarray) -> int:
    """Length of the line running into this block up to its first line end."""
    return scan.offset + int(np.argmax(ends)) - scan.line_start


def _scan_breaks(scan: _Scan, tail: bytes, block: bytes, newline: np.ndarray, has_cr: bool) -> None:
    """Blank lines (inside is not clean) and lone carriage returns (not clean)."""
    blank = newline[1:] & newline[:-1]
    if has_cr:
        blank[1:] |= newline[2:] & (np.frombuffer(block, np.uint8)[1:-1] == 13) & newline[:-2]
    seam = tail + block[:2]
    found = int(np.argmax(blank)) if blank.any() else -1
    for pattern in (b"\n\n", b"\n\r\n"):
        at_seam = seam.find(pattern)
        if 0 <= at_seam < len(tail):
            found = at_seam - len(tail)
    if found != -1 and (scan.first_blank < 0 or scan.offset + found < scan.first_blank):
        scan.first_blank = scan.offset + found
    if not has_cr:
        if scan.pending_cr and not block.startswith(b"\n"):
            scan.clean = False
        scan.pending_cr = False
        return
    if scan.pending_cr and not block.startswith(b"\n"):
        scan.clean = False
    scan.pending_cr = block.endswith(b"\r")
    returns = block.count(b"\r") - (1 if scan.pending_cr else 0)
    if returns > block.count(b"\r\n"):
        scan.clean = False


def _last_content(scan: _Scan, block: bytes, newline: np.ndarray) -> None:
    """Where the last non-blank byte is, and how many line breaks precede it."""
    tail = block[-4096:].rstrip()
    if tail:
        stop = len(block) - 4096 + len(tail) if len(block) > 4096 else len(tail)
    else:
        stop = len(block.rstrip())
    if stop:
        scan.last_content = scan.offset + stop - 1
        scan.rows_before_last = scan.newlines + int(np.count_nonzero(newline[:stop]))


def _refuse_line(name: str, scan: _Scan, block: bytes, start: int, length: int,
                 limit: int) -> None:  # fmt: skip
    inside = max(start - scan.offset, 0)
    row = scan.newlines + block.count(b"\n", 0, inside) + 1
    raise RecordError(
        f"{name}: row {row}: line of {length} bytes or more, longer than the limit of "
        f"{limit} bytes; expected one sample per line (raise --max-line-bytes or "
        f"{ENV_MAX_LINE_BYTES} for very wide records)"
    )


def _read_arrow(
    name: str,
    handle: BinaryIO,
    most_rows: int,
    header: tuple[str, ...],
    keep: Callable[[str], bool],
    text_columns: Sequence[str],
    sha256: str,
) -> TableColumns | None:
    """The kept columns parsed by Arrow, or None if Arrow cannot read them as the format says.

    Arrow streams the file in small blocks (parsing ahead on a second thread, into memory
    the system allocator takes back); each block's columns are copied into arrays sized
    for ``most_rows`` (pages never written cost no memory) and trimmed in place at the end,
    so the peak is the result plus a few blocks.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    labels = [f"c{j}" for j in range(len(header))]
    kept = {labels[j]: col for j, col in enumerate(header) if keep(col)}
    types = {label: pa.string() if col in text_columns else pa.float64()
             for label, col in kept.items()}  # fmt: skip
    rows = most_rows
    floats = {label: np.empty(rows) for label, col in kept.items() if col not in text_columns}
    words: dict[str, list[Words]] = {label: [] for label in kept if label not in floats}
    nulls = dict.fromkeys(floats, 0)
    done = 0
    try:
        reader = pacsv.open_csv(
            handle,
            read_options=pacsv.ReadOptions(
                column_names=labels, skip_rows=1, block_size=_ARROW_BLOCK_BYTES
            ),
            parse_options=pacsv.ParseOptions(newlines_in_values=False),
            convert_options=pacsv.ConvertOptions(
                column_types=types, include_columns=list(kept), null_values=[""],
                strings_can_be_null=False, quoted_strings_can_be_null=True,
            ),
            memory_pool=pa.system_memory_pool(),
        )  # fmt: skip
        for batch in reader:
            size = batch.num_rows
            if done + size > rows:
                return None
            for label, out in floats.items():
                nulls[label] += arrow_floats(batch.column(label), out[done : done + size])
            for label, parts in words.items():
                parts.append(arrow_codes(batch.column(label)))
            done += size
    except (pa.ArrowException, ValueError):
        return None
    for out in floats.values():
        out.resize(done, refcheck=False)  # gives back the untouched tail, no copy
    if done == 0 or not all(_finite(floats[k], nulls[k]) for k in floats):
        return None
    columns: dict[str, np.ndarray | Words] = {kept[k]: v for k, v in floats.items()}
    columns.update({kept[k]: Words.concatenate(parts) for k, parts in words.items()})
    return TableColumns(name, header, {c: columns[c] for c in kept.values()}, sha256)


def _finite(values: np.ndarray, nulls: int) -> bool:
    """Whether every NaN of ``values`` is an empty cell (not a ``nan``/``inf`` word)."""
    finite = np.isfinite(values)
    return bool(finite.all()) or int(np.count_nonzero(~finite)) == nulls
