"""Every measured number in the README and docs is rendered from a results file.

The files in ``docs/results/`` are written by a run or a benchmark with the machine, date
and command (``benchmarks/results.py``); a page whose generated block differs from what its
file renders is stale, and so is a page that quotes a number of a results file outside a
generated block (the MPC table was the page's last hand-typed copy).
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def results():
    spec = importlib.util.spec_from_file_location("results", ROOT / "benchmarks" / "results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_generated_blocks_match_their_files(results) -> None:
    assert results.stale_pages() == []


def test_every_results_file_says_where_it_comes_from(results) -> None:
    files = sorted(results.RESULTS.glob("*.json"))
    assert files, "docs/results holds no results file"
    for path in files:
        doc = json.loads(path.read_text(encoding="utf-8"))
        assert {"command", "date", "machine", "data"} <= doc.keys(), path.name
        assert doc["machine"]["cores"] >= 1, path.name


def test_every_results_file_is_rendered_somewhere(results) -> None:
    pages = "".join(p.read_text(encoding="utf-8") for p in results.PAGES)
    used = {m["file"] for m in results.BLOCK.finditer(pages)}
    assert used == {p.stem for p in results.RESULTS.glob("*.json")}


def test_a_changed_number_makes_the_page_stale(results) -> None:
    page = next(p for p in results.PAGES if results.BLOCK.search(p.read_text(encoding="utf-8")))
    text = page.read_text(encoding="utf-8")
    match = results.BLOCK.search(text)
    body = match["body"]
    digit = next(i for i, c in enumerate(body) if c.isdigit())
    changed = body[:digit] + str((int(body[digit]) + 1) % 10) + body[digit + 1 :]
    tampered = text[: match.start("body")] + changed + text[match.end("body") :]
    assert results.render_page(tampered) != tampered
