"""FMI 3.0 co-simulation FMUs: every family and the effect blocks, from the description the
FMI 2.0 FMU is built from.

The FMI 3.0 and FMI 2.0 C FMUs compile the same component (plant.c, the family, the effect
blocks, the generated code) with the same flags; only the glue differs. So their outputs must
be equal to the bit, not merely close: any difference would be a glue that moves a value.
"""

from __future__ import annotations

import zipfile
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from effect_cases import EXAMPLES
from fmu_support import (
    arx_plant,
    compiler,
    driven_inputs,
    extract_all,
    fmu_run,
    fopdt_plant,
    open_fmu,
)
from gatetwin.cli import main
from gatetwin.fmu import export_fmu
from gatetwin.modelfile import read_model_file
from gatetwin.plant.effects import KINDS, effect_dict

MODELS = Path(__file__).resolve().parents[2] / "models"


def _with_every_block():
    effects = tuple(effect_dict(k, **EXAMPLES[k]) for k in KINDS)
    return replace(fopdt_plant(), effects=effects)


#: name -> (plant factory, family used for the inputs' time grid)
PLANTS = {
    "fopdt_local": (fopdt_plant, "fopdt"),
    "arx_local": (arx_plant, "arx"),
    "fopdt_envelope": (lambda: read_model_file(MODELS / "fopdt_3F.json").plant, "fopdt"),
    "arx_envelope": (lambda: read_model_file(MODELS / "arx_3F.json").plant, "arx"),
    "physical": (lambda: read_model_file(MODELS / "physical_3F.json").plant, "fopdt"),
    "fopdt_every_block": (_with_every_block, "fopdt"),
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[tuple[str, str], Path]:
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("fmi3")
    return {
        (name, version): export_fmu(
            make(), folder / version / f"{name}.fmu", backend="c", model_name=f"gate_{name}",
            provenance={"test": name}, fmi_version=version,
        )
        for name, (make, _) in PLANTS.items() for version in ("2.0", "3.0")
    }  # fmt: skip


@pytest.fixture(scope="module")
def extracted(fmus, tmp_path_factory):
    return extract_all(fmus, tmp_path_factory.mktemp("fmi3_x"))


@pytest.mark.parametrize("name", PLANTS)
def test_fmi3_fmu_passes_fmpy_validation(fmus, name):
    assert validate_fmu(str(fmus[name, "3.0"])) == []


@pytest.mark.parametrize("name", PLANTS)
def test_fmi3_and_fmi2_fmus_give_identical_outputs(extracted, name):
    times, opening, flow = driven_inputs(PLANTS[name][1], 400, seed=3)
    runs = {}
    for version in ("2.0", "3.0"):
        driver = open_fmu(extracted[name, version], f"{name}_{version}", logging_on=False)
        try:
            runs[version] = fmu_run(driver, times, opening, flow)
        finally:
            driver.close()
    assert np.all(np.isfinite(runs["3.0"]))
    assert np.array_equal(runs["3.0"], runs["2.0"])


def test_both_descriptions_declare_the_same_variables(fmus):
    """One description, two renderings: names, value references, causality, variability,
    units and start values agree; FMI 3.0 adds its independent variable ``time``."""

    def variables(path: Path, tag: str) -> dict[str, dict[str, str]]:
        with zipfile.ZipFile(path) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
        found = {}
        for element in root.find("ModelVariables"):
            attrs = dict(element.attrib)
            if tag == "ScalarVariable":
                attrs.update(element.find("Real").attrib)
            attrs.pop("description", None)
            found[attrs.pop("name")] = attrs
        return found

    two = variables(fmus["fopdt_every_block", "2.0"], "ScalarVariable")
    three = variables(fmus["fopdt_every_block", "3.0"], "Float64")
    time = three.pop("time")
    assert time["causality"] == "independent" and int(time["valueReference"]) == len(two)
    assert three == two


@pytest.mark.parametrize("name", ["fopdt_every_block", "arx_envelope", "physical"])
def test_fmi3_state_round_trips_through_serialization(extracted, name):
    times, opening, flow = driven_inputs(PLANTS[name][1], 200, seed=12)
    first = open_fmu(extracted[name, "3.0"], "first")
    second = open_fmu(extracted[name, "3.0"], "second")
    try:
        fmu_run(first, times[:100], opening[:100], flow[:100])
        state = first.slave.getFMUState()
        data = first.slave.serializeFMUState(state)
        first.slave.freeFMUState(state)
        fmu_run(second, times[:3], opening[:3], flow[:3])  # a different history, overwritten
        restored = second.slave.deserializeFMUState(data)
        second.slave.setFMUState(restored)
        second.slave.freeFMUState(restored)
        second.time_s = first.time_s
        for i in range(100, 200):
            args = (times[i] - times[i - 1], opening[i - 1], flow[i - 1])
            assert second.step(*args) == first.step(*args)
    finally:
        first.close()
        second.close()


def test_fmi3_bad_calls_return_error_with_a_logged_reason(extracted):
    driver = open_fmu(extracted["fopdt_local", "3.0"], "bad")
    try:
        driver.start(20.0, 50.0)
        with pytest.raises(FMICallException) as info:
            driver.slave.setFloat64([driver.vr["opening_mm"]], [float("nan")])
        assert info.value.status == 3  # fmi3Error
        assert "opening_mm" in driver.messages[-1][1] and driver.messages[-1][0] == 3
        driver.slave.reset()  # out of the error state, as the FMI 3.0 standard allows
        with pytest.raises(FMICallException) as info:
            driver.slave.setFloat64([len(driver.vr) - 1], [5.0])  # `time`: independent
        assert info.value.status == 3
        assert "independent" in driver.messages[-1][1]
    finally:
        driver.close()


def test_fmi3_time_is_the_fmus_time(extracted):
    driver = open_fmu(extracted["fopdt_local", "3.0"], "time")
    try:
        driver.start(20.0, 50.0, start_s=10.0)
        driver.step(2.5, 20.0, 50.0)
        assert driver.slave.getFloat64([len(driver.vr) - 1]) == [12.5]
    finally:
        driver.close()


def test_export_command_writes_fmi3_and_validate_runs_it(tmp_path, capsys):
    from gatetwin.bundled import bundled_records_dir

    out = {}
    for fmi in ("2", "3"):
        fmu = tmp_path / f"fopdt_3F_{fmi}.fmu"
        assert main(["export", str(MODELS / "fopdt_3F.json"), "--backend", "c", "--fmi", fmi,
                     "--out", str(fmu)]) == 0  # fmt: skip
        report = tmp_path / f"v{fmi}.json"
        record = bundled_records_dir() / "Q55.csv"
        assert main(["validate", str(fmu), str(record), "--json", str(report)]) == 0
        import json

        out[fmi] = json.loads(report.read_text(encoding="utf-8"))
    assert out["3"]["fmu"]["fmi_version"] == "3.0" and out["2"]["fmu"]["fmi_version"] == "2.0"
    assert out["3"]["records"][0]["metrics"] == out["2"]["records"][0]["metrics"]
    assert main(["export", str(MODELS / "fopdt_3F.json"), "--backend", "python", "--fmi", "3",
                 "--out", str(tmp_path / "p.fmu")]) == 2  # fmt: skip
    assert "C backend" in capsys.readouterr().err
    assert not (tmp_path / "p.fmu").exists()


def test_fmi3_warns_once_outside_the_schedule_as_the_fmi2_fmu_does(extracted):
    """The status contract's first row in FMI 3.0: a discharge beyond the knots is a warning
    (status 1, logged once per instance), and the step goes on."""
    from ctypes import byref

    from fmpy.fmi3 import fmi3Boolean, fmi3Float64

    driver = open_fmu(extracted["fopdt_local", "3.0"], "warn")
    try:
        driver.start(20.0, 50.0)
        driver.set_inputs(20.0, 100.0)  # the knots end at 85 m3/h
        flags = [fmi3Boolean() for _ in range(3)]
        last = fmi3Float64()
        status = driver.slave.fmi3DoStep(driver.slave.component, 0.0, 1.0, fmi3Boolean(True),
                                         *(byref(f) for f in flags), byref(last))  # fmt: skip
        assert status == 1 and last.value == 1.0
        warnings = [text for level, text in driver.messages if level == 1]
        assert len(warnings) == 1 and "outside the schedule" in warnings[0]
        status = driver.slave.fmi3DoStep(driver.slave.component, 1.0, 1.0, fmi3Boolean(True),
                                         *(byref(f) for f in flags), byref(last))  # fmt: skip
        assert status == 0  # warned once per instance
    finally:
        driver.close()


def test_both_versions_carry_one_binary_built_once(tmp_path, monkeypatch):
    """A plant's FMI 2.0 and 3.0 FMUs carry one binary with both glues compiled in: given
    one ``builds`` dict, the second export takes the first's binary (one compiler run, the
    same bytes and file mode), another plant compiles its own, and the binary answers to
    both versions' function names."""
    import ctypes

    import gatetwin.fmu.c_build as c_build

    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    runs = []
    compile_shared = c_build.compile_shared
    monkeypatch.setattr(c_build, "compile_shared",
                        lambda *a, **k: runs.append(a) or compile_shared(*a, **k))  # fmt: skip
    builds: dict = {}
    binaries = {}
    for name, plant, version in (("a", fopdt_plant(), "2.0"), ("a", fopdt_plant(), "3.0"),
                                 ("b", arx_plant(), "2.0")):  # fmt: skip
        fmu = export_fmu(plant, tmp_path / f"{name}{version}.fmu", backend="c",
                         model_name=name, provenance={}, fmi_version=version,
                         builds=builds)  # fmt: skip
        with zipfile.ZipFile(fmu) as z:
            (info,) = (i for i in z.infolist() if i.filename.startswith("binaries/"))
            binaries[name, version] = (z.read(info), info.external_attr >> 16)
    assert len(runs) == 2 and len(builds) == 2
    assert binaries["a", "2.0"] == binaries["a", "3.0"]
    assert binaries["b", "2.0"][0] != binaries["a", "2.0"][0]
    library = tmp_path / Path(info.filename).name
    library.write_bytes(binaries["a", "2.0"][0])
    loaded = ctypes.CDLL(str(library))
    assert all(hasattr(loaded, f) for f in ("fmi2DoStep", "fmi3DoStep", "fmi2Instantiate",
                                             "fmi3InstantiateCoSimulation"))  # fmt: skip
