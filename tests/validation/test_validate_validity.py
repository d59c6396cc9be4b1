"""Validity made visible: the FMU's envelope, records inside and outside it, the warning.

The envelope FMU is ``models/fopdt_3F.json`` in its local form (no ``envelope``, no stated
ranges, the Q range of its knots) exported through ``gatetwin export`` after adding
``validity.opening_range_mm = [15, 40]`` and ``validity.level_range_mm = [140, 370]`` to it,
so the whole path (model file -> FMU provenance -> harness) is exercised.
The bundled A record (openings 15 and 20 mm, Q 29.4-29.7 m³/h, level at 3F 148-232 mm) lies
inside; A with every logged opening lowered by 3 mm (12 and 17 mm) lies 3 mm below the
opening range, beyond the 1 mm actuator resolution that still counts as inside.
"""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path
from types import SimpleNamespace
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from fmu_support import compiler
from gatetwin.cli import main
from gatetwin.errors import ModelFileError
from gatetwin.fmu import export_fmu
from gatetwin.modelfile import validity_envelope
from gatetwin.plant import FopdtPlant, Schedule
from gatetwin.records import read_record
from gatetwin.run.stages import write_report
from gatetwin.validation import (
    VALIDITY_CHECK,
    ValidationError,
    matrix_cells,
    matrix_markdown,
    read_envelope,
    record_validity,
    validate_fmu,
)

ROOT = Path(__file__).resolve().parents[2]
RECORDS = ROOT / "src" / "gatetwin" / "data" / "records"
A = RECORDS / "A.csv"
MODEL = ROOT / "models" / "fopdt_3F.json"
BACKEND = "c" if compiler() else "python"
OPENING_RANGE_MM, LEVEL_RANGE_MM = [15.0, 40.0], [140.0, 370.0]
SHIFT_MM = 3.0


def _local_doc() -> dict:
    """``models/fopdt_3F.json`` in its local form: no envelope, validity on its knots only."""
    doc = json.loads(MODEL.read_text(encoding="utf-8"))
    doc["plant"].pop("envelope", None)
    for key in ("opening_range_mm", "level_range_mm"):
        doc["validity"].pop(key, None)
    knots = doc["plant"]["schedule"]["flow_m3h"]
    doc["validity"]["flow_m3h"] = [knots[0], knots[-1]]
    return doc


def _write(doc: dict, path: Path) -> Path:
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _model_with_ranges(folder: Path) -> Path:
    doc = _local_doc()
    doc["validity"]["opening_range_mm"] = OPENING_RANGE_MM
    doc["validity"]["level_range_mm"] = LEVEL_RANGE_MM
    path = folder / "fopdt_3F.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("validity")
    ranged, partial = folder / "ranged" / "fopdt_3F.fmu", folder / "partial" / "fopdt_3F.fmu"
    ranged.parent.mkdir()
    model = _model_with_ranges(ranged.parent)
    local = _write(_local_doc(), folder / "fopdt_3F_local.json")
    for src, out in ((model, ranged), (local, partial)):
        assert main(["export", str(src), "--backend", BACKEND, "--out", str(out)]) == 0
    plain = FopdtPlant("3F", 20.0, Schedule((29.5,), {
        "gain_mm_per_mm": (-15.4,), "time_constant_s": (71.0,), "dead_time_s": (2.0,),
        "level_ref_mm": (154.0,)}))  # fmt: skip
    bare = export_fmu(plain, folder / "bare.fmu", backend=BACKEND, model_name="bare",
                      provenance={"test": 1})  # fmt: skip
    return {"ranged": ranged, "partial": partial, "bare": bare}


def _shifted_record(folder: Path, shift_mm: float = -SHIFT_MM) -> Path:
    """A.csv with every logged opening moved by ``shift_mm`` (empty openings stay empty)."""
    lines = A.read_text(encoding="utf-8").splitlines()
    column = lines[0].split(",").index("opening_mm")
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        if cells[column]:
            cells[column] = f"{float(cells[column]) + shift_mm:g}"
        out.append(",".join(cells))
    path = folder / "A_low.csv"
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path


# --------------------------------------------------------------------------- the envelope


def test_envelope_comes_from_the_model_file_and_prefers_stated_ranges() -> None:
    doc = _local_doc()
    validity = doc["validity"]
    knots, band = validity["opening_mm_at_knots"], validity["opening_band_mm"]
    derived = validity_envelope(doc)
    assert derived == {"flow_m3h": validity["flow_m3h"],
                       "opening_mm": [min(knots) - band, max(knots) + band]}  # fmt: skip
    doc["validity"].update(opening_range_mm=[12, 33.5], level_range_mm=[150, 300.25])
    stated = validity_envelope(doc)
    assert stated["opening_mm"] == [12.0, 33.5] and stated["level_mm"] == [150.0, 300.25]
    doc["validity"]["level_range_mm"] = [300, 150]
    with pytest.raises(ModelFileError, match="level_range_mm: low 300 above high 150"):
        validity_envelope(doc)


def test_fmu_carries_the_envelope_and_the_harness_reads_it(fmus: dict[str, Path]) -> None:
    with zipfile.ZipFile(fmus["ranged"]) as archive:
        provenance = json.loads(archive.read("resources/provenance.json"))
    assert provenance["validity"]["opening_mm"] == OPENING_RANGE_MM
    assert provenance["validity"]["level_mm"] == LEVEL_RANGE_MM
    assert provenance["validity_flow_m3h"] == provenance["validity"]["flow_m3h"]
    envelope = read_envelope(fmus["ranged"])
    assert envelope == {q: tuple(r) for q, r in provenance["validity"].items()}
    assert "level_mm" not in read_envelope(fmus["partial"])
    assert read_envelope(fmus["bare"]) is None


def _with_provenance(tmp_path: Path, provenance: object) -> Path:
    path = tmp_path / "p.fmu"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("resources/provenance.json", json.dumps(provenance))
    return path


def test_earlier_fmus_state_the_flow_range_only_and_bad_ranges_are_refused(
    tmp_path: Path,
) -> None:
    legacy = _with_provenance(tmp_path, {"validity_flow_m3h": [30, 85]})
    assert read_envelope(legacy) == {"flow_m3h": (30.0, 85.0)}
    assert read_envelope(_with_provenance(tmp_path, ["not", "an", "object"])) is None
    bad = _with_provenance(tmp_path, {"validity": {"opening_mm": [40, "x"]}})
    with pytest.raises(ValidationError, match="validity range opening_mm must be"):
        read_envelope(bad)


def test_record_validity_distances_tolerances_and_unknowns() -> None:
    envelope = {"opening_mm": (15.0, 40.0), "flow_m3h": (30.0, 85.0), "level_mm": (100.0, 200.0)}
    opening = np.array([20.0, 25.0, 12.5, 30.0])
    flow = np.array([84.0, 85.4, 85.2, np.nan])  # 0.4 m³/h above: within the meter's accuracy
    level = np.array([150.0, 204.0, 190.0, 180.0])  # 4 mm above, noise SD 1 mm: 3 mm tolerance
    found = record_validity(envelope, opening, flow, level, level_noise_sd_mm=1.0)
    assert found.outside_by == pytest.approx({"opening_mm": 2.5, "flow_m3h": 0.4,
                                              "level_mm": 4.0})  # fmt: skip
    assert found.outside == ("opening_mm", "level_mm") and found.inside is False
    assert found.problems() == ["opening 12.5 mm below 15.0 mm", "level 204.0 mm above 200.0 mm"]
    relaxed = record_validity(envelope, opening, flow, level, level_noise_sd_mm=2.0)
    assert relaxed.outside == ("opening_mm",)
    inside = record_validity(envelope, opening + 5.0, flow, level - 10.0, 1.0)
    assert inside.inside is True and inside.outside_by["opening_mm"] == 0.0
    partial = record_validity({"flow_m3h": (30.0, 85.0)}, opening, flow, level, 1.0)
    assert partial.inside is None and partial.unknown == ("opening_mm", "level_mm")
    outside_by = partial.to_dict()["outside_by"]
    assert outside_by["opening_mm"] is None and outside_by["level_mm"] is None
    assert outside_by["flow_m3h"] == pytest.approx(0.4)
    assert record_validity(None, opening, flow, level, 1.0).to_dict()["validity"] is None


# --------------------------------------------------------------------------- the harness


def test_record_inside_and_outside_the_envelope(fmus: dict[str, Path], tmp_path: Path) -> None:
    low = _shifted_record(tmp_path)
    result = validate_fmu(fmus["ranged"], [A, low])
    inside, outside = result.records
    assert inside.inside_validity is True and outside.inside_validity is False
    record = read_record(A)
    hold_openings = record.opening_mm[record.hold]
    expected = OPENING_RANGE_MM[0] - (float(np.nanmin(hold_openings)) - SHIFT_MM)
    doc = outside.to_dict()
    assert doc["outside_by"]["opening_mm"] == pytest.approx(expected)
    assert doc["outside_by"]["flow_m3h"] == inside.to_dict()["outside_by"]["flow_m3h"]
    assert doc["validity"] == {"opening_mm": OPENING_RANGE_MM, "flow_m3h": [29.5, 85.0],
                               "level_mm": LEVEL_RANGE_MM}  # fmt: skip
    assert outside.passed, "outside is a warning unless it is enforced"
    cells = matrix_cells(result)
    assert [c["inside_validity"] for c in cells] == [True, False]
    assert cells[1]["outside_validity"] == ["opening 12.0 mm below 15.0 mm"]
    table = matrix_markdown(cells)
    assert "| inside |" in table and "outside: opening 12.0 mm below 15.0 mm" in table
    enforced = validate_fmu(fmus["ranged"], [A, low], fail_outside_validity=True)
    assert enforced.records[0].passed and not enforced.records[1].passed
    assert matrix_cells(enforced)[1]["failed_checks"] == [VALIDITY_CHECK]


def test_unknown_is_never_inside(fmus: dict[str, Path]) -> None:
    partial = validate_fmu(fmus["partial"], [A], fail_outside_validity=True).records[0]
    assert partial.inside_validity is None and partial.passed
    assert partial.to_dict()["validity_unknown"] == ["level_mm"]
    bare = validate_fmu(fmus["bare"], [A]).to_dict()
    assert bare["fmu"]["validity"] is None
    assert bare["records"][0]["inside_validity"] is None and bare["records"][0]["validity"] is None


# --------------------------------------------------------------------------- the command


def _run(fmu: Path, records: list[Path], tmp_path: Path, *extra: str) -> tuple[int, Path, Path]:
    json_path, junit = tmp_path / "out" / "v.json", tmp_path / "out" / "v.xml"
    code = main(["validate", str(fmu), *map(str, records), "--json", str(json_path),
                 "--junit", str(junit), *extra])  # fmt: skip
    return code, json_path, junit


def test_cli_warns_once_per_record_outside_and_still_passes(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    low = _shifted_record(tmp_path)
    code, json_path, junit = _run(fmus["ranged"], [A, low], tmp_path)
    captured = capsys.readouterr()
    assert code == 0 and captured.out.rstrip().endswith("passed")
    warnings = [line for line in captured.err.splitlines() if "warning" in line]
    assert warnings == ["gatetwin: warning: A_low.csv lies outside fopdt_3F.fmu's validity: "
                        "opening 12.0 mm below 15.0 mm"]  # fmt: skip
    doc = json.loads(json_path.read_text(encoding="utf-8"))
    for rec in doc["records"]:
        assert {"inside_validity", "validity", "outside_by", "noise_floor", "fit_vs_floor"} <= (
            rec.keys()
        )
    assert [r["inside_validity"] for r in doc["records"]] == [True, False]
    props = {p.get("name"): p.get("value") for p in ET.parse(junit).getroot().iter("property")}
    assert props["A.csv: inside_validity"] == "true"
    assert props["A_low.csv: inside_validity"] == "false"


def test_cli_fail_outside_validity_exits_1(
    fmus: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    low = _shifted_record(tmp_path)
    code, json_path, junit = _run(fmus["ranged"], [A, low], tmp_path, "--fail-outside-validity")
    captured = capsys.readouterr()
    assert code == 1 and "FAILED" in captured.out
    assert re.search(r"A_low.csv lies outside .* opening 12.0 mm below 15.0 mm", captured.err)
    doc = json.loads(json_path.read_text(encoding="utf-8"))
    assert [r["passed"] for r in doc["records"]] == [True, False]
    assert doc["records"][1]["validity_failed"] is True
    failures = ET.parse(junit).getroot().findall(".//failure")
    assert [f.get("type") for f in failures] == ["OutsideValidity"]
    assert "opening 12.0 mm below 15.0 mm" in failures[0].get("message")
    code, *_ = _run(fmus["ranged"], [A], tmp_path, "--fail-outside-validity")
    assert code == 0


def test_report_shows_floor_and_validity(fmus: dict[str, Path], tmp_path: Path) -> None:
    cells = matrix_cells(validate_fmu(fmus["ranged"], [A, _shifted_record(tmp_path)]))
    ctx = SimpleNamespace(results={"validation": [{"backend": BACKEND, **c} for c in cells]},
                          out_dir=tmp_path)  # fmt: skip
    write_report(ctx)
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "noise floor fit %" in html and "fit − floor (points)" in html
    assert "outside: opening 12.0 mm below 15.0 mm" in html
    assert f"{cells[0]['noise_floor_fit_percent']:.4g}" in html
