"""A gate's model set when one family cannot be identified: the others are written."""

from __future__ import annotations

import copy

import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.errors import IdentificationError
from gatetwin.identification import suite
from gatetwin.modelfile import read_model_file, write_model_file

GAUGE = "1D"  # not the discrete model's gauge: its task fits the two families only
WHY = "physical fit did not converge (The maximum number of function evaluations is exceeded.)"


@pytest.fixture(scope="module")
def ident():
    return suite.load_records(sorted(bundled_records_dir().glob("*.csv")), "bundled")


def _physical_fails(monkeypatch):
    def fails(_ident, gauge):
        raise IdentificationError(WHY)

    monkeypatch.setattr(suite, "physical_model", fails)


def test_a_gauge_whose_physical_fit_fails_keeps_its_step_fopdt(ident, monkeypatch, tmp_path):
    _physical_fails(monkeypatch)
    docs = suite.gauge_models((ident, GAUGE))
    assert sorted(docs) == [f"fopdt_{GAUGE}"]
    fopdt = docs[f"fopdt_{GAUGE}"]
    assert fopdt["provenance"]["metrics"]["physical_not_identified"] == WHY
    assert "envelope" not in fopdt["plant"]  # the schedule of the step conditions alone
    path = write_model_file(tmp_path / f"fopdt_{GAUGE}.json", fopdt)
    assert read_model_file(path).plant.gauge == GAUGE  # a model file the reader accepts


def test_the_set_is_written_and_the_missing_model_named(ident, monkeypatch, tmp_path, capsys):
    """``gatetwin models`` writes every model it could identify, warns once per missing one
    in a line, and exits 0."""
    _physical_fails(monkeypatch)
    step_only = suite.gauge_models((ident, GAUGE))[f"fopdt_{GAUGE}"]

    def each_gauge(job):  # the step-only FOPDT of every gauge, renamed: no fit repeated
        doc = copy.deepcopy(step_only)
        doc["name"] = f"fopdt_{job[1]}"
        doc["gauge"] = doc["plant"]["gauge"] = job[1]
        return {doc["name"]: doc}

    monkeypatch.setattr(suite, "gauge_models", each_gauge)
    monkeypatch.setattr(suite, "arx_model", lambda *_a, **_k: pytest.fail("no discrete model"))
    # the patched fits live in this process: the gauges' tasks run here, not on a pool
    monkeypatch.setattr("gatetwin.fleet.default_workers", lambda: 1)
    out = tmp_path / "models"
    assert main(["models", "--records", str(bundled_records_dir()), "--out", str(out)]) == 0
    gauges = ["1D", "2E", "3F", "4G", "5H"]
    written = sorted(p.name for p in out.glob("*_*.json"))
    assert written == [f"fopdt_{g}.json" for g in gauges]
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert warned == [f"gatetwin: warning: physical_{g} not identified ({WHY}); the others are "
                      "written" for g in gauges]  # fmt: skip


def test_a_fleets_gate_summary_names_the_missing_model():
    from gatetwin.fleet.gate import gate_summary

    ident = suite.Identified(not_identified={"physical_N2_2": WHY})
    summary = gate_summary("G2", ident, ["a warning of the identification"])
    assert summary["warnings"][:2] == [
        "a warning of the identification",
        f"physical_N2_2 not identified ({WHY}); the others are written",
    ]


def test_a_gauge_no_model_can_name_is_refused_before_any_fit(tmp_path, capsys, monkeypatch):
    """A column ``level_N2.1(ds)_mm`` is a record's gauge, but no model file, FMU variable or
    C identifier can carry its name: refused in one line naming the file and the column,
    before a fit (none is run) and with no output."""
    import shutil

    monkeypatch.setattr(suite, "gauge_models", lambda _job: pytest.fail("a fit was started"))
    folder = tmp_path / "records"
    shutil.copytree(bundled_records_dir(), folder)
    record = folder / "A.csv"
    text = record.read_text(encoding="utf-8")
    record.write_text(text.replace("level_1D_mm", "level_N2.1(ds)_mm", 1), encoding="utf-8")
    out = tmp_path / "models"
    assert main(["models", "--records", str(folder), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (f"gatetwin: error: {record}: column level_N2.1(ds)_mm: gauge name "
                   "'N2.1(ds)' does not match ^[A-Za-z0-9_]{1,32}$ (a model names its FMU "
                   "variables after it); rename the column\n")  # fmt: skip
    assert not out.exists()
