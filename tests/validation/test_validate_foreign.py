"""``gatetwin validate --map``: an FMU gatetwin did not write (built here with pythonfmu, its
variables named and dimensioned its own way) validated against a measured record, with
JUnit output, as a co-simulation repository's CI would run it."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from foreign_fmus import foreign_gate_fmu, foreign_gate_record
from gatetwin.cli import main

MAP = """
[opening_mm]
variable = "u_gate"
unit = "{length}"
[flow_m3h]
variable = "Q_in"
unit = "m3s"
[level_3F_mm]
variable = "h_up"
unit = "{length}"
"""


@pytest.fixture(scope="module")
def foreign_fmu(tmp_path_factory) -> Path:
    return foreign_gate_fmu(tmp_path_factory.mktemp("foreign"))


def _validate(fmu: Path, folder: Path, length_unit: str, capsys) -> tuple[int, str]:
    (folder / "map.toml").write_text(MAP.format(length=length_unit), encoding="utf-8")
    record = foreign_gate_record(folder)
    code = main(["validate", str(fmu), str(record), "--map", str(folder / "map.toml"),
                 "--fail-under", "fit_percent=90", "--json", str(folder / "v.json"),
                 "--junit", str(folder / "v.xml")])  # fmt: skip
    return code, capsys.readouterr().err


def test_a_foreign_fmu_is_validated_through_its_map_with_junit_output(foreign_fmu, tmp_path,
                                                                      capsys):  # fmt: skip
    code, err = _validate(foreign_fmu, tmp_path, "m", capsys)
    assert code == 0, err
    suite = ET.parse(tmp_path / "v.xml").getroot()
    cases = suite.findall(".//testcase")
    assert cases and not suite.findall(".//failure") and not suite.findall(".//error")
    import json

    doc = json.loads((tmp_path / "v.json").read_text())
    text = json.dumps(doc)
    assert '"h_up"' in text and '"m3s"' in text  # the map is part of the report


def test_a_map_in_the_wrong_unit_fails_the_threshold(foreign_fmu, tmp_path, capsys):
    """The same FMU read as if it spoke millimetres: 1000 times off, the fit fails."""
    code, _ = _validate(foreign_fmu, tmp_path, "mm", capsys)
    assert code == 1
    assert ET.parse(tmp_path / "v.xml").getroot().findall(".//failure")


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (MAP.format(length="m").replace('"h_up"', '"h_down"'), "'h_down'"),
        (
            MAP.format(length="m")
            .replace('"Q_in"', '"x"')
            .replace('"h_up"', '"Q_in"')
            .replace('"x"', '"h_up"'),
            "'h_up', which must be a Real input",
        ),  # roles swapped
        (MAP.format(length="m").replace('"Q_in"', '"h_up"'), "named for two columns"),
        (MAP.format(length="furlong"), "furlong"),
        ("[opening_mm]\nvariable = 'u_gate'\nunit = 'm'\n", "[flow_m3h]"),
        ("not = toml = at all", "not a TOML file"),
    ],
    ids=[
        "unknown variable",
        "an output as input",
        "one variable twice",
        "unknown unit",
        "incomplete",
        "not toml",
    ],
)
def test_a_bad_map_is_one_line_and_nothing_written(foreign_fmu, tmp_path, capsys, text, says):
    (tmp_path / "map.toml").write_text(text, encoding="utf-8")
    code = main(["validate", str(foreign_fmu), str(foreign_gate_record(tmp_path)), "--map",
                 str(tmp_path / "map.toml"), "--json", str(tmp_path / "v.json")])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and says in err[0], err
    assert not (tmp_path / "v.json").exists()


def test_the_python_call_takes_the_same_map(foreign_fmu, tmp_path):
    import gatetwin

    (tmp_path / "map.toml").write_text(MAP.format(length="m"), encoding="utf-8")
    record = foreign_gate_record(tmp_path)
    report = gatetwin.validate(foreign_fmu, record, variable_map=tmp_path / "map.toml")
    assert report.cells[0]["fit_percent"] > 90
