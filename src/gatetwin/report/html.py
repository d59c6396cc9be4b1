"""One self-contained HTML report page built from sections.

A :class:`Report` is a title plus an ordered list of :class:`Section` objects; a section
holds paragraphs (plain text), :class:`Table` objects (header + rows) and :class:`Figure`
objects (PNG bytes with a caption), in the order given. :meth:`Report.write` renders one
``report.html``: CSS inline, every figure embedded as a base64 ``data:`` URI, no script, no
external resource of any kind, so the file opens offline and can be mailed or archived as
is.

Typical use::

    report = Report("gatetwin run", subtitle="bundled records")
    report.add_section(
        "Validation",
        "Free-run FMU output against the measured level.",
        Table.from_dicts(cells, ["fmu", "record", "fit_percent", "passed"]),
        Figure.from_source(png_bytes_or_path_or_matplotlib_figure, "A record, 3F"),
    )
    report.write("out/report.html")

This module lays out what it is given; it computes nothing and draws no plot.
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
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from gatetwin import __version__
from gatetwin._io import write_text_atomic
from gatetwin.errors import GatetwinError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class ReportError(GatetwinError, ValueError):
    """A report part that cannot be rendered (not a PNG, ragged table, unwritable file)."""


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


def _as_table(item: Any) -> Table:
    if isinstance(item, Table):
        return item
    if isinstance(item, tuple) and len(item) in (2, 3):
        return Table(*item)
    raise ReportError(f"cannot use a {type(item).__name__} as a table; expected Table or "
                      "(header, rows[, caption])")  # fmt: skip


def _as_figure(item: Any) -> Figure:
    if isinstance(item, Figure):
        return item
    if isinstance(item, tuple) and len(item) == 2:
        return Figure.from_source(item[0], str(item[1]))
    return Figure.from_source(item)


@dataclass
class Report:
    """An HTML report under construction (a builder: sections are appended in place).

    Attributes
    ----------
    title : str
        Page title and main heading.
    subtitle : str
        One line under the title ("" for none).
    sections : list of Section
    generated_by : str
        Shown in the footer with the creation time.
    """

    title: str = "gatetwin report"
    subtitle: str = ""
    sections: list[Section] = field(default_factory=list)
    generated_by: str = f"gatetwin {__version__}"

    def add_section(
        self,
        title: str,
        *content: Block,
        paragraphs: Iterable[str] = (),
        tables: Iterable[Any] = (),
        figures: Iterable[Any] = (),
    ) -> Section:
        """Append a section; returns it.

        Parameters
        ----------
        title : str
            Section heading.
        *content : str, Table or Figure
            Blocks shown first, in the order given.
        paragraphs : iterable of str
            Then these paragraphs (plain text).
        tables : iterable of Table or (header, rows[, caption])
            Then these tables.
        figures : iterable of Figure, PNG bytes, PNG path, matplotlib figure or (source, caption)
            Then these figures.
        """
        blocks: list[Block] = [*content, *(str(p) for p in paragraphs)]
        blocks += [_as_table(t) for t in tables]
        blocks += [_as_figure(f) for f in figures]
        section = Section(str(title), tuple(blocks))
        self.sections.append(section)
        return section

    def to_html(self, *, created: datetime | None = None) -> str:
        """The whole page as one string (``created`` defaults to now, UTC)."""
        from gatetwin.report._render import render_page

        when = created or datetime.now(timezone.utc)
        return render_page(self, when)

    def write(self, path: str | os.PathLike[str]) -> Path:
        """Render and write the page atomically; returns the path.

        Raises
        ------
        ReportError
            The file cannot be written.
        """
        page = self.to_html()
        try:
            return write_text_atomic(path, page)
        except OSError as exc:
            raise ReportError(f"{path}: cannot write ({exc.strerror or exc})") from None


def escape(text: str) -> str:
    """HTML-escape text (quotes included)."""
    return html.escape(text, quote=True)


def data_uri(png: bytes) -> str:
    """``data:image/png;base64,...`` for embedding."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")
