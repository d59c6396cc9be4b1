"""Every code block of the README and the docs runs as a test, as written.

:data:`RUN_BY` names, for each block (page, language, its place among the page's blocks of
that language), the test that runs it; a block added to a page without a test here fails
:func:`test_every_code_block_is_run_by_a_test`.
"""

from __future__ import annotations

import glob
import json
import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest
import tomllib

from gatetwin.cli import main
from observer_cases import PRINTED_RTOL
from observer_cases import TOL as OBSERVER_TOL

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^ *```(\w*)\n(.*?)^ *```", re.M | re.S)
#: (page, language, index among that page's blocks of the language) -> the test running it.
RUN_BY = {
    # the set-up commands: a whole run (`-m long`), and the test command .ci/run ends with
    ("README.md", "bash", 0): "test_pipeline.py::test_run_writes_models_fmus_figures_and_summary",
    ("README.md", "bash", 1): ".ci/run",
    ("README.md", "python", 0): "test_readme.py::test_the_python_example_runs",
    ("docs/python.md", "python", 0):
        "test_readme.py::test_the_python_page_opens_with_the_readmes_example",
    ("docs/mpc.md", "python", 0): "test_the_mpc_page_example_steps_the_controller",
    ("docs/flume.md", "json", 0): "test_the_flume_page_scenario_runs",
    ("docs/record_format.md", "json", 0): "test_the_record_format_page_sidecar_is_read",
    ("docs/validation.md", "toml", 0): "test_the_validation_page_recipe_runs_as_written",
    ("docs/validation.md", "bash", 0): "test_the_validation_page_recipe_runs_as_written",
    ("docs/closed-loop.md", "bash", 0): "test_the_closed_loop_page_commands_run",
    ("docs/closed-loop.md", "bash", 1): "test_the_closed_loop_page_observer_on_a_record_runs",
}  # fmt: skip


def blocks(page: str, language: str) -> list[str]:
    """The fenced blocks of ``page`` in ``language``, in order, their indent removed."""
    text = (ROOT / page).read_text(encoding="utf-8")
    found = []
    for lang, body in FENCE.findall(text):
        if lang == language:
            lines = body.splitlines()
            indent = min(len(ln) - len(ln.lstrip()) for ln in lines if ln.strip())
            found.append("\n".join(ln[indent:] for ln in lines) + "\n")
    return found


def commands(block: str) -> list[list[str]]:
    """The ``gatetwin`` command lines of a shell block (continuations joined), as argv
    without the program name; other lines (``pip install``) are not run here."""
    joined = block.replace("\\\n", " ")
    return [shlex.split(line)[1:] for line in joined.splitlines()
            if line.strip().startswith("gatetwin ")]  # fmt: skip


def test_every_code_block_is_run_by_a_test():
    pages = ["README.md", *(str(p.relative_to(ROOT)) for p in sorted((ROOT / "docs").glob("*.md")))]
    seen = set()
    for page in pages:
        text = (ROOT / page).read_text(encoding="utf-8")
        counts: dict[str, int] = {}
        for lang, _ in FENCE.findall(text):
            seen.add((page, lang, counts.get(lang, 0)))
            counts[lang] = counts.get(lang, 0) + 1
    assert seen == set(RUN_BY), f"blocks without a test: {sorted(seen - set(RUN_BY))}"


def test_the_mpc_page_example_steps_the_controller(monkeypatch):
    monkeypatch.chdir(ROOT)  # the example names models/fopdt_3F.json
    scope: dict[str, object] = {}
    exec(compile(blocks("docs/mpc.md", "python")[0], "docs/mpc.md", "exec"), scope)
    opening = scope["opening_mm"]
    assert isinstance(opening, float) and np.isfinite(opening)


def test_the_flume_page_scenario_runs(tmp_path):
    from gatetwin.records import read_record

    scenario = tmp_path / "my_test.json"
    scenario.write_text(blocks("docs/flume.md", "json")[0], encoding="utf-8")
    assert main(["flume", "--scenario", str(scenario), "--out", str(tmp_path / "out")]) == 0
    record = read_record(tmp_path / "out" / "my_test.csv")
    assert record.time_s[-1] >= json.loads(scenario.read_text())["duration_s"] - 1.2 - 1e-9


def test_the_record_format_page_sidecar_is_read(tmp_path):
    from gatetwin.records import read_record

    shutil.copyfile(ROOT / "src" / "gatetwin" / "data" / "records" / "A.csv", tmp_path / "A.csv")
    (tmp_path / "A.json").write_text(blocks("docs/record_format.md", "json")[0], encoding="utf-8")
    record = read_record(tmp_path / "A.csv")
    sidecar = json.loads((tmp_path / "A.json").read_text())
    assert record.test == sidecar["test"] and record.sample_period_s == sidecar["sample_period_s"]
    assert record.gauges_m == {g: d for g, d in sidecar["gauges"].items() if g in record.levels_mm}
    assert record.metadata.get("condition") == "A"


def test_the_validation_page_recipe_runs_as_written(tmp_path, monkeypatch):
    """The map and the command of the page, on a stranger's FMU and record placed where
    the command names them (tests/foreign_fmus.py builds both)."""
    from foreign_fmus import foreign_gate_fmu, foreign_gate_record

    monkeypatch.chdir(tmp_path)
    (tmp_path / "plant_map.toml").write_text(blocks("docs/validation.md", "toml")[0],
                                             encoding="utf-8")  # fmt: skip
    assert tomllib.loads((tmp_path / "plant_map.toml").read_text())  # TOML as written
    (tmp_path / "build").mkdir()
    shutil.copyfile(foreign_gate_fmu(tmp_path / "fmu"), tmp_path / "build" / "plant.fmu")
    (tmp_path / "measurements").mkdir()
    foreign_gate_record(tmp_path / "measurements")
    (argv,) = commands(blocks("docs/validation.md", "bash")[0])
    argv = [a for pattern in argv for a in (sorted(glob.glob(pattern)) or [pattern])]
    assert main(argv) == 0
    assert (tmp_path / "validation.json").is_file() and (tmp_path / "validation.xml").is_file()


@pytest.mark.slow  # five C FMU builds, the MPC at the default horizon among them: ~17 s
def test_the_closed_loop_page_commands_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "models").symlink_to(ROOT / "models")
    argvs = commands(blocks("docs/closed-loop.md", "bash")[0])
    assert len(argvs) == 5
    for argv in argvs:
        assert main(argv) == 0, argv
    for name in ("fopdt_3F_pi.fmu", "fopdt_3F_mpc.fmu", "loop.ssp", "mpc_loop.ssp", "result.csv"):
        assert (tmp_path / name).is_file(), name


def test_the_closed_loop_page_observer_on_a_record_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("models", "src"):
        (tmp_path / name).symlink_to(ROOT / name)
    argvs = commands(blocks("docs/closed-loop.md", "bash")[1])
    assert len(argvs) == 3
    for argv in argvs:
        assert main(argv) == 0, argv
    ours = np.genfromtxt(tmp_path / "observed.csv", delimiter=",", names=True, deletechars="")
    observed = np.genfromtxt(tmp_path / "estimates.csv", delimiter=",", names=True)
    # the page's claim: observe's estimates, within the observer FMU's bound and observe's 10
    # printed digits
    bound = OBSERVER_TOL + PRINTED_RTOL * np.abs(observed["filtered_level_mm"])
    assert np.all(np.abs(ours["observer.filtered_level_mm"] - observed["filtered_level_mm"])
                  <= bound)  # fmt: skip
