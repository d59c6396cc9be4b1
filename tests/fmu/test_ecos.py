"""The FMUs ``gatetwin run`` writes, run alone in ecos (the ``ecospy`` package: a
co-simulation engine no one here wrote) and in fmpy, give the same outputs.

The FMUs are built by the run's own task functions (:func:`gatetwin.run.pipeline.
export_model_fmus`, :func:`gatetwin.run.stages.closed_loop_fmu_task`) from the repository's
model files, which equal the run's (``tests/test_models.py``): one model per family with
each backend and FMI version, the PI and MPC controllers and the observers. Each FMU gets
the same input sequence in both engines: set the inputs, one communication step of 1.2 s,
read every output. The same binary given the same doubles computes the same bits; the
tolerance, 1e-9 in the output's unit (the C-against-Python contract of the plant FMUs),
leaves room only for the engines forming the communication points differently (k·h or a
running sum), which an FMU may read.

ecos needs Intel's TBB runtime (Debian's ``libtbb12``): without it the module is skipped,
unless ``GATETWIN_REQUIRE_ECOS`` is set (as CI sets it), where that is a failure.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from ecos_support import load_ecospy
from fmu_support import compiler

pytestmark = pytest.mark.slow  # ~1 min: fourteen FMUs built (the MPC and observers by casadi)

ROOT = Path(__file__).resolve().parents[2]
#: Communication step, s (the controllers' sample period) and steps run.
STEP_S, STEPS = 1.2, 150
#: |ecos - fmpy| allowed, in each output's unit (module docstring).
TOLERANCE = 1e-9


@pytest.fixture(scope="module")
def run_fmus(tmp_path_factory) -> dict[str, Path]:
    """``{name: path}``: what ``gatetwin run`` writes under fmus/ for fopdt_3F, arx_3F and
    physical_3F, and under controllers/ and observers/."""
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    load_ecospy()
    from gatetwin.run.pipeline import export_model_fmus
    from gatetwin.run.stages import closed_loop_fmu_task

    folder = tmp_path_factory.mktemp("ecos_fmus")
    fmus: dict[str, Path] = {}
    for model in ("fopdt_3F", "arx_3F", "physical_3F"):
        for kind, data in export_model_fmus((str(ROOT / "models" / f"{model}.json"), "host")
                                            ).items():  # fmt: skip
            fmus[f"fmus/{kind}/{model}.fmu"] = _write(folder / kind / f"{model}.fmu", data)
    fopdt, physical = (str(ROOT / "models" / f"{m}_3F.json") for m in ("fopdt", "physical"))
    jobs = [(fopdt, "controllers/fopdt_3F_pi.fmu", {"controller": "pi"}),
            (fopdt, "controllers/fopdt_3F_mpc.fmu", {"controller": "mpc",
                                                     "without_effects": True}),
            (fopdt, "observers/fopdt_3F_observer.fmu", {"without_effects": True}),
            (physical, "observers/physical_3F_observer.fmu", {"without_effects": True}),
            (physical, "observers/physical_3F_observer_gauges.fmu",
             {"without_effects": True, "reference_gauges": ["2E", "4G"]})]  # fmt: skip
    for job in jobs:
        fmus[job[1]] = _write(folder / job[1], closed_loop_fmu_task(job))
    return fmus


def _write(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def _input(name: str, k: int) -> float:
    """Input ``name`` at step ``k``: steps and a slow wave in each, inside the plants'
    ranges (a level near the 3F pool's, an opening and a discharge of the bundled tests)."""
    if name.startswith("level_") and name.endswith("_mm"):
        return 300.0 + 12.0 * math.sin(2.0 * math.pi * k / 60.0) + (8.0 if k >= 90 else 0.0)
    if name == "opening_mm":
        return 24.5 + (4.0 if (k // 30) % 2 else 0.0)
    if name == "flow_m3h":
        return 50.0 + (8.0 if k >= 70 else 0.0)
    if name == "setpoint_mm":
        return 300.0 + (15.0 if k >= 40 else 0.0)
    raise AssertionError(f"no test signal for the input {name}")


def _variables(fmu: Path) -> tuple[list[str], list[str]]:
    """The FMU's real inputs and outputs, by name."""
    md = read_model_description(str(fmu))
    real = ("Real", "Float64")
    inputs = [v.name for v in md.modelVariables if v.causality == "input" and v.type in real]
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type in real]
    return inputs, outputs


def _fmpy_run(fmu: Path, folder: Path) -> np.ndarray:
    md = read_model_description(str(fmu))
    inputs, outputs = _variables(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(fmu), str(folder / "fmpy"))
    kind = FMU3Slave if md.fmiVersion == "3.0" else FMU2Slave
    slave = kind(guid=md.guid, unzipDirectory=unzipped, instanceName="m",
                 modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
    slave.instantiate()
    if md.fmiVersion == "3.0":
        slave.enterInitializationMode(startTime=0.0)
        get, put = slave.getFloat64, slave.setFloat64
    else:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        get, put = slave.getReal, slave.setReal
    slave.exitInitializationMode()
    rows = []
    for k in range(STEPS):
        put([vr[n] for n in inputs], [_input(n, k) for n in inputs])
        slave.doStep(currentCommunicationPoint=k * STEP_S, communicationStepSize=STEP_S)
        rows.append(get([vr[n] for n in outputs]))
    slave.terminate()
    slave.freeInstance()
    return np.array(rows, dtype=float)


def _ecos_run(fmu: Path) -> np.ndarray:
    ecospy = load_ecospy()
    inputs, outputs = _variables(fmu)
    with ecospy.EcosSimulationStructure() as structure:
        structure.add_model("m", str(fmu))
        with ecospy.EcosSimulation(structure=structure, step_size=STEP_S) as sim:
            assert sim.init(), "ecos could not initialise the FMU"
            rows = []
            for k in range(STEPS):
                for name in inputs:
                    sim.set_real(f"m::{name}", _input(name, k))
                sim.step()
                rows.append([sim.get_real(f"m::{name}") for name in outputs])
            sim.terminate()
    return np.array(rows, dtype=float)


@pytest.mark.parametrize("name", [
    *(f"fmus/{kind}/{model}.fmu" for kind in ("c", "python", "fmi3")
      for model in ("fopdt_3F", "arx_3F", "physical_3F")),
    "controllers/fopdt_3F_pi.fmu", "controllers/fopdt_3F_mpc.fmu",
    "observers/fopdt_3F_observer.fmu", "observers/physical_3F_observer.fmu",
    "observers/physical_3F_observer_gauges.fmu",
])  # fmt: skip
def test_an_fmu_alone_in_ecos_gives_fmpys_outputs(run_fmus, name, tmp_path):
    fmu = run_fmus[name]
    inputs, outputs = _variables(fmu)
    assert inputs and outputs
    expected = _fmpy_run(fmu, tmp_path)
    got = _ecos_run(fmu)
    assert np.all(np.isfinite(expected)), "the test signals drove the FMU out of its range"
    assert got.shape == expected.shape
    worst = np.max(np.abs(got - expected), axis=0)
    assert np.all(worst <= TOLERANCE), dict(zip(outputs, worst, strict=True))
    # the inputs reached the FMU: its outputs move over the run
    assert np.any(np.ptp(expected, axis=0) > 0.0)
