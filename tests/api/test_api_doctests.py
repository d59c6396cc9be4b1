"""The Examples sections of the public API run as doctests, one test per docstring (in a
temporary folder, since several write files), so the documentation cannot drift from the
code."""

from __future__ import annotations

import doctest
import importlib

import matplotlib
import pytest

import gatetwin

matplotlib.use("Agg")

MODULES = (
    "gatetwin.api._model",
    "gatetwin.api._simulation",
    "gatetwin.api._identify",
    "gatetwin.api._validation",
    "gatetwin.api._diagnosis",
    "gatetwin.bundled",
    "gatetwin.fmu.provenance",
    "gatetwin.mpc.online",
)
#: Examples that take longer than the default run should, and CI's slow subset too:
#: identify_folder's fits a physical model per gauge of the bundled folder (81-146 s in CI
#: logs), which tests/test_models.py's slow tests already identify; it runs with the long tests.
LONG = {"gatetwin.api._identify.identify_folder"}


def _doctests() -> list[doctest.DocTest]:
    finder = doctest.DocTestFinder()
    found = []
    for name in MODULES:
        found += [t for t in finder.find(importlib.import_module(name)) if t.examples]
    return sorted(found, key=lambda t: t.name)


def _params() -> list[object]:
    return [pytest.param(t, id=t.name,
                         marks=[pytest.mark.slow, pytest.mark.long] if t.name in LONG else [])
            for t in _doctests()]  # fmt: skip


@pytest.mark.parametrize("test", _params())
def test_example_runs(test: doctest.DocTest, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    output: list[str] = []
    result = runner.run(test, out=output.append)
    assert result.failed == 0, "".join(output)


def test_every_public_name_of_the_api_has_examples() -> None:
    documented = {t.name.rsplit(".", 1)[-1] for t in _doctests()}
    api = [
        n
        for n in gatetwin.__all__
        if n != "__version__"
        and getattr(gatetwin, n).__module__.startswith(("gatetwin.api", "gatetwin.bundled"))
    ]
    assert len(api) >= 12
    assert sorted(set(api) - documented) == []
