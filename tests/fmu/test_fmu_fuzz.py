"""The C FMUs survive random FMI call sequences under AddressSanitizer and UBSan.

tests/c/fmu_fuzz.c drives an FMU binary built with the sanitizers through random call sequences
from a seed (out-of-order calls, NaN/inf/huge values, hostile step sizes, unknown value
references, FMU state round trips, tampered and foreign serialised states, free/instantiate
cycles) and checks what every call returns; any sanitizer report, crash, hang or failed check
fails the test. The fuzzer is built once and knows an FMU only by the SPEC file written from
its modelDescription.xml (and its state's layout, tests/c/fmu_layout.c). One FMU per plant
family: the envelope FOPDT and the physical model of the repository (with their validity
envelopes), a FOPDT and an ARX plant carrying every effect block; the PI controller FMU
of the envelope FOPDT; the MPC controller FMU and the observer FMU of its FOPDT (without the
seiche they do not cover), both with casadi-generated arithmetic; the scenario FMU of an SSP.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import pytest
from fmpy import extract, read_model_description

from effect_cases import EXAMPLES
from fmu_support import (
    PLANTS,
    build_fuzzer,
    build_sanitized,
    compiler,
    fuzz_spec,
    sanitizers_work,
)
from gatetwin.fmu import export_fmu
from gatetwin.fmu.controller import export_controller
from gatetwin.fmu.provenance import fmu_provenance
from gatetwin.modelfile import read_model_file
from gatetwin.plant.effects import KINDS, effect_dict

MODELS = Path(__file__).resolve().parents[2] / "models"
#: A validity envelope for the test plants (their knots span 30..85 m3/h).
VALIDITY = {"validity": {"opening_mm": [10.0, 40.0], "flow_m3h": [30.0, 85.0],
                         "level_mm": [150.0, 450.0]}}  # fmt: skip
#: case -> sequences in the default run (19,250 in all, seconds of fuzzing on one core; a
#: physical step of 1e5 s integrates 1.7e5 RK4 sub-steps, so the physical FMU gets fewer; the
#: MPC's initialisation iterates the Riccati map and every sample solves a QP, ~70 ms a
#: sequence under the sanitizers, so it gets fewest; the envelope observer bisects the gate law
#: three times a sample).
SEQUENCES = {"fopdt_envelope": 4000, "fopdt_effects": 4000, "arx_effects": 3000,
             "physical": 1000, "pi_controller": 3000, "mpc_controller": 150,
             "observer": 1000, "observer_envelope": 100, "scenario": 3000}  # fmt: skip
#: The MPC controller FMU's horizon: short, to keep its build and its samples quick (the
#: code paths are those of any horizon).
MPC_HORIZON = 10
#: Cases that step whole samples of their default step size only (no variable holds it).
SAMPLED = ("mpc_controller", "observer", "observer_envelope")
CASES = tuple(SEQUENCES)
#: Plausible values of the plants' inputs (gate up to 90 mm, discharge up to 150 m3/h: inside
#: and beyond the test plants' envelope); another input draws from 0..2x its start.
INPUT_RANGES = {"opening_mm": (0.0, 90.0), "flow_m3h": (0.0, 150.0)}
#: The controllers (of fopdt_3F) are driven with level and set-point across their level
#: band, the model's validity range [lo, hi], and one band's width beyond either end; each
#: set-point outside the band may bring its own fmi2Warning (the MPC's reason, logged).
CONTROLLERS = ("pi_controller", "mpc_controller")


def _band_ranges() -> dict[str, tuple[float, float]]:
    doc = json.loads((MODELS / "fopdt_3F.json").read_text(encoding="utf-8"))
    lo, hi = doc["validity"]["level_range_mm"]
    span = (lo - (hi - lo), hi + (hi - lo))
    return {**INPUT_RANGES, f"level_{doc['gauge']}_mm": span, "setpoint_mm": span}


#: The long run: ten times as many.
SLOW_FACTOR = 10
#: A check every component makes on a state it restores (every Real variable finite, in
#: component.c), and the line without it: the fuzzer must notice the state the PI controller
#: then accepts.
PLANTED_BUG = ("if (!isfinite(real[vr])) {", "if (0) {")


class Fuzzed(NamedTuple):
    """One FMU ready for the fuzzer."""

    binary: Path  # rebuilt with the sanitizers
    fuzzer: Path
    spec: Path
    guid: str
    extracted: Path


def _export(case: str, folder: Path) -> Path:
    """The FMI 2.0 C FMU of ``case``."""
    if case in ("mpc_controller", "observer", "observer_envelope"):
        return _export_generated(case, folder)
    if case == "scenario":  # an SSP's scenario: a held and a linear table, no inputs
        from gatetwin.fmu.signal_source import TableSignal, export_signal_source

        signals = [
            TableSignal("setpoint_mm", "mm", (0.0, 6.0, 12.0), (180.0, 200.0, 170.0)),
            TableSignal("flow_m3h", "m3/h", (0.0, 60.0), (40.0, 60.0), linear=True),
        ]
        return export_signal_source(signals, folder / f"{case}.fmu", step_size_s=1.2,
                                    model_identifier=f"fuzz_{case}")  # fmt: skip
    if case == "pi_controller":
        model = read_model_file(MODELS / "fopdt_3F.json")
        return export_controller(model, "pi", folder / f"{case}.fmu", model_name=f"fuzz_{case}")
    plant, provenance = _plant_and_provenance(case)
    return export_fmu(plant, folder / f"{case}.fmu", backend="c", model_name=f"fuzz_{case}",
                      provenance=provenance)  # fmt: skip


def _export_generated(case: str, folder: Path) -> Path:
    """The MPC controller or the observer FMU (with reference gauges) of the envelope FOPDT
    without its seiche, or the envelope observer FMU of the physical model without it."""
    from gatetwin.fmu.mpc_controller import export_mpc_controller
    from gatetwin.fmu.observer_fmu import export_observer
    from gatetwin.mpc.settings import MpcSettings

    plant = replace(read_model_file(MODELS / "fopdt_3F.json").plant, effects=())
    out = folder / f"{case}.fmu"
    if case == "observer_envelope":
        physical = replace(read_model_file(MODELS / "physical_3F.json").plant, effects=())
        return export_observer(physical, out, model_name=f"fuzz_{case}")
    if case == "observer":  # with two reference gauges: the gauge-drift rule's C too
        return export_observer(plant, out, model_name=f"fuzz_{case}",
                               reference_gauges=("1D", "2E"))  # fmt: skip
    return export_mpc_controller(plant, out, settings=MpcSettings(horizon=MPC_HORIZON),
                                 model_name=f"fuzz_{case}")  # fmt: skip


def _plant_and_provenance(case: str):
    if case in ("fopdt_envelope", "physical"):
        model = read_model_file(
            MODELS / ("fopdt_3F.json" if case != "physical" else "physical_3F.json")
        )
        return model.plant, fmu_provenance(model)
    family = case.split("_")[0]
    kinds = [k for k in KINDS if family == "fopdt" or k != "flow_dependent_gain"]
    effects = tuple(effect_dict(k, **EXAMPLES[k]) for k in kinds)
    return replace(PLANTS[family](), effects=effects), VALIDITY


#: The sanitizer builds alone take over a minute: the module runs with CI's slow subset, on
#: one worker (CI's slow run distributes by group), so they are made once.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("fuzz")]


@pytest.fixture(scope="module")
def fuzzers(tmp_path_factory) -> dict[str, Fuzzed]:
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("fuzz")
    if not sanitizers_work(folder):
        pytest.skip("the C compiler cannot build or run -fsanitize=address,undefined here")
    fuzzer = build_fuzzer(folder)
    out = {}
    for case in CASES:
        extracted = Path(extract(str(_export(case, folder)), str(folder / case)))
        controller = case in CONTROLLERS
        spec = fuzz_spec(extracted, folder / f"{case}.spec",
                         _band_ranges() if controller else INPUT_RANGES, sampled=case in SAMPLED,
                         warns_on_change="setpoint_mm" if controller else None)  # fmt: skip
        out[case] = Fuzzed(
            build_sanitized(extracted, folder),
            fuzzer,
            spec,
            read_model_description(str(extracted)).guid,
            extracted,
        )
    return out


def _run(fuzzers, case: str, seed: int, sequences: int, binary: Path | None = None):
    this = fuzzers[case]
    other = fuzzers[CASES[(CASES.index(case) + 1) % len(CASES)]]
    return subprocess.run(
        [str(this.fuzzer), str(binary or this.binary), str(this.spec), str(seed), str(sequences),
         str(other.binary), other.guid],
        capture_output=True,
        text=True,
        timeout=1200,
    )  # fmt: skip


def _fuzz(fuzzers, case: str, seed: int, sequences: int) -> str:
    run = _run(fuzzers, case, seed, sequences)
    assert run.returncode == 0, run.stderr[-4000:]
    assert f"fuzz: {sequences} sequences" in run.stdout
    return run.stdout


@pytest.mark.parametrize("case", CASES)
def test_random_call_sequences_find_nothing(fuzzers, case):
    _fuzz(fuzzers, case, seed=20261123, sequences=SEQUENCES[case])


@pytest.mark.parametrize("case", CONTROLLERS)
def test_the_controllers_level_and_set_point_are_drawn_across_and_beyond_their_band(fuzzers, case):
    """The spec gives level and set-point one band's width beyond the validity's level range
    on either side, so the fuzzer's draws fall below, inside and above the band."""
    doc = json.loads((MODELS / "fopdt_3F.json").read_text(encoding="utf-8"))
    lo, hi = doc["validity"]["level_range_mm"]
    md = read_model_description(str(fuzzers[case].extracted))
    vr = {v.name: v.valueReference for v in md.modelVariables if v.causality == "input"}
    ranges = {int(parts[1]): (float(parts[2]), float(parts[3]))
              for parts in map(str.split, fuzzers[case].spec.read_text().splitlines())
              if parts and parts[0] == "range"}  # fmt: skip
    for name in (f"level_{doc['gauge']}_mm", "setpoint_mm"):
        low, high = ranges[vr[name]]
        assert low < lo and high > hi and (lo - low, high - hi) == (hi - lo, hi - lo), name


# ~8 min over the cases: run before a release (`-m long`), not on every change
@pytest.mark.long
@pytest.mark.parametrize("case", CASES)
def test_long_fuzzing_finds_nothing(fuzzers, case):
    _fuzz(fuzzers, case, seed=1, sequences=SLOW_FACTOR * SEQUENCES[case])


def test_the_fuzzer_finds_a_state_check_left_out(fuzzers, tmp_path):
    """The PI controller rebuilt without one of its state checks (component.c's, which every
    component shares) is caught (exit 1)."""
    planted = Path(shutil.copytree(fuzzers["pi_controller"].extracted, tmp_path / "planted"))
    code = (planted / "sources" / "component.c").read_text(encoding="utf-8")
    assert code.count(PLANTED_BUG[0]) == 1
    (planted / "sources" / "component.c").write_text(code.replace(*PLANTED_BUG),
                                                         encoding="utf-8")  # fmt: skip
    run = _run(fuzzers, "pi_controller", 20261123, SEQUENCES["pi_controller"],
               build_sanitized(planted, tmp_path))  # fmt: skip
    assert run.returncode == 1, run.stdout + run.stderr[-2000:]
    assert "FINDING" in run.stderr and "accepted" in run.stderr


def test_a_bad_spec_is_one_line_naming_the_file_and_line(fuzzers, tmp_path):
    this = fuzzers["pi_controller"]
    lines = this.spec.read_text(encoding="utf-8").splitlines()
    bad = tmp_path / "bad.spec"
    bad.write_text("\n".join([lines[0], lines[2], *lines[1:]]), encoding="utf-8")  # var 1 first
    run = subprocess.run([str(this.fuzzer), str(this.binary), str(bad), "1", "1"],
                         capture_output=True, text=True, timeout=60)  # fmt: skip
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.strip().splitlines() == [run.stderr.strip()]
    assert run.stderr.startswith(f"{bad}:2: ")
