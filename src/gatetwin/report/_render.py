"""HTML rendering of a :class:`~gatetwin.report.html.Report` (page layout and inline CSS).

Kept apart from the data classes so that the page's look can change without touching
what a report holds. Everything is escaped; nothing refers outside the page.
"""

from __future__ import annotations

import numbers
from datetime import datetime
from typing import TYPE_CHECKING, Any

from gatetwin.report.content import Figure, Section, Table, data_uri, escape, format_cell

if TYPE_CHECKING:
    from gatetwin.report.html import Report

__all__ = ["CSS", "render_page"]

CSS = """
:root { --ink: #1d2430; --muted: #5b6575; --rule: #d5dbe3; --band: #f3f6f9;
        --accent: #1f5f99; --pass: #1b7a3a; --fail: #b3261e; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto,
       "DejaVu Sans", sans-serif; color: var(--ink); background: #fff; }
header, nav, main, footer { max-width: 1060px; margin: 0 auto; padding: 0 24px; }
header { padding-top: 28px; border-bottom: 3px solid var(--accent); padding-bottom: 12px; }
h1 { font-size: 1.8em; margin: 0 0 4px; }
.subtitle { color: var(--muted); margin: 0; }
nav { padding-top: 12px; }
nav ol { margin: 0; padding-left: 1.4em; color: var(--muted); }
nav a { color: var(--accent); text-decoration: none; }
section { padding: 8px 0 20px; border-bottom: 1px solid var(--rule); }
h2 { font-size: 1.35em; margin: 20px 0 8px; color: var(--accent); }
p { margin: 8px 0; max-width: 80ch; }
.table-wrap { overflow-x: auto; }
figure.table figcaption { color: var(--ink); margin: 0 0 6px; }
table { border-collapse: collapse; font-size: 0.92em; font-variant-numeric: tabular-nums; }
th, td { border: 1px solid var(--rule); padding: 4px 9px; vertical-align: top; }
th { background: var(--band); text-align: left; }
tbody tr:nth-child(even) td { background: #fafbfc; }
td.num { text-align: right; white-space: nowrap; }
td.pass { color: var(--pass); font-weight: 600; }
td.fail { color: var(--fail); font-weight: 700; }
figure { margin: 16px 0; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--rule); }
figcaption { color: var(--muted); font-size: 0.92em; margin-top: 4px; }
.label { font-weight: 600; color: var(--ink); }
footer { color: var(--muted); font-size: 0.85em; padding: 16px 24px 32px; }
@media print { nav { display: none; } section { break-inside: avoid-page; } }
"""


class _Counter:
    """Running numbers of tables and figures across the page."""

    def __init__(self) -> None:
        self.tables = 0
        self.figures = 0


def _cell(value: Any) -> str:
    text = escape(format_cell(value))
    if isinstance(value, bool):
        return f'<td class="{"pass" if value else "fail"}">{text}</td>'
    if isinstance(value, numbers.Real):
        return f'<td class="num">{text}</td>'
    return f"<td>{text}</td>"


def _table(table: Table, count: _Counter) -> str:
    count.tables += 1
    caption = f'<span class="label">Table {count.tables}.</span> {escape(table.caption)}'
    head = "".join(f'<th scope="col">{escape(h)}</th>' for h in table.header)
    body = "\n".join("<tr>" + "".join(_cell(v) for v in row) + "</tr>" for row in table.rows)
    return (
        f'<figure class="table"><figcaption>{caption}</figcaption>\n<div class="table-wrap">'
        f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table></div>"
        "</figure>"
    )


def _figure(figure: Figure, count: _Counter) -> str:
    count.figures += 1
    width, height = figure.size_px
    alt = escape(figure.alt or figure.caption or f"Figure {count.figures}")
    caption = f'<span class="label">Figure {count.figures}.</span> {escape(figure.caption)}'
    return (
        f'<figure><img src="{data_uri(figure.png)}" width="{width}" height="{height}" '
        f'alt="{alt}">\n<figcaption>{caption}</figcaption></figure>'
    )


def _section(section: Section, index: int, count: _Counter) -> str:
    parts = [f'<section id="s{index}">', f"<h2>{escape(section.title)}</h2>"]
    for block in section.blocks:
        if isinstance(block, Table):
            parts.append(_table(block, count))
        elif isinstance(block, Figure):
            parts.append(_figure(block, count))
        else:
            parts.append(f"<p>{escape(block)}</p>")
    parts.append("</section>")
    return "\n".join(parts)


def render_page(report: Report, created: datetime) -> str:
    """The report as a complete, self-contained HTML5 document."""
    count = _Counter()
    sections = "\n".join(_section(s, i, count) for i, s in enumerate(report.sections, 1))
    toc = "".join(
        f'<li><a href="#s{i}">{escape(s.title)}</a></li>' for i, s in enumerate(report.sections, 1)
    )
    subtitle = f'<p class="subtitle">{escape(report.subtitle)}</p>' if report.subtitle else ""
    stamp = created.isoformat(timespec="seconds")
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="{escape(report.generated_by)}">
<title>{escape(report.title)}</title>
<style>{CSS}</style>
</head>
<body>
<header><h1>{escape(report.title)}</h1>{subtitle}</header>
<nav aria-label="Contents"><ol>{toc}</ol></nav>
<main>
{sections}
</main>
<footer>Generated by {escape(report.generated_by)} on {escape(stamp)}.
Self-contained page: figures are embedded, nothing is loaded from elsewhere.</footer>
</body>
</html>
"""
