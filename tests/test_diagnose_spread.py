"""``gatetwin diagnose`` over several records, one record per task on a process pool: the
findings and every file written are the serial run's."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.diagnose import DiagnosisSettings, diagnose_record
from gatetwin.diagnose.spread import DiagnoseTask, diagnose_records
from gatetwin.fleet.execute import FleetSettings

#: B, a step test, and C, a PRBS test: an FOPDT and an ARX baseline.
RECORDS = ("B", "C")


def _content(path: Path) -> object:
    """A file's bytes; for an FMU (a zip) its members' bytes, which leave out the entries'
    time stamps: an FMU built twice differs in those alone."""
    if path.suffix != ".fmu":
        return path.read_bytes()
    with zipfile.ZipFile(path) as fmu:
        return {name: fmu.read(name) for name in sorted(fmu.namelist())}


def _run(out: Path, *extra: str) -> tuple[str, dict[str, object]]:
    records = [str(bundled_records_dir() / f"{r}.csv") for r in RECORDS]
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


def test_workers_with_a_scheduler_is_refused_in_one_line(tmp_path, capsys) -> None:
    record = str(bundled_records_dir() / "A.csv")
    assert main(["diagnose", record, "--json", str(tmp_path / "d.json"), "--workers", "2",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 2  # fmt: skip
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "d.json").exists()


@pytest.mark.slow
def test_the_runs_diagnosis_stage_on_a_pool_writes_the_serial_outputs(tmp_path) -> None:
    # about a minute on 2 shared cores: three diagnoses, each augmented model exported as
    # FMUs and validated through fmpy, twice
    import shutil
    from types import SimpleNamespace

    from gatetwin.run.stages import diagnose_records as diagnose_stage

    records = tmp_path / "records"
    records.mkdir()
    for name in RECORDS:
        for suffix in (".csv", ".json"):
            shutil.copy(bundled_records_dir() / f"{name}{suffix}", records)
    texts = []
    for label, fleet in (("serial", None), ("pool", FleetSettings(workers=2))):
        out = tmp_path / label
        (out / "models").mkdir(parents=True)  # C is also diagnosed against the step tests'
        shutil.copy(Path(__file__).resolve().parents[1] / "models" / "fopdt_3F.json",
                    out / "models")  # fmt: skip
        ctx = SimpleNamespace(out_dir=out, records_dir=records, fleet=fleet, results={},
                              progress=lambda _line: None)  # fmt: skip
        diagnose_stage(ctx)
        files = {str(p.relative_to(out)): _content(p) for p in sorted(out.rglob("*"))
                 if p.is_file() and p.name != "diagnose.json"}  # fmt: skip
        assert any(name.startswith("diagnose/C_fopdt_3F/") for name in files)
        texts.append(((out / "diagnose.json").read_text().replace(str(out), "OUT"), files))
    assert texts[0][0] == texts[1][0]
    assert texts[0][1] == texts[1][1] and texts[0][1]
