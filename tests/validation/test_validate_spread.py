"""``gatetwin validate`` with one record per task: a local process pool and a real dask
cluster give the serial run's findings, and what cannot be validated still fails in one
line before any task is sent."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dask_support import dask_cluster
from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.fmu import export_fmu
from gatetwin.modelfile import read_model_file

MODEL = Path(__file__).resolve().parents[2] / "models" / "fopdt_3F.json"
RECORDS = [bundled_records_dir() / f"{name}.csv" for name in ("A", "Q55", "Eboth", "C")]
#: Per-record keys that say how long a run took: they differ between runs by nature.
TIMINGS = {"run_time_s"}


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    model = read_model_file(MODEL)
    return export_fmu(model.plant, tmp_path_factory.mktemp("spread") / "fopdt_3F.fmu",
                      backend="c", model_name=model.name, provenance={})  # fmt: skip


def _validate(fmu: Path, out: Path, *extra: str) -> dict:
    args = ["validate", str(fmu), *map(str, RECORDS), "--json", str(out),
            "--fail-under", "fit_percent=70", *extra]  # fmt: skip
    assert main(args) in (0, 1)
    doc = json.loads(out.read_text(encoding="utf-8"))
    for rec in doc["records"]:
        for key in TIMINGS:
            rec.pop(key, None)
    return doc


@pytest.fixture(scope="module")
def serial(fmu, tmp_path_factory) -> dict:
    return _validate(fmu, tmp_path_factory.mktemp("serial") / "v.json")


def test_a_process_pool_gives_the_serial_findings(fmu, serial, tmp_path):
    pooled = _validate(fmu, tmp_path / "v.json", "--workers", "2")
    assert [r["record"] for r in pooled["records"]] == [p.name for p in RECORDS]
    assert pooled["records"] == serial["records"]
    assert pooled["passed"] == serial["passed"]


def test_a_dask_cluster_gives_the_serial_findings(fmu, serial, tmp_path):
    with dask_cluster(tmp_path) as address:
        spread = _validate(fmu, tmp_path / "v.json", "--scheduler", address)
    assert spread["records"] == serial["records"]
    assert spread["static_validation"] == serial["static_validation"]


def test_a_record_that_cannot_be_validated_fails_in_one_line_without_output(fmu, tmp_path,
                                                                            capsys):  # fmt: skip
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,opening_mm\nnot,a,record\n")
    out = tmp_path / "v.json"
    code = main(["validate", str(fmu), str(RECORDS[0]), str(bad), "--json", str(out),
                 "--workers", "2"])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "bad.csv" in err[0]
    assert not out.exists()
    assert main(["validate", str(fmu), str(RECORDS[0]), "--json", str(out), "--workers", "0"]) == 2
    assert main(["validate", str(fmu), str(RECORDS[0]), "--json", str(out), "--workers", "2",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 2  # fmt: skip
    assert not out.exists()


def test_the_runs_matrices_on_a_pool_are_the_serial_matrices(fmu, tmp_path):
    """``gatetwin run`` validates one FMU per task: two FMUs on two processes give, FMU by
    FMU, the cells the serial matrix gives."""
    from gatetwin.fleet.execute import FleetSettings
    from gatetwin.run.stages import MATRIX_FAIL_UNDER
    from gatetwin.validation import parse_thresholds, validate_matrix
    from gatetwin.validation.spread import validate_matrices

    model = read_model_file(MODEL)
    python_fmu = export_fmu(model.plant, tmp_path / "fopdt_3F_python.fmu", backend="python",
                            model_name=model.name, provenance={})  # fmt: skip
    thresholds = parse_thresholds(MATRIX_FAIL_UNDER)
    pairs = [(fmu, RECORDS), (python_fmu, RECORDS[:2])]
    serial = [validate_matrix([f], records, thresholds=thresholds) for f, records in pairs]
    pooled = validate_matrices(pairs, FleetSettings(workers=2), thresholds=thresholds)
    assert [[c["record"] for c in cells] for cells in pooled] == [
        [p.name for p in records] for _, records in pairs]  # fmt: skip
    assert pooled == serial


def test_a_record_without_the_fmus_gauge_is_refused_before_any_task_runs(fmu, tmp_path,
                                                                         capsys):  # fmt: skip
    """The FMU's output is level_3F_mm; a record of other gauges is refused in one line before
    the pool starts (no task's progress line), as the serial run refuses it."""
    other = tmp_path / "other.csv"
    other.write_text(RECORDS[0].read_text().replace("level_3F_mm", "level_9Z_mm", 1))
    other.with_suffix(".json").write_bytes(RECORDS[0].with_suffix(".json").read_bytes())
    out = tmp_path / "v.json"
    code = main(["validate", str(fmu), str(RECORDS[0]), str(other), "--json", str(out),
                 "--workers", "2"])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "other.csv" in err[0] and "level_3F_mm" in err[0]
    assert not out.exists()
