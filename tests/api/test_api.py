"""The Python API (gatetwin.api): the same files as the command line, the same numbers as
the library it calls, and one clear error for bad input."""

from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

import jsonschema
import numpy as np
import pytest

import gatetwin
from gatetwin import (
    ExportError,
    GatetwinError,
    IdentificationError,
    Model,
    ModelFileError,
    bundled_records_dir,
    identify,
    identify_folder,
    load_model,
    read_record,
)
from gatetwin.cli import main
from gatetwin.plant.inputs import SimulationError

RECORDS = bundled_records_dir()
MODELS = Path(__file__).resolve().parents[2] / "models"
#: Round-off of the same arithmetic done two ways (state update vs transfer function), mm.
ROUND_OFF_MM = 1e-9


class _PathLike:
    """An os.PathLike that is neither str nor Path."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __fspath__(self) -> str:
        return str(self.path)


@pytest.fixture(scope="module")
def fopdt() -> Model:
    return identify(RECORDS / "A.csv")


@pytest.fixture(scope="module")
def arx() -> Model:
    return identify(str(RECORDS / "C.csv"))


@pytest.fixture(scope="module")
def delayed(fopdt, tmp_path_factory) -> Model:
    """The FOPDT of A with a dead time of 2 s: 1 sample of 1.2 s and a fraction."""
    doc = fopdt.to_dict()
    doc["plant"]["schedule"]["dead_time_s"] = [2.0] * len(fopdt.plant.schedule.flow_m3h)
    path = tmp_path_factory.mktemp("delayed") / "fopdt_3F.json"
    path.write_text(json.dumps(doc))
    return load_model(path)


# --------------------------------------------------------------------------- model files


@pytest.mark.parametrize("name", ["fopdt_3F", "arx_3F", "physical_3F"])
def test_a_loaded_model_saves_byte_identical(name, tmp_path):
    model = load_model(_PathLike(MODELS / f"{name}.json"))
    out = model.save(_PathLike(tmp_path / "copy.json"))
    assert out.read_bytes() == (MODELS / f"{name}.json").read_bytes()
    assert load_model(out).sha256 == model.sha256


def test_an_identified_model_is_a_valid_model_file_and_reads_back_equal(fopdt, tmp_path):
    schema = json.loads((MODELS / "schema.json").read_text())
    jsonschema.validate(fopdt.to_dict(), schema)
    again = load_model(fopdt.save(tmp_path / "m.json"))
    assert again.to_dict() == fopdt.to_dict()
    assert again.sha256 == fopdt.sha256 and again.plant == fopdt.plant


def test_identify_accepts_a_record_a_str_and_a_pathlike():
    by_record = identify(read_record(RECORDS / "A.csv"))
    by_str = identify(str(RECORDS / "A.csv"))
    by_pathlike = identify(_PathLike(RECORDS / "A.csv"))
    assert by_record.sha256 == by_str.sha256 == by_pathlike.sha256


def test_identify_folder_takes_a_str_and_refuses_a_missing_folder(tmp_path):
    with pytest.raises(IdentificationError, match="not a folder"):
        identify_folder(str(tmp_path / "nowhere"))


def test_a_model_set_is_a_read_only_mapping_naming_what_it_lacks(fopdt):
    models = gatetwin.ModelSet({"fopdt_3F": fopdt})
    assert dict(models) == {"fopdt_3F": fopdt}
    with pytest.raises(KeyError, match="fopdt_3F"):
        models["arx_3F"]


# --------------------------------------------------------------------------- identification


def test_the_family_follows_the_test_type_and_the_gauge_defaults_to_3f(fopdt, arx):
    assert (fopdt.family, fopdt.gauge, fopdt.name) == ("fopdt", "3F", "fopdt_3F")
    assert (arx.family, arx.name, arx.plant.na, arx.plant.nb, arx.plant.nk) == (
        "arx",
        "arx_3F",
        2,
        2,
        1,
    )


def test_a_single_record_fopdt_matches_the_step_tests_fit(fopdt):
    from gatetwin.identification import identify_step

    onset = identify_step(read_record(RECORDS / "A.csv"), "3F").gauges["3F"].fit
    point = fopdt.at(*fopdt.operating_point())
    # two fits of one transient (onset model vs input-driven model): within 3 standard
    # errors of the onset fit, plus the schedule's rounding
    assert abs(point.gain_mm_per_mm - onset.gain_mm_per_mm) < 3 * onset.gain_se_mm_per_mm + 1e-4
    assert abs(point.time_constant_s - onset.time_constant_s) < 3 * onset.time_constant_se_s


def test_a_single_record_model_holds_over_the_records_discharge(fopdt):
    record = read_record(RECORDS / "A.csv")
    lo, hi = fopdt.plant.schedule.flow_range_m3h
    q = record.flow_m3h[np.isfinite(record.flow_m3h)]
    assert lo <= q.min() and q.max() <= hi


# 80-190 s (the storage is fitted twice, see below): a whole physical identification, which
# CI's slow subset already runs for the bundled folder (tests/test_models.py); this one runs
# with the long tests
@pytest.mark.long
@pytest.mark.slow
def test_a_physical_model_from_one_record_reads_the_static_table_beside_it(tmp_path):
    # the actuator's speed needs three gate moves or more: a PRBS test has them
    model = identify(RECORDS / "C.csv", family="physical", gauge="3F")
    assert model.family == "physical"
    doc = model.to_dict()
    assert doc["provenance"]["records"][0]["name"] == "C"
    # one record at one discharge spans too little depth for the area's slope: fitted, it
    # fell to the area's floor inside the static table's levels (a 25 % fit of the record
    # before); the fit says so and keeps a constant area, a model its reader accepts
    assert doc["plant"]["parameters"]["area_per_depth_m"] == 0.0
    assert (
        "fell to its floor" in doc["provenance"]["metrics"]["fit"]["fixed_from"]["area_per_depth_m"]
    )
    path = model.save(tmp_path / "c.json")
    assert load_model(path).plant.parameters["area_m2"] == doc["plant"]["parameters"]["area_m2"]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"family": "spline"}, "family must be one of"),
    ({"gauge": "9Z"}, "no gauge 9Z"),
])  # fmt: skip
def test_identify_refuses_with_one_line(kwargs, message):
    with pytest.raises(IdentificationError, match=message) as info:
        identify(RECORDS / "A.csv", **kwargs)
    assert "\n" not in str(info.value)


def test_a_physical_model_without_a_static_table_is_refused(tmp_path):
    for ext in (".csv", ".json"):
        (tmp_path / f"A{ext}").write_bytes((RECORDS / f"A{ext}").read_bytes())
    with pytest.raises(IdentificationError, match="static"):
        identify(tmp_path / "A.csv", family="physical")


# --------------------------------------------------------------------------- simulation


def test_simulate_is_the_reference_simulation(fopdt):
    from gatetwin.plant.simulate import simulate

    record = read_record(RECORDS / "A.csv")
    e = np.where(record.time_s < 180.0, 15.0, 20.0)
    q = np.full(record.n_samples, 29.5)
    result = fopdt.simulate(e, q, record.time_s)
    assert np.array_equal(result.level_mm, simulate(fopdt.plant, record.time_s, e, q))
    shifted = fopdt.simulate(e, q, record.time_s, level0=200.0)
    assert shifted.level_mm[0] == 200.0
    assert np.allclose(np.diff(shifted.level_mm), np.diff(result.level_mm), atol=ROUND_OFF_MM)


def test_simulate_builds_the_time_axis_from_the_sample_period(fopdt, arx):
    result = fopdt.simulate([15.0, 20.0, 20.0, 20.0], 29.5, sample_period_s=2.0)
    assert result.time_s.tolist() == [0.0, 2.0, 4.0, 6.0]
    q = arx.plant.schedule.flow_m3h[0]
    assert arx.simulate([35.0] * 5, q).time_s[1] == arx.plant.sample_period_s


@pytest.mark.parametrize(("args", "kwargs", "message"), [
    (([15.0, np.nan, 20.0], 29.5), {"sample_period_s": 1.2}, r"opening_mm\[1\] is nan"),
    (([15.0, 20.0], [29.5] * 3), {"sample_period_s": 1.2}, "opening_mm: expected .* 3 samples"),
    ((15.0, 29.5), {"sample_period_s": 1.2}, "at least 2 samples"),
    (([15.0, 20.0], 29.5), {}, "give time_s or sample_period_s"),
    (([15.0, 20.0], 29.5), {"time_s": [0.0, 0.0]}, r"time_s\[1\]"),
    (([15.0, 20.0], 29.5), {"time_s": [0.0, 1.0], "sample_period_s": 1.0}, "not both"),
])  # fmt: skip
def test_simulate_refuses_bad_inputs_with_one_line(fopdt, args, kwargs, message):
    with pytest.raises(SimulationError, match=message) as info:
        fopdt.simulate(*args, **kwargs)
    assert isinstance(info.value, ValueError) and "\n" not in str(info.value)


def test_to_pandas_says_when_pandas_is_missing(fopdt, monkeypatch):
    result = fopdt.simulate([15.0, 20.0], 29.5, sample_period_s=1.2)
    assert list(result.to_pandas()["level_3F_mm"]) == list(result.level_mm)
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(GatetwinError, match="pip install pandas"):
        result.to_pandas()


# --------------------------------------------------------------------------- linearisation


@pytest.mark.parametrize("name", ["fopdt_3F", "physical_3F", "arx_3F"])
def test_the_steady_level_of_at_is_where_the_simulation_settles(name):
    model = load_model(MODELS / f"{name}.json")
    q, e = model.operating_point()
    t = np.arange(0.0, 3600.0, 1.2)
    level = model.simulate(np.where(t < 60.0, e - 4.0, e), q, t).level_mm
    # an hour is > 20 time constants at every gauge: what is left is round-off
    assert level[-1] == pytest.approx(model.at(q, e).level_mm, abs=1e-6)


@pytest.mark.parametrize("dt", [1.2, 0.5, 2.0, 3.0])  # L = 2 s: fraction, whole, one, < dt
def test_the_discrete_transfer_function_is_the_simulation(delayed, dt):
    import control

    q, e0 = delayed.operating_point()
    t = np.arange(400) * dt
    e = np.where(t < 30.0, e0, e0 + 5.0)
    simulated = delayed.simulate(e, q, t).level_mm
    response = control.forced_response(delayed.to_control(dt=dt), t, e - e0)
    assert np.allclose(response.outputs, simulated - simulated[0], atol=ROUND_OFF_MM)


def test_without_dead_time_the_discrete_form_is_first_order(fopdt):
    assert fopdt.at(*fopdt.operating_point()).dead_time_s == 0.0
    g = fopdt.to_control(dt=1.2)
    assert len(g.poles()) == 1 and len(g.zeros()) == 0


def test_the_arx_transfer_function_is_the_simulation(arx):
    import control

    q = arx.plant.schedule.flow_m3h[0]
    e0 = arx.plant.opening_ref_mm
    t = np.arange(300) * arx.plant.sample_period_s
    e = np.where(t < 20.0, e0, e0 + 5.0)
    simulated = arx.simulate(e, q, t).level_mm
    g = arx.to_control()
    assert g.dt == arx.plant.sample_period_s
    response = control.forced_response(g, t, e - e0)
    assert np.allclose(response.outputs, simulated - simulated[0], atol=ROUND_OFF_MM)
    with pytest.raises(GatetwinError, match="resampling"):
        arx.to_control(dt=1.0)


@pytest.mark.parametrize("order", [1, 3, 5])
def test_the_continuous_form_keeps_k_and_has_the_pade_order(delayed, order):
    g = delayed.to_control(pade_order=order)
    point = delayed.at(*delayed.operating_point())
    assert g.dcgain() == pytest.approx(point.gain_mm_per_mm, rel=1e-12)
    assert len(g.poles()) == 1 + order
    assert g.input_labels == ["opening_mm"] and g.output_labels == ["level_3F_mm"]


def test_the_envelope_model_linearises_its_gate_law():
    from gatetwin.plant.model import local_fopdt

    model = load_model(MODELS / "fopdt_3F.json")
    point = model.at(50.0, 30.0)
    local = local_fopdt(model.plant, 50.0, 30.0)
    assert point.source == "envelope"
    assert (point.gain_mm_per_mm, point.time_constant_s) == (
        local["gain_mm_per_mm"],
        local["time_constant_s"],
    )


# --------------------------------------------------------------------------- FMU and validation


def _provenance(fmu: Path) -> dict:
    with zipfile.ZipFile(fmu) as zf:
        return json.loads(zf.read("resources/provenance.json"))


def test_export_carries_the_provenance_gatetwin_export_writes(fopdt, tmp_path):
    api_fmu = fopdt.export_fmu(_PathLike(tmp_path / "api" / "fopdt_3F.fmu"))
    model_file = fopdt.save(tmp_path / "fopdt_3F.json")
    cli_fmu = tmp_path / "cli" / "fopdt_3F.fmu"
    assert main(["export", str(model_file), "--backend", "c", "--out", str(cli_fmu)]) == 0
    assert _provenance(api_fmu) == _provenance(cli_fmu)
    assert _provenance(api_fmu)["model_file_sha256"] == fopdt.sha256


@pytest.mark.parametrize(
    ("backend", "fmi_version", "message"),
    [("c", "4.0", "fmi_version must be one of 2.0, 3.0"),
     ("python", "3.0", "FMI 3.0 FMUs are built by the C backend")],
)  # fmt: skip
def test_an_fmi_version_not_built_is_refused_with_one_line_and_no_file(
    fopdt, tmp_path, backend, fmi_version, message
):
    with pytest.raises(ExportError, match=message) as info:
        fopdt.export_fmu(tmp_path / "m.fmu", backend=backend, fmi_version=fmi_version)
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_validate_scores_an_fmu_as_the_harness_does(fopdt, tmp_path):
    from gatetwin.validation import matrix_cells, parse_thresholds, validate_fmu

    fmu = fopdt.export_fmu(tmp_path / "fopdt_3F.fmu")
    records = [RECORDS / "A.csv", str(RECORDS / "Q50.csv")]
    report = gatetwin.validate(str(fmu), records, fail_under={"fit_percent": 70})
    direct = validate_fmu(fmu, records, thresholds=parse_thresholds(["fit_percent=70"]))
    assert report.cells == matrix_cells(direct)
    # A is the record it was fitted on; Q50 is another discharge, far from its validity
    assert [c["passed"] for c in report.cells] == [c["passed"] for c in matrix_cells(direct)]
    assert report.passed == direct.passed
    assert list(report.to_pandas()["record"]) == ["A.csv", "Q50.csv"]
    assert "| fopdt_3F.fmu | A.csv |" in report.markdown()


def test_a_bad_threshold_is_refused(fopdt, tmp_path):
    from gatetwin.validation import ValidationError

    fmu = fopdt.export_fmu(tmp_path / "fopdt_3F.fmu")
    with pytest.raises(ValidationError):
        gatetwin.validate(fmu, RECORDS / "A.csv", fail_under=["fit_percent"])


# --------------------------------------------------------------------------- diagnosis


def test_diagnose_an_in_memory_model_as_its_saved_file(fopdt, tmp_path):
    path = fopdt.save(tmp_path / "fopdt_3F.json")
    in_memory = gatetwin.diagnose(RECORDS / "A.csv", fopdt)
    from_file = gatetwin.diagnose(str(RECORDS / "A.csv"), path)
    assert in_memory.named_effect == from_file.named_effect
    assert in_memory.rmse_before_mm == from_file.rmse_before_mm
    assert in_memory.to_dict()["named_effect"] == in_memory.named_effect


def test_diagnose_refuses_a_record_without_a_file():
    record = read_record(RECORDS / "A.csv")
    from gatetwin.records import record_from_arrays

    arrays = record_from_arrays(record.time_s, record.opening_mm, record.hold,
                                record.flow_m3h, dict(record.levels_mm))  # fmt: skip
    with pytest.raises(GatetwinError, match="no file"):
        gatetwin.diagnose(arrays)


# --------------------------------------------------------------------------- the package


def test_api_functions_and_stage_packages_have_their_own_names():
    import gatetwin.diagnosis.workflow
    import gatetwin.identification.suite
    import gatetwin.validation.harness  # noqa: F401
    from gatetwin.validation import validate_fmu

    assert callable(validate_fmu)
    for name in ("identify", "validate", "diagnose"):
        assert getattr(gatetwin, name).__module__.startswith("gatetwin.api"), name
    for name in ("identification", "validation", "diagnosis"):
        assert getattr(gatetwin, name) is sys.modules[f"gatetwin.{name}"], name


def test_all_lists_each_public_name_once():
    assert len(gatetwin.__all__) == len(set(gatetwin.__all__))
    assert all(hasattr(gatetwin, n) for n in gatetwin.__all__)


def test_a_bad_model_file_is_refused(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(ModelFileError, match="bad.json"):
        load_model(bad)


def test_a_free_record_needs_a_family_named():
    with pytest.raises(IdentificationError, match="no default family"):
        identify(RECORDS / "EflowLow.csv")


def test_importing_gatetwin_leaves_the_heavy_libraries_alone():
    import subprocess

    heavy = ("scipy", "matplotlib", "fmpy", "control", "numba", "casadi", "pandas")
    code = ("import sys, gatetwin; print(' '.join(m for m in " + repr(heavy)
            + " if m in sys.modules))")  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(Path(gatetwin.__file__).parents[1])},
    )
    assert done.stdout.strip() == ""
