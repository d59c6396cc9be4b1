"""The documents the code, tests and README cite are in the repository."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: A cited document: a Markdown file name, optionally with a folder.
CITATION = re.compile(r"(?<![\w/.-])((?:[\w-]+/)*[\w-]+\.md)\b")
#: Markdown files ``gatetwin run`` and ``gatetwin models`` write (outputs, not documents).
RUN_OUTPUTS = {"summary.md", "tables.md", "fleet.md"}


def _sources() -> list[Path]:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for folder in ("src", "tests", "benchmarks", "fmu_templates", "examples"):
        for pattern in ("*.py", "*.c", "*.h", "*.md"):
            files += sorted((ROOT / folder).rglob(pattern))
    return [f for f in files if "__pycache__" not in f.parts]


def test_every_cited_markdown_file_exists() -> None:
    missing = []
    for source in _sources():
        for cited in CITATION.findall(source.read_text(encoding="utf-8", errors="replace")):
            if cited in RUN_OUTPUTS:
                continue
            candidates = (ROOT / cited, source.parent / cited, ROOT / "docs" / cited)
            if not any(c.is_file() for c in candidates):
                missing.append(f"{source.relative_to(ROOT)} cites {cited}")
    assert not missing, "\n".join(missing)
