"""FMU export: valid FMUs, one description behind both backends, provenance, atomic failure."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import zipfile
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest
from fmpy.validation import validate_fmu

from fmu_support import BACKENDS, FAMILIES, PLANTS, PROVENANCE, compiler
from gatetwin.errors import ExportError
from gatetwin.fmu import export_fmu
from gatetwin.fmu.description import describe, model_config_header

needs_cc = pytest.mark.skipif(compiler() is None, reason="no C compiler (cc/gcc) on PATH")


@pytest.fixture(scope="module")
def fmus(test_plant_fmus) -> dict[tuple[str, str], Path]:
    return test_plant_fmus


def _xml(path: Path) -> ET.Element:
    with zipfile.ZipFile(path) as zf:
        return ET.fromstring(zf.read("modelDescription.xml"))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("family", FAMILIES)
def test_fmpy_validation_finds_no_problem(fmus, backend, family):
    assert validate_fmu(str(fmus[backend, family])) == []


@pytest.mark.parametrize("family", FAMILIES)
def test_both_backends_declare_the_same_variables(fmus, family):
    def variables(path):
        return [(sv.attrib, sv.find("Real").attrib) for sv in _xml(path).find("ModelVariables")]

    c_vars, py_vars = variables(fmus["c", family]), variables(fmus["python", family])
    assert c_vars == py_vars
    for attrib, real in c_vars:
        assert attrib["description"] and real["unit"] in {"mm", "m3/h", "s", "mm/mm"}
    names = [a["name"] for a, _ in c_vars]
    assert names[:3] == ["opening_mm", "flow_m3h", "level_3F_mm"]
    assert [int(a["valueReference"]) for a, _ in c_vars] == list(range(len(c_vars)))
    assert "schedule.flow_m3h[3]" in names or family == "arx"


@pytest.mark.parametrize("family", FAMILIES)
def test_capability_flags_are_declared_truthfully(fmus, family):
    c_cs = _xml(fmus["c", family]).find("CoSimulation").attrib
    py_cs = _xml(fmus["python", family]).find("CoSimulation").attrib
    assert c_cs["needsExecutionTool"] == "false" and py_cs["needsExecutionTool"] == "true"
    for cs in (c_cs, py_cs):
        assert cs["canHandleVariableCommunicationStepSize"] == "true"
        assert cs["canGetAndSetFMUstate"] == "true"
        assert cs["canSerializeFMUstate"] == "true"
        assert cs["modelIdentifier"] == f"gate_3F_{family}"


@pytest.mark.parametrize("backend", BACKENDS)
def test_provenance_travels_inside_the_fmu(fmus, backend):
    path = fmus[backend, "fopdt"]
    with zipfile.ZipFile(path) as zf:
        assert json.loads(zf.read("resources/provenance.json")) == PROVENANCE
        plant = json.loads(zf.read("resources/plant.json"))
    assert plant["plant"]["kind"] == "fopdt" and plant["fmu"]["backend"] == backend
    description = _xml(path).get("description")
    assert "model_file_sha256=9f2c4e0d5b7a" in description
    assert "fit.r2=0.987" in description and "[30, 85] m3/h" in description


def test_python_fmu_runs_where_gatetwin_cannot_be_imported(fmus):
    script = (
        "import sys; sys.modules['gatetwin'] = None\n"  # any 'import gatetwin' now fails
        "from fmpy import simulate_fmu\n"
        f"r = simulate_fmu({str(fmus['python', 'fopdt'])!r}, stop_time=10.0, output_interval=1.0)\n"
        "print(r['level_3F_mm'][-1])\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr[-1500:]
    # start values hold the plant at rest: level_ref at Q = 57.5 m3/h, 300 + 2.5 / 30 * 60
    assert float(run.stdout.split()[-1]) == pytest.approx(305.0, abs=1e-9)


def test_c_fmu_ships_sources_that_rebuild(fmus, tmp_path):
    path = fmus["c", "arx"]
    with zipfile.ZipFile(path) as zf:
        zf.extractall(tmp_path)
    listed = [f.get("name") for f in _xml(path).iter("File")]
    assert listed == [
        "fmi2_glue.c",
        "glue_core.c",
        "component.c",
        "plant.c",
        "support.c",
        "effects.c",
        "blocks.c",
        "model_arx.c",
    ]
    build_line = (tmp_path / "sources" / "BUILD.txt").read_text().splitlines()[2].split()
    assert "-Werror" in build_line and "-fvisibility=hidden" in build_line
    build_line[0] = compiler()
    subprocess.run(build_line, cwd=tmp_path / "sources", check=True, capture_output=True)
    rebuilt = tmp_path / "sources" / "gate_3F_arx.so"
    assert rebuilt.stat().st_size > 0
    if shutil.which("nm"):
        symbols = subprocess.run(
            ["nm", "-D", "--defined-only", str(rebuilt)], capture_output=True, text=True, check=True
        ).stdout.split()
        exported = [s for s in symbols if re.fullmatch(r"[A-Za-z_]\w*", s) and len(s) > 1]
        assert exported and all(s.startswith("fmi2") for s in exported)


def test_model_config_header_carries_the_description_value_references():
    desc = describe(PLANTS["fopdt"](), "gate_3F_fopdt", PROVENANCE, "c")
    header = model_config_header(desc)
    assert f"#define VR_OPENING_MM {desc.vr('opening_mm')}" in header
    assert f"#define VR_COL_DEAD_TIME_S {desc.vr('schedule.dead_time_s[1]')}" in header
    assert header.count('    X("') == len(desc.variables)


def test_missing_compiler_is_one_clear_error_and_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "")
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    out = tmp_path / "model.fmu"
    with pytest.raises(ExportError, match=r"no C compiler found \(looked for \$CC, cc, gcc\)"):
        export_fmu(PLANTS["fopdt"](), out, backend="c", model_name="m", provenance={})
    assert list(tmp_path.iterdir()) == []


@needs_cc
def test_failing_compiler_leaves_the_previous_fmu_in_place(tmp_path, monkeypatch):
    out = tmp_path / "model.fmu"
    out.write_bytes(b"previous")
    monkeypatch.setenv("CC", shutil.which("false") or "false")
    with pytest.raises(ExportError, match="C compiler .* failed"):
        export_fmu(PLANTS["arx"](), out, backend="c", model_name="m", provenance={})
    assert out.read_bytes() == b"previous"
    assert [p.name for p in tmp_path.iterdir()] == ["model.fmu"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"backend": "java"}, "backend must be one of c, python"),
        ({"model_name": "3-gauge"}, "must be a C identifier"),
        ({"provenance": {"r2": float("nan")}}, "provenance must be JSON"),
        ({"out": "model.zip"}, "must end in .fmu"),
        ({"plant": "arx9"}, r"orders \(na, nb, nk\) = \(9, 2, 1\) exceed 8"),
        ({"plant": "not a plant"}, "expected FopdtPlant, ArxPlant or PhysicalPlant"),
    ],
)
def test_bad_requests_raise_export_error(tmp_path, change, message):
    args = {
        "backend": "python",
        "model_name": "m",
        "provenance": {},
        "out": "m.fmu",
        "plant": PLANTS["fopdt"](),
    }
    args.update(change)
    if args["plant"] == "arx9":
        arx = PLANTS["arx"]()
        columns = {**arx.schedule.values, **{f"a{i}": (0.01, 0.01) for i in range(3, 10)}}
        args["plant"] = replace(arx, na=9, schedule=replace(arx.schedule, values=columns))
    out = tmp_path / args.pop("out")
    with pytest.raises(ExportError, match=message):
        export_fmu(args.pop("plant"), out, **args)
    assert list(tmp_path.iterdir()) == []


@needs_cc
def test_c_export_to_a_relative_path(tmp_path, monkeypatch):
    # the compiler runs in the FMU's sources folder; a relative --out must still land
    monkeypatch.chdir(tmp_path)
    out = export_fmu(PLANTS["fopdt"](), Path("rel") / "m.fmu", backend="c", model_name="m",
                     provenance=PROVENANCE)  # fmt: skip
    assert (tmp_path / "rel" / "m.fmu").is_file() and out.name == "m.fmu"
