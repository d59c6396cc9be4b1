"""The README's Python example runs as written."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

README = Path(__file__).resolve().parents[2] / "README.md"


def python_example() -> str:
    """The first ``python`` block of the README's "Python" section."""
    section = README.read_text(encoding="utf-8").split("\n## Python\n", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)


def test_the_python_example_is_short():
    lines = [ln for ln in python_example().splitlines() if ln.strip()]
    assert len(lines) <= 10


def test_the_python_example_runs(tmp_path, monkeypatch, capsys):
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    try:
        exec(compile(python_example(), str(README), "exec"), {"__name__": "__readme__"})
    finally:
        plt.close("all")
    out = capsys.readouterr().out
    assert "passed: True" in out
    assert (tmp_path / "fopdt_3F.fmu").is_file() and (tmp_path / "validation.png").is_file()


def test_the_readme_is_an_entry_point_and_the_guides_are_in_the_docs():
    """The README stays short (the commands, an example, the command table, links); every
    page of ``docs/`` is in the site's navigation, and every page the README links to
    exists."""
    root = README.parent
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 150
    nav = set(re.findall(r":\s*([\w-]+\.md)\s*$", (root / "mkdocs.yml").read_text(), re.M))
    pages = {p.name for p in (root / "docs").glob("*.md")}
    assert pages == nav
    linked = re.findall(r"\]\((docs/[\w-]+\.md)\)", README.read_text(encoding="utf-8"))
    assert linked and all((root / link).is_file() for link in linked)


def test_the_python_page_opens_with_the_readmes_example():
    page = (README.parent / "docs" / "python.md").read_text(encoding="utf-8")
    assert re.search(r"```python\n(.*?)```", page, re.DOTALL).group(1) == python_example()
