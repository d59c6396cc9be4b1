"""The HTML report: one self-contained page from titled sections.

Build a :class:`Report`, add sections of paragraphs, :class:`Table` and :class:`Figure`
objects with :meth:`Report.add_section`, and :meth:`Report.write` one ``report.html`` that
embeds its figures and styles and loads nothing from elsewhere. Drawing figures is up to
the stage that owns the data (e.g. :func:`gatetwin.validation.plot_record`).
"""

from gatetwin.report.html import Figure, Report, ReportError, Section, Table, format_cell

__all__ = ["Figure", "Report", "ReportError", "Section", "Table", "format_cell"]
