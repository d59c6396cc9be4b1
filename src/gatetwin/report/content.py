"""What a report holds: tables, figures, sections, and the cell and text escaping.

The data half of :mod:`gatetwin.report` (the page is :class:`~gatetwin.report.html.Report`,
its layout :mod:`gatetwin.report._render`).
"""

from __future__ import annotations

import base64
import html
import math
import numbers
import os
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import ReportError

__all__ = ["Block", "Figure", "Section", "Table", "data_uri", "escape", "format_cell", "png_size"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def format_cell(value: Any) -> str:
    """Text of a table cell: numbers to 4 significant digits, None/NaN as an en dash.

    Booleans read ``pass`` / ``FAIL``; strings are kept as they are.
    """
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "pass" if value else "FAIL"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        value = float(value)
        if math.isnan(value):
            return "–"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"
    return str(value)


@dataclass(frozen=True)
class Table:
    """A table: a header row and body rows of equal length.

    Attributes
    ----------
    header : tuple of str
        Column titles (put units here, e.g. ``"RMSE (mm)"``).
    rows : tuple of tuple
        Cell values; rendered with :func:`format_cell` (pass pre-formatted strings for
        full control).
    caption : str
        Shown above the table after "Table n." ("" for none).
    """

    header: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...]
    caption: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "header", tuple(str(h) for h in self.header))
        object.__setattr__(self, "rows", tuple(tuple(r) for r in self.rows))
        if not self.header:
            raise ReportError("table: the header needs at least one column")
        for i, row in enumerate(self.rows):
            if len(row) != len(self.header):
                raise ReportError(
                    f"table {self.caption or '(no caption)'}: row {i + 1} has {len(row)} "
                    f"cells, the header {len(self.header)}"
                )

    @classmethod
    def from_dicts(
        cls,
        records: Iterable[Mapping[str, Any]],
        columns: Sequence[str] | None = None,
        *,
        titles: Mapping[str, str] | None = None,
        caption: str = "",
    ) -> Table:
        """A table with one row per mapping (e.g. validation-matrix cells).

        ``columns`` picks and orders the keys (default: the first mapping's keys);
        ``titles`` renames column headers. Missing keys give empty (–) cells.
        """
        rows = list(records)
        keys = list(columns) if columns is not None else list(rows[0]) if rows else []
        names = titles or {}
        return cls(
            header=tuple(names.get(k, k) for k in keys),
            rows=tuple(tuple(r.get(k) for k in keys) for r in rows),
            caption=caption,
        )


def png_size(png: bytes) -> tuple[int, int]:
    """Width and height in pixels from a PNG's header; raises :class:`ReportError`."""
    if len(png) < 24 or not png.startswith(_PNG_SIGNATURE) or png[12:16] != b"IHDR":
        raise ReportError("figure: not a PNG image")
    width, height = struct.unpack(">II", png[16:24])
    if width == 0 or height == 0:
        raise ReportError("figure: PNG of zero size")
    return int(width), int(height)


@dataclass(frozen=True)
class Figure:
    """A PNG image with a caption.

    Attributes
    ----------
    png : bytes
        The PNG file's bytes (checked on construction).
    caption : str
        Shown below the image after "Figure n.".
    alt : str
        Alternative text (defaults to the caption).
    """

    png: bytes = field(repr=False)
    caption: str = ""
    alt: str = ""

    def __post_init__(self) -> None:
        png_size(self.png)

    @property
    def size_px(self) -> tuple[int, int]:
        return png_size(self.png)

    @classmethod
    def from_source(
        cls, source: Any, caption: str = "", *, alt: str = "", dpi: int = 100
    ) -> Figure:
        """A figure from PNG bytes, a PNG file path, or a matplotlib figure.

        A matplotlib figure (anything with ``savefig``) is rendered to PNG at ``dpi``.
        """
        if isinstance(source, (bytes, bytearray, memoryview)):
            return cls(bytes(source), caption, alt)
        if isinstance(source, (str, os.PathLike)):
            try:
                data = Path(source).read_bytes()
            except OSError as exc:
                raise ReportError(f"figure {source}: cannot read ({exc.strerror or exc})") from None
            try:
                return cls(data, caption, alt)
            except ReportError as exc:
                raise ReportError(f"figure {source}: {exc}") from None
        if hasattr(source, "savefig"):
            import io

            buffer = io.BytesIO()
            source.savefig(buffer, format="png", dpi=dpi)
            return cls(buffer.getvalue(), caption, alt)
        raise ReportError(
            f"figure: cannot use a {type(source).__name__}; expected PNG bytes, a PNG file "
            "path or a matplotlib figure"
        )


Block = str | Table | Figure


@dataclass(frozen=True)
class Section:
    """A titled part of the report: paragraphs, tables and figures in order.

    Attributes
    ----------
    title : str
    blocks : tuple of (str or Table or Figure)
        Strings are paragraphs of plain text (HTML is escaped).
    """

    title: str
    blocks: tuple[Block, ...] = ()

    def __post_init__(self) -> None:
        for block in self.blocks:
            if not isinstance(block, (str, Table, Figure)):
                raise ReportError(
                    f"section {self.title!r}: cannot show a {type(block).__name__}; expected "
                    "a paragraph (str), a Table or a Figure"
                )


def escape(text: str) -> str:
    """HTML-escape text (quotes included)."""
    return html.escape(text, quote=True)


def data_uri(png: bytes) -> str:
    """``data:image/png;base64,...`` for embedding."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")
