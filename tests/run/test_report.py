"""The HTML report: one self-contained page, everything escaped, figures embedded."""

from __future__ import annotations

import base64
import io
import math
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from gatetwin.report import Figure, Report, ReportError, Table, format_cell


def png_bytes(color: str = "C0", size_in: tuple[float, float] = (3.0, 2.0)) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure as MplFigure

    fig = MplFigure(figsize=size_in)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    t = np.linspace(0.0, 10.0, 50)
    ax.plot(t, np.exp(-t / 3.0), color=color)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=80)
    return buffer.getvalue()


class _Tags(HTMLParser):
    """Every start tag with its attributes, and the text of <script>/<style> elements."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))

    def named(self, tag: str) -> list[dict[str, str | None]]:
        return [attrs for name, attrs in self.tags if name == tag]


def parse(page: str) -> _Tags:
    parser = _Tags()
    parser.feed(page)
    parser.close()
    return parser


def sample_report(tmp_path: Path) -> tuple[Report, list[bytes]]:
    from matplotlib.figure import Figure as MplFigure

    pngs = [png_bytes("C0"), png_bytes("C3")]
    path = tmp_path / "second.png"
    path.write_bytes(pngs[1])
    mpl = MplFigure(figsize=(2.0, 1.5))
    mpl.subplots().plot([0, 1], [1, 0])
    report = Report("Gate <3F> & co", subtitle="bundled records")
    report.add_section(
        "Published vs ours",
        "Levels in mm; <script>alert('x')</script> must show as text.",
        Table(
            ("gauge", "K (mm/mm)", "ok"),
            [("3F", -15.27, True), ("5H", math.nan, False)],
            "Condition A",
        ),  # fmt: skip
    )
    report.add_section(
        "Figures",
        paragraphs=["Two figures and a matplotlib one."],
        tables=[(("a", "b"), [(1, 2.5)])],
        figures=[pngs[0], (path, "from a file"), Figure.from_source(mpl, "matplotlib")],
    )
    return report, pngs


def test_page_is_self_contained_and_escaped(tmp_path: Path) -> None:
    report, pngs = sample_report(tmp_path)
    written = report.write(tmp_path / "out" / "report.html")
    page = written.read_text(encoding="utf-8")
    tags = parse(page)
    assert page.startswith("<!DOCTYPE html>") and not tags.named("script")
    assert not tags.named("link") and len(tags.named("style")) == 1
    for attrs in tags.tags:
        for name in ("src", "href", "srcset", "action", "data"):
            value = attrs[1].get(name)
            assert value is None or value.startswith(("data:image/png;base64,", "#")), value
    assert "http:" not in page and "https:" not in page
    images = tags.named("img")
    assert len(images) == 3
    embedded = [base64.b64decode(img["src"].split(",", 1)[1]) for img in images]
    assert embedded[:2] == pngs
    assert all(img["width"] and img["height"] and img["alt"] for img in images)
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;" in page
    assert "<title>Gate &lt;3F&gt; &amp; co</title>" in page
    assert len(tags.named("table")) == 2
    assert "Table 2." in page and "Figure 3.</span> matplotlib" in page
    assert [a["href"] for a in tags.named("a")] == ["#s1", "#s2"]
    assert [s["id"] for s in tags.named("section")] == ["s1", "s2"]


def test_cells_are_formatted_and_marked() -> None:
    assert [format_cell(v) for v in (None, True, False, 3, -15.2714, 1.0e5, math.nan)] == [
        "–", "pass", "FAIL", "3", "-15.27", "100000", "–"]  # fmt: skip
    assert format_cell(np.float64(0.99652)) == "0.9965" and format_cell(np.int64(7)) == "7"
    assert format_cell(math.inf) == "∞" and format_cell("x|y") == "x|y"
    report = Report()
    report.add_section("t", Table(("ok", "v"), [(True, 1.5), (False, "n/a")]))
    page = report.to_html()
    assert '<td class="pass">pass</td><td class="num">1.5</td>' in page
    assert '<td class="fail">FAIL</td><td>n/a</td>' in page


def test_table_from_dicts_picks_orders_and_renames_columns() -> None:
    cells = [{"fmu": "a.fmu", "record": "A.csv", "fit_percent": 94.1, "passed": True},
             {"fmu": "b.fmu", "record": "A.csv", "passed": False}]  # fmt: skip
    titles = {"fit_percent": "fit %"}
    table = Table.from_dicts(cells, ["record", "fmu", "fit_percent"], titles=titles)
    assert table.header == ("record", "fmu", "fit %")
    assert table.rows == (("A.csv", "a.fmu", 94.1), ("A.csv", "b.fmu", None))
    assert Table.from_dicts(cells[:1]).header == ("fmu", "record", "fit_percent", "passed")


def test_bad_parts_are_refused_with_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ReportError, match="row 2 has 1 cells, the header 2"):
        Table(("a", "b"), [(1, 2), (3,)], "ragged")
    with pytest.raises(ReportError, match="not a PNG image"):
        Figure(b"GIF89a not a png")
    with pytest.raises(ReportError, match="missing.png: cannot read"):
        Figure.from_source(tmp_path / "missing.png")
    text = tmp_path / "fake.png"
    text.write_text("hello", encoding="utf-8")
    with pytest.raises(ReportError, match="fake.png: figure: not a PNG image"):
        Figure.from_source(text)
    with pytest.raises(ReportError, match="cannot use a int"):
        Figure.from_source(42)
    with pytest.raises(ReportError, match="cannot show a dict"):
        Report().add_section("s", {"not": "a block"})  # type: ignore[arg-type]


def test_write_failure_is_a_report_error_and_leaves_nothing(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x", encoding="utf-8")
    with pytest.raises(ReportError, match="cannot write"):
        Report().write(blocker / "report.html")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
