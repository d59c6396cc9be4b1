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

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from gatetwin._io import write_text_atomic
from gatetwin.report.content import (  # noqa: F401 - re-exported
    Block,
    Figure,
    ReportError,
    Section,
    Table,
    data_uri,
    escape,
    format_cell,
    png_size,
)
from gatetwin.version import __version__

__all__ = [
    "Block",
    "Figure",
    "Report",
    "ReportError",
    "Section",
    "Table",
    "data_uri",
    "escape",
    "format_cell",
    "png_size",
]


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
