"""Model files that break the limits are refused in one line before anything is built.

Each reported case is a test: control characters and lone surrogates in text, an over-long
gauge name, ARX orders that are huge, fractional or written as floats, gains and reference
openings that overflow the output, sections of the wrong type, deep nesting.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from fmu_support import PLANTS, PROVENANCE, assert_well_formed, compiler
from gatetwin.cli import main
from gatetwin.errors import ExportError, ModelFileError
from gatetwin.fmu import export_fmu
from gatetwin.modelfile import read_model_file
from gatetwin.modelschema import (
    MAX_DEPTH,
    SHOW_CHARS,
    check_model_document,
    model_schema,
)
from gatetwin.plant.model import ARX_ORDER_LIMIT, plant_from_dict

MODELS = Path(__file__).resolve().parents[1] / "models"
#: Longest refusal line accepted: the message names the file and the field and quotes at
#: most SHOW_CHARS characters of the value (plus escapes and the fixed wording).
MAX_LINE_CHARS = 400


def _doc(name: str) -> dict[str, Any]:
    return json.loads((MODELS / f"{name}.json").read_text(encoding="utf-8"))


def _set(doc: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    *head, last = path.split(".")
    node = doc
    for key in head:
        node = node[key]
    node[last] = value
    return doc


def _export(path: Path, tmp_path: Path, capsys) -> tuple[int, str]:
    out = tmp_path / "out" / "m.fmu"
    code = main(["export", str(path), "--backend", "c", "--out", str(out)])
    err = capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    return code, err


#: (model, field path, bad value, words the refusal must hold)
CASES = [
    ("fopdt_3F", "plant.gauge", "3F\x01<&", ["plant.gauge", "control character U+0001"]),
    ("fopdt_3F", "gauge", "3F\x1b[31m", ["gauge", "control character U+001B"]),
    ("fopdt_3F", "provenance.method", "fit\x00ted", ["provenance.method", "U+0000"]),
    ("fopdt_3F", "plant.gauge", "3F\ud800", ["plant.gauge", "lone surrogate U+D800"]),
    ("fopdt_3F", "provenance.method", "a\udfffb", ["provenance.method", "lone surrogate"]),
    ("fopdt_3F", "plant.gauge", "G" * 1_000_000, ["plant.gauge", "1000000 characters"]),
    ("fopdt_3F", "plant.gauge", "3F-x", ["plant.gauge", "does not match"]),
    ("arx_3F", "plant.na", 10**12, ["plant.na", "is above the limit 50"]),
    ("arx_3F", "plant.na", 1e12, ["plant.na", "not a JSON integer"]),
    ("arx_3F", "plant.na", 1_000_000, ["plant.na: 1000000 is above the limit 50"]),
    ("arx_3F", "plant.na", 2.9, ["plant.na: 2.9 is not a JSON integer"]),
    ("arx_3F", "plant.nk", 2.0, ["plant.nk: 2.0 is not a JSON integer"]),
    ("arx_3F", "plant.nb", True, ["plant.nb: true is not a JSON integer"]),
    ("fopdt_3F", "plant.schedule.gain_mm_per_mm", [1e308] * 6,
     ["plant.schedule.gain_mm_per_mm[0]", "above the limit 1000"]),
    ("fopdt_3F", "plant.opening_ref_mm", 1e308, ["plant.opening_ref_mm", "above the limit 50000"]),
    ("arx_3F", "plant.opening_ref_mm", -1e308, ["plant.opening_ref_mm", "below the limit 0"]),
    ("physical_3F", "plant.parameters.area_m2", 1e308,
     ["plant.parameters.area_m2", "above the limit"]),
    ("fopdt_3F", "provenance", 5, ["provenance: 5 is not an object"]),
    ("fopdt_3F", "provenance", [1, 2], ["provenance: a list is not an object"]),
    ("fopdt_3F", "validity", "wide", ["validity: 'wide' is not an object"]),
    ("fopdt_3F", "validity.flow_m3h", [20.0], ["validity.flow_m3h", "fewer than the 2"]),
    ("fopdt_3F", "provenance.records", {"a": 1}, ["provenance.records", "not a list"]),
    ("fopdt_3F", "plant.kind", "neural", ["plant.kind", "not one of fopdt, arx, physical"]),
]  # fmt: skip


@pytest.mark.parametrize(("model", "field", "value", "words"), CASES)
def test_bad_field_is_refused_in_one_line_naming_it(tmp_path, capsys, model, field, value,
                                                    words):  # fmt: skip
    path = tmp_path / "m.json"
    path.write_text(json.dumps(_set(_doc(model), field, value)), encoding="utf-8")
    code, err = _export(path, tmp_path, capsys)
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"gatetwin: error: {path}: "), err[:500]
    assert len(lines[0]) <= MAX_LINE_CHARS
    for word in words:
        assert word in lines[0], (word, lines[0])


def test_a_bad_value_is_quoted_at_most_show_chars_long(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps(_set(_doc("fopdt_3F"), "plant.gauge", "ab\x07" + "x" * 3000)))
    with pytest.raises(ModelFileError) as info:
        read_model_file(path)
    quoted = str(info.value).split("'")[1]
    assert len(quoted) <= SHOW_CHARS and "x" * (SHOW_CHARS + 1) not in str(info.value)


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 100_000])
def test_deep_nesting_is_one_line(tmp_path, capsys, depth):
    path = tmp_path / "m.json"
    doc = json.dumps(_doc("fopdt_3F"))
    nested = "[" * depth + "]" * depth
    path.write_text(doc[:-1] + f', "extra": {nested}}}', encoding="utf-8")
    code, err = _export(path, tmp_path, capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert "nest" in err and "32" in err


@pytest.mark.parametrize(
    ("text", "words"),
    [('{"schema_version": "1.0", "a": NaN}', "NaN is not a number"),
     ('{"schema_version": "1.0", "a": 1e999}', "not a finite number"),
     ('{"schema_version": "1.0", "a": 1, "a": 2}', "appears twice"),
     ('{"schema_version": "1.0", "a": ' + "9" * 5000 + "}", "not a JSON model file"),
     ("\ufeff{}", "not a JSON model file")],
)  # fmt: skip
def test_json_that_python_reads_leniently_is_refused(tmp_path, capsys, text, words):
    path = tmp_path / "m.json"
    path.write_text(text, encoding="utf-8")
    code, err = _export(path, tmp_path, capsys)
    assert code == 2 and len(err.splitlines()) == 1 and words in err


def test_an_oversized_file_is_refused_without_reading_it_all(tmp_path, capsys):
    path = tmp_path / "m.json"
    with path.open("w", encoding="utf-8") as handle:
        handle.write('{"pad": "')
        handle.write("x" * (5 * 1024 * 1024))
        handle.write('"}')
    code, err = _export(path, tmp_path, capsys)
    assert code == 2 and "larger than" in err


def test_every_bundled_model_passes_and_both_validators_agree_on_it():
    schema = json.loads((MODELS / "schema.json").read_text(encoding="utf-8"))
    assert schema == model_schema()
    for path in sorted(MODELS.glob("*.json")):
        if path.name != "schema.json":
            doc = json.loads(path.read_text(encoding="utf-8"))
            check_model_document(doc)
            jsonschema.validate(doc, schema)


def test_schema_and_plant_agree_on_the_arx_order_limit():
    plant = model_schema()["properties"]["plant"]["properties"]
    assert plant["na"]["maximum"] == plant["nb"]["maximum"] == ARX_ORDER_LIMIT


def test_plant_from_dict_checks_the_section_first():
    section = _doc("arx_3F")["plant"]
    with pytest.raises(ModelFileError, match=r"plant\.na: 1000000000000 is above the limit 50"):
        plant_from_dict({**section, "na": 10**12})
    with pytest.raises(ModelFileError, match=r"plant\.na: 2\.9 is not a JSON integer"):
        plant_from_dict({**section, "na": 2.9})


# --------------------------------------------------------------------------- export side


@pytest.mark.parametrize(
    "change",
    [{"gain_mm_per_mm": (1e308, 1e308, 1e308)}, {"opening_ref_mm": 1e308},
     {"level_ref_mm": (1e308, -1e308, 1e308)}],
)  # fmt: skip
def test_a_plant_with_non_finite_output_is_refused_at_export(tmp_path, change):
    # built in Python, past the model-file check: the export itself must refuse it
    plant = PLANTS["fopdt"]()
    if "opening_ref_mm" in change:
        plant = replace(plant, opening_ref_mm=change["opening_ref_mm"])
    else:
        values = {**plant.schedule.values, **change}
        plant = replace(plant, schedule=replace(plant.schedule, values=values))
    name = next(iter(change))
    # refused by the parameter limit (|value| <= 1e9) or, below it, by the output check
    with pytest.raises(ExportError, match=rf"{name}.*(not a finite number|beyond the FMU's limit)"):
        export_fmu(plant, tmp_path / "m.fmu", backend="c", model_name="m", provenance={})
    assert list(tmp_path.iterdir()) == []


def test_a_gauge_outside_the_name_rule_is_refused_at_export(tmp_path):
    plant = replace(PLANTS["fopdt"](), gauge="3F\x01" + "G" * 100)
    with pytest.raises(ExportError, match=r"gauge '3F\\x01G+' must be 1 to 32 characters"):
        export_fmu(plant, tmp_path / "m.fmu", backend="c", model_name="m", provenance={})
    assert list(tmp_path.iterdir()) == []


#: Text no XML may carry raw, and text XML must escape.
HOSTILE = {
    "controls": "a\x00b\x01c\x08d\x0be\x1bf\x7fg\x85h",
    "surrogates": "lone \ud800 and \udfff",
    "non_characters": "\ufffe\uffff",
    "markup": '<tag attr="x">&amp; ]]> \' " </fmiModelDescription>',
    "long": "y" * 5000,
}


@pytest.mark.skipif(compiler() is None, reason="no C compiler (cc/gcc) on PATH")
@pytest.mark.parametrize("backend", ["c", "python"])
def test_hostile_provenance_still_gives_a_well_formed_model_description(tmp_path, backend):
    provenance = {**PROVENANCE, **HOSTILE, "nested": {"deeper": HOSTILE["controls"]}}
    path = export_fmu(PLANTS["fopdt"](), tmp_path / "m.fmu", backend=backend, model_name="m",
                      provenance=provenance)  # fmt: skip
    assert_well_formed(path)
    import zipfile
    from xml.etree import ElementTree as ET

    with zipfile.ZipFile(path) as zf:
        description = ET.fromstring(zf.read("modelDescription.xml")).get("description")
    assert "a\\u0000b\\u0001c" in description and "\\ud800" in description
    assert '<tag attr="x">&amp; ]]>' in description  # escaped in the file, intact when read
