"""The README's Python example runs as written."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

README = Path(__file__).resolve().parents[1] / "README.md"


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
