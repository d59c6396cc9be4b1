"""Model files: the repository's models/ are fresh, valid against the schema, and export."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.errors import ModelFileError
from gatetwin.identification.suite import identify_folder
from gatetwin.modelfile import read_model_file, write_model_files

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: each worker identifies the folder itself
    fcntl = None

MODELS = Path(__file__).resolve().parents[1] / "models"


@pytest.fixture(scope="session")
def regenerated(tmp_path_factory, worker_id):
    """The bundled records identified as ``gatetwin run`` does (each gauge on a process of a
    pool of two) and written as ``gatetwin models`` writes them: once per test session, also
    when the two tests that use it run on two xdist workers (the first one to need it
    identifies the folder under a lock in the workers' shared temporary folder, the other
    reads what it wrote; a minute of identification saved)."""
    from gatetwin.fleet.execute import FleetSettings

    root = tmp_path_factory.getbasetemp()
    root = root if worker_id == "master" or fcntl is None else root.parent
    out = root / "regenerated_models"
    with open(root / "regenerated_models.lock", "w") as lock:
        if root != tmp_path_factory.getbasetemp():
            fcntl.flock(lock, fcntl.LOCK_EX)
        if not (root / "regenerated_models.done").exists():
            models = identify_folder(bundled_records_dir(), fleet=FleetSettings(workers=2)).models
            write_model_files(models, out)
            (root / "regenerated_models.done").touch()
    return out


def assert_close_json(a, b, path="$"):
    """Equal structure and strings; numbers to 1e-6 (platform round-off, far below any SE)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), path
        for k in a:
            assert_close_json(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_close_json(x, y, f"{path}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert np.isclose(a, b, rtol=1e-6, atol=1e-6), f"{path}: {a} != {b}"
    else:
        assert a == b, path


@pytest.mark.slow
def test_repository_models_are_not_stale(regenerated):
    fresh = sorted(p.name for p in regenerated.glob("*.json"))
    stored = sorted(p.name for p in MODELS.glob("*.json"))
    assert fresh == stored, "run `gatetwin models --out models` and commit the result"
    for name in fresh:
        assert_close_json(json.loads((regenerated / name).read_text()),
               json.loads((MODELS / name).read_text()), name)  # fmt: skip


@pytest.mark.slow
def test_identification_here_is_the_identification_on_a_pool(regenerated, tmp_path):
    """The API's ``identify_folder`` of the folder's name (one gauge after another in this
    process) saves the pool's model files to the bit (the numerical libraries on one thread
    in both)."""
    import gatetwin

    gatetwin.identify_folder(str(bundled_records_dir())).save(tmp_path)
    names = sorted(p.name for p in regenerated.iterdir())
    assert names == sorted(p.name for p in tmp_path.iterdir())
    for name in names:
        assert (tmp_path / name).read_bytes() == (regenerated / name).read_bytes(), name


def test_every_model_validates_against_the_schema():
    schema = json.loads((MODELS / "schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    for path in MODELS.glob("*.json"):
        if path.name != "schema.json":
            jsonschema.validate(json.loads(path.read_text()), schema)


def test_model_file_round_trip_and_provenance():
    model = read_model_file(MODELS / "fopdt_3F.json")
    assert model.plant.kind == "fopdt" and model.plant.gauge == "3F"
    roles = {r["name"]: r["role"] for r in model.content["provenance"]["records"]}
    assert roles["Q55"] == "held_out" and roles["A"] == "fit" and roles["static"] == "rating"
    assert len(model.sha256) == 64


def test_schedule_is_monotone_in_flow_like_the_paper():
    # |K| falls and T shortens as Q rises (docs/reference_study.md), along the operating line
    sched = read_model_file(MODELS / "fopdt_3F.json").plant.schedule.values
    assert np.all(np.diff(np.abs(sched["gain_mm_per_mm"])) < 0)
    assert np.all(np.diff(sched["time_constant_s"]) < 0)


@pytest.mark.parametrize(
    ("text", "match"),
    [("{", "not a JSON"), ("[]", "JSON object"), ('{"schema_version": "9.0"}', "schema_version"),
     ('{"schema_version": "1.0", "name": "x"}', "missing")],
)  # fmt: skip
def test_bad_model_files_are_refused(tmp_path, text, match):
    path = tmp_path / "m.json"
    path.write_text(text)
    with pytest.raises(ModelFileError, match=match):
        read_model_file(path)


def test_export_cli_refuses_bad_model_without_output(tmp_path, capsys):
    bad = tmp_path / "m.json"
    bad.write_text("{")
    out = tmp_path / "m.fmu"
    assert main(["export", str(bad), "--backend", "c", "--out", str(out)]) == 2
    assert not out.exists()
    assert capsys.readouterr().err.count("\n") == 1
