"""``gatetwin diagnose`` over several records, one record per task on a process pool or a
real dask.distributed cluster: the findings and every file written are the serial run's."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import pytest

from dask_support import dask_cluster
from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.diagnosis import DiagnosisSettings, diagnose_record
from gatetwin.diagnosis.spread import DiagnoseTask, diagnose_records
from gatetwin.fleet.execute import FleetSettings

#: B, a step test, and C, a PRBS test: an FOPDT and an ARX baseline.
RECORDS = ("B", "C")
#: For the dask cluster: B (no effect named) and Eboth, whose named inflow disturbance
#: makes the diagnosis write an augmented model file and its C and python FMUs (about 5 s
#: a record on 2 shared cores).
DASK_RECORDS = ("B", "Eboth")


def _content(path: Path) -> object:
    """A file's bytes; for an FMU (a zip) its members' bytes, which leave out the entries'
    time stamps: an FMU built twice differs in those alone."""
    if path.suffix != ".fmu":
        return path.read_bytes()
    with zipfile.ZipFile(path) as fmu:
        return {name: fmu.read(name) for name in sorted(fmu.namelist())}


def _run(out: Path, *extra: str,
         names: tuple[str, ...] = RECORDS) -> tuple[str, dict[str, object]]:  # fmt: skip
    records = [str(bundled_records_dir() / f"{r}.csv") for r in names]
    assert main(["diagnose", *records, "--json", str(out / "d.json"), "--plots",
                 str(out / "plots"), "--fmu-dir", str(out / "fmus"), *extra]) == 0  # fmt: skip
    files = {str(p.relative_to(out)): _content(p) for p in sorted(out.rglob("*"))
             if p.is_file() and p.name != "d.json"}  # fmt: skip
    return (out / "d.json").read_text().replace(str(out), "OUT"), files


def test_two_process_pool_gives_the_serial_findings(tmp_path) -> None:
    # the findings alone (no figure, no FMU): the diagnosis itself, on two processes
    paths = [str(bundled_records_dir() / f"{r}.csv") for r in RECORDS]
    serial = [diagnose_record(p) for p in paths]
    tasks = [DiagnoseTask(p, None, None, None, DiagnosisSettings()) for p in paths]
    pool = diagnose_records(tasks, FleetSettings(workers=2))
    assert len(pool) == len(RECORDS)
    assert json.dumps(pool, sort_keys=True) == json.dumps(serial, sort_keys=True)


@pytest.mark.slow
def test_cli_on_two_processes_writes_the_serial_findings_and_files(tmp_path) -> None:
    # about 100 s on 2 shared cores: each record's augmented model is exported as FMUs
    # and validated through fmpy
    serial, serial_files = _run(tmp_path / "serial")
    pool, pool_files = _run(tmp_path / "pool", "--workers", "2")
    assert len(json.loads(serial)["diagnoses"]) == len(RECORDS)
    assert pool == serial
    assert sorted(pool_files) == sorted(serial_files) and serial_files
    for name, data in serial_files.items():
        assert pool_files[name] == data, name


@pytest.mark.slow  # ~24 s on 2 shared cores: the serial run, the cluster's start, the tasks
def test_cli_on_a_dask_cluster_writes_the_serial_findings_and_files(tmp_path) -> None:
    # a scheduler and two worker processes on localhost, one record per task
    serial, serial_files = _run(tmp_path / "serial", names=DASK_RECORDS)
    with dask_cluster(tmp_path) as address:
        spread, spread_files = _run(tmp_path / "dask", "--scheduler", address,
                                    names=DASK_RECORDS)  # fmt: skip
    diagnoses = json.loads(serial)["diagnoses"]
    assert [d["named_effect"] != "none" for d in diagnoses] == [False, True]
    assert any(name.endswith("_c.fmu") for name in serial_files)
    assert spread == serial
    assert sorted(spread_files) == sorted(serial_files)
    for name, data in serial_files.items():
        assert spread_files[name] == data, name


def test_workers_with_a_scheduler_is_refused_in_one_line(tmp_path, capsys) -> None:
    record = str(bundled_records_dir() / "A.csv")
    assert main(["diagnose", record, "--json", str(tmp_path / "d.json"), "--workers", "2",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 2  # fmt: skip
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "d.json").exists()


def _diagnose_stage(out: Path, records: Path, fleet: FleetSettings | None) -> tuple[str, dict]:
    """The run's diagnosis stage into ``out``: ``diagnose.json`` (``out`` replaced by OUT)
    and every other file's content."""
    from gatetwin.run.pipeline import PipelineContext
    from gatetwin.run.stages import diagnose_records as diagnose_stage

    (out / "models").mkdir(parents=True)  # C is also diagnosed against the step tests'
    shutil.copy(Path(__file__).resolve().parents[2] / "models" / "fopdt_3F.json", out / "models")
    ctx = PipelineContext(out_dir=out, records_dir=records, fleet=fleet,
                          progress=lambda _line: None)  # fmt: skip
    diagnose_stage(ctx)
    files = {str(p.relative_to(out)): _content(p) for p in sorted(out.rglob("*"))
             if p.is_file() and p.name != "diagnose.json"}  # fmt: skip
    assert any(name.startswith("diagnose/C_fopdt_3F/") for name in files)
    return (out / "diagnose.json").read_text().replace(str(out), "OUT"), files


@pytest.fixture
def stage_records(tmp_path) -> Path:
    records = tmp_path / "records"
    records.mkdir()
    for name in RECORDS:
        for suffix in (".csv", ".json"):
            shutil.copy(bundled_records_dir() / f"{name}{suffix}", records)
    return records


@pytest.mark.slow
def test_the_runs_diagnosis_stage_on_a_pool_writes_the_serial_outputs(
        tmp_path, stage_records) -> None:  # fmt: skip
    # three diagnoses, each augmented model exported as FMUs and validated through fmpy,
    # twice: about a minute on 2 shared cores before pool processes ran one BLAS thread
    # each, ~12 s since
    serial = _diagnose_stage(tmp_path / "serial", stage_records, None)
    pool = _diagnose_stage(tmp_path / "pool", stage_records, FleetSettings(workers=2))
    assert pool[0] == serial[0]
    assert pool[1] == serial[1] and serial[1]
    # the files diagnose.json names are the output folder's, named from it: the run
    # writes into a work folder it renames at the end, whose name must not leak
    assert "OUT" not in serial[0]
    named = [path for d in json.loads(serial[0])["diagnoses"]
             for path in [*d["plots"], d["augmented_model"], *(f["path"] for f in d["fmus"])]
             if path is not None]  # fmt: skip
    assert named and set(named) <= set(serial[1])


@pytest.mark.slow
def test_the_runs_diagnosis_stage_on_a_dask_cluster_writes_the_serial_outputs(
        tmp_path, stage_records) -> None:  # fmt: skip
    # ~21 s on 2 shared cores; what `gatetwin run --scheduler` sends to the cluster besides
    # the validation matrix (whose dask path tests/validation/test_validate_spread.py runs)
    serial = _diagnose_stage(tmp_path / "serial", stage_records, None)
    with dask_cluster(tmp_path) as address:
        spread = _diagnose_stage(tmp_path / "dask", stage_records,
                                 FleetSettings(scheduler=address))  # fmt: skip
    assert spread[0] == serial[0]
    assert spread[1] == serial[1] and serial[1]
