"""``gatetwin validate --map``: an FMU gatetwin did not write (built here with pythonfmu, its
variables named and dimensioned its own way) validated against a measured record, with
JUnit output, as a co-simulation repository's CI would run it."""

from __future__ import annotations

import math
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from gatetwin.cli import main

#: The foreign gate: level h (m) relaxing with time constant T towards
#: h_ss = H0 + A * Q - B * u (Q in m³/s, u in m), as a stranger might write it.
H0_M, A_S_PER_M2, B, T_S = 0.2, 5.0, 4.0, 30.0
SLAVE = textwrap.dedent(f"""
    import math

    from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Real


    class ForeignGate(Fmi2Slave):
        description = "A first-order gate pool, SI units"

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.u_gate = 0.02
            self.Q_in = 0.01
            self.h_up = 0.0
            self.register_variable(Real("u_gate", causality=Fmi2Causality.input))
            self.register_variable(Real("Q_in", causality=Fmi2Causality.input))
            self.register_variable(Real("h_up", causality=Fmi2Causality.output,
                                        initial=Fmi2Initial.exact))

        def _steady(self):
            return {H0_M} + {A_S_PER_M2} * self.Q_in - {B} * self.u_gate

        def exit_initialization_mode(self):
            self.h_up = self._steady()

        def do_step(self, current_time, step_size):
            keep = math.exp(-step_size / {T_S})
            self.h_up = keep * self.h_up + (1.0 - keep) * self._steady()
            return True
""")
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
#: Gauge noise of the record, mm; the free-run fit then sits near 100 % less the noise's
#: share of the 20 mm step's variance (~97 %): 90 % passes with room, a wrong map cannot.
NOISE_MM = 0.5


def foreign_gate_fmu(folder: Path) -> Path:
    """The foreign gate's FMU, built with pythonfmu into ``folder``."""
    from pythonfmu.builder import FmuBuilder

    folder.mkdir(parents=True, exist_ok=True)
    script = folder / "foreign_gate.py"
    script.write_text(SLAVE, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


@pytest.fixture(scope="module")
def foreign_fmu(tmp_path_factory) -> Path:
    return foreign_gate_fmu(tmp_path_factory.mktemp("foreign"))


def _record(folder: Path) -> Path:
    """The foreign gate's response to a 20 -> 25 mm opening step at 40 m³/h, logged in mm
    and m³/h every second, with gauge noise."""
    rng = np.random.default_rng(5)
    n, q = 400, 40.0
    opening = np.where(np.arange(n) < 100, 20.0, 25.0)
    keep = math.exp(-1.0 / T_S)
    level = np.empty(n)
    steady = lambda e: 1000.0 * (H0_M + A_S_PER_M2 * q / 3600.0 - B * e / 1000.0)  # noqa: E731
    level[0] = steady(opening[0])
    for k in range(1, n):
        level[k] = keep * level[k - 1] + (1.0 - keep) * steady(opening[k - 1])
    lines = ["time_s,opening_mm,state,flow_m3h,level_3F_mm"]
    for k in range(n):
        lines.append(f"{k:.1f},{opening[k]:.1f},hold,{q:.1f},"
                     f"{level[k] + NOISE_MM * rng.standard_normal():.2f}")  # fmt: skip
    path = folder / "step.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _validate(fmu: Path, folder: Path, length_unit: str, capsys) -> tuple[int, str]:
    (folder / "map.toml").write_text(MAP.format(length=length_unit), encoding="utf-8")
    code = main(["validate", str(fmu), str(_record(folder)), "--map", str(folder / "map.toml"),
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
    code = main(["validate", str(foreign_fmu), str(_record(tmp_path)), "--map",
                 str(tmp_path / "map.toml"), "--json", str(tmp_path / "v.json")])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and says in err[0], err
    assert not (tmp_path / "v.json").exists()


def test_the_python_call_takes_the_same_map(foreign_fmu, tmp_path):
    import gatetwin

    (tmp_path / "map.toml").write_text(MAP.format(length="m"), encoding="utf-8")
    report = gatetwin.validate(foreign_fmu, _record(tmp_path), variable_map=tmp_path / "map.toml")
    assert report.cells[0]["fit_percent"] > 90
