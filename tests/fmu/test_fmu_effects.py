"""Effect blocks in every FMU rendering: C FMU, pythonfmu FMU and the Python reference agree
within 1e-9 mm for plants with each effect (driven through fmpy), the FMUs validate, carry the
blocks' state in their FMU states and refuse out-of-range block parameters."""

from __future__ import annotations

import subprocess
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
    BACKENDS,
    PLANTS,
    compile_host,
    compiler,
    driven_inputs,
    extract_all,
    fmu_run,
    open_fmu,
    reference_run,
)
from gatetwin.fmu import export_fmu
from gatetwin.fmu.c_build import source_files
from gatetwin.plant.effects import KINDS, effect_dict
from test_fmu_dynamic import _asan_works, _guid_and_vrs

TOL_MM = 1e-9
#: (family, kind) of every exported test plant; "all" carries every block its family can.
CASES = [("fopdt", k) for k in (*KINDS, "all")] + [
    ("arx", k) for k in (*KINDS, "all") if k != "flow_dependent_gain"
]


def plant_with(family: str, kind: str):
    kinds = [k for k in KINDS if family == "fopdt" or k != "flow_dependent_gain"]
    chosen = kinds if kind == "all" else [kind]
    return replace(PLANTS[family](), effects=tuple(effect_dict(k, **EXAMPLES[k]) for k in chosen))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[tuple[str, str, str], Path]:
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("effect_fmus")
    built = {
        (backend, family, kind): export_fmu(
            plant_with(family, kind), folder / f"{family}_{kind}_{backend}.fmu",
            backend=backend, model_name=f"gate_{family}_fx", provenance={"test": kind},
        )
        for backend in BACKENDS for family, kind in CASES
    }  # fmt: skip
    return built


@pytest.fixture(scope="module")
def extracted(fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("effect_fmus_x")
    flat = {(f"{b}-{fam}-{k}", ""): p for (b, fam, k), p in fmus.items()}
    out = extract_all(flat, folder)
    return {tuple(key[0].split("-")): path for key, path in out.items()}


@pytest.mark.parametrize(("family", "kind"), CASES)
def test_both_fmus_follow_the_reference(extracted, family, kind):
    times, opening, flow = driven_inputs(family, 800, seed=11)
    reference = reference_run(plant_with(family, kind), times, opening, flow)
    for backend in BACKENDS:
        driver = open_fmu(extracted[backend, family, kind])
        try:
            levels = fmu_run(driver, times, opening, flow)
        finally:
            driver.close()
        assert np.max(np.abs(levels - reference)) <= TOL_MM, backend
    bare = reference_run(PLANTS[family](), times, opening, flow)
    assert np.max(np.abs(reference - bare)) > 1.0  # the block really acts


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("family", ["fopdt", "arx"])
def test_fmpy_validation_finds_no_problem_with_every_block(fmus, backend, family):
    assert validate_fmu(str(fmus[backend, family, "all"])) == []


def test_block_parameters_are_declared_from_the_one_description(fmus):
    with zipfile.ZipFile(fmus["c", "fopdt", "all"]) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    declared = {sv.get("name"): sv for sv in root.find("ModelVariables")}
    for kind in KINDS:
        for name in EXAMPLES[kind]:
            sv = declared[f"effect.{kind}.{name}"]
            assert sv.get("causality") == "parameter" and sv.get("variability") == "tunable"
            assert float(sv.find("Real").get("start")) == EXAMPLES[kind][name]
    assert declared["effect.actuator_rate_limit.substep_s"].get("variability") == "fixed"


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("family", ["fopdt", "arx"])
def test_block_state_travels_in_serialized_fmu_states(extracted, backend, family):
    times, opening, flow = driven_inputs(family, 200, seed=12)
    first = open_fmu(extracted[backend, family, "all"], "first")
    second = open_fmu(extracted[backend, family, "all"], "second")
    try:
        fmu_run(first, times[:100], opening[:100], flow[:100])
        state = first.slave.getFMUstate()
        data = first.slave.serializeFMUstate(state)
        first.slave.freeFMUstate(state)
        restored = second.slave.deSerializeFMUstate(data)
        second.slave.setFMUstate(restored)
        second.slave.freeFMUstate(restored)
        second.time_s = first.time_s
        for i in range(100, 200):
            args = (times[i] - times[i - 1], opening[i - 1], flow[i - 1])
            assert second.step(*args) == first.step(*args)
    finally:
        first.close()
        second.close()


@pytest.mark.parametrize("backend", BACKENDS)
def test_out_of_range_block_parameter_is_refused(extracted, backend):
    driver = open_fmu(extracted[backend, "fopdt", "all"])
    try:
        driver.start(20.0, 50.0)
        driver.slave.setReal([driver.vr["effect.seiche.period_s"]], [-3.0])
        with pytest.raises(FMICallException):
            driver.step(1.2, 20.0, 50.0)
        assert any("effect.seiche.period_s = -3 must be > 0" in m for _, m in driver.messages)
    finally:
        driver.close()


def test_tuning_a_block_parameter_changes_the_run_as_in_the_reference(extracted):
    times, opening, flow = driven_inputs("fopdt", 300, seed=13)
    plant = plant_with("fopdt", "seiche")
    tuned = replace(
        plant,
        effects=(effect_dict("seiche", **{**EXAMPLES["seiche"], "amplitude_mm_per_mm": 2.5}),),
    )
    reference = reference_run(tuned, times, opening, flow)
    for backend in BACKENDS:
        driver = open_fmu(extracted[backend, "fopdt", "seiche"])
        try:
            driver.slave.setReal([driver.vr["effect.seiche.amplitude_mm_per_mm"]], [2.5])
            levels = fmu_run(driver, times, opening, flow)
        finally:
            driver.close()
        assert np.max(np.abs(levels - reference)) <= TOL_MM, backend


@pytest.mark.parametrize("family", ["fopdt", "arx"])
def test_effect_blocks_are_clean_under_address_sanitizer(extracted, tmp_path, family):
    """The C FMU with every block through a thousand lifecycles under ASan/UBSan."""
    if not _asan_works(tmp_path):
        pytest.skip("-fsanitize=address does not build or run here")
    sources = extracted["c", family, "all"] / "sources"
    flags = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all")
    fmu = tmp_path / "fmu_asan.so"
    subprocess.run(
        [compiler(), "-std=c99", "-O1", "-g", "-fPIC", "-shared", "-fvisibility=hidden",
         "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", *flags, "-o", str(fmu),
         *source_files(family), "-lm"],
        cwd=sources, check=True, capture_output=True,
    )  # fmt: skip
    host = tmp_path / "host_asan"
    compile_host(sources, host, flags)
    vrs = _guid_and_vrs(extracted["c", family, "all"])
    run = subprocess.run([str(host), str(fmu), *vrs, "1.2", "1000"],
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
