"""The exported models of the repository agree with the reference on every bundled record.

Each model of ``models/`` is exported with both backends, and as FMI 3.0, and driven through
fmpy with each bundled record's inputs (opening reconstructed during gate motion, measured
flow, on the nominal sample grid so the ARX FMU can follow); the C FMU, the python FMU and
:func:`gatetwin.plant.simulate` must agree within 1e-9 mm at every sample, and the FMI 3.0
FMU must give the FMI 2.0 C FMU's outputs exactly: both compile the same component with the
same flags, only the glue differs. The physical model and the envelope FOPDT are run as well
with a pool below the gate (a submerged gate: the kernel's second state and its time
constant's two-pool moment), and with a floor at the gauge (a far gauge's level levelling off
at its channel's flow depth).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from fmu_support import compiler, extract_all, fmu_run, open_fmu, reference_run  # noqa: E402
from gatetwin.bundled import bundled_records_dir
from gatetwin.fmu import export_fmu
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.modelfile import read_model_file
from gatetwin.records import read_record

MODELS = Path(__file__).resolve().parents[2] / "models"
RECORDS = sorted(p for p in bundled_records_dir().glob("*.csv") if p.stem != "static")
TOLERANCE_MM = 1e-9
NAMES = ("fopdt_3F", "arx_3F", "physical_3F", "fopdt_3F_submerged", "physical_3F_submerged",
         "fopdt_3F_floored", "physical_3F_floored")  # fmt: skip
#: What the variants add to the bundled model: a pool below the flume's gate (m², m; an
#: orifice outlet), and a floor at the gauge (mm: a flow depth of 150 mm at the discharge
#: centre, rising as Q^0.6, met over 10 mm) that the bundled records' levels cross.
VARIANTS = {
    "_submerged": {"tail_area_m2": 1.5, "tail_depth_m": 0.12, "tail_datum_m": 0.03,
                   "tail_exponent": 0.5},
    "_floored": {"floor_mm": 150.0, "floor_per_q_mm": 164.0, "floor_smooth_mm": 10.0},
}  # fmt: skip


def _plant(name: str):
    suffix = next((s for s in VARIANTS if name.endswith(s)), "")
    plant = read_model_file(MODELS / f"{name.removesuffix(suffix)}.json").plant
    if not suffix:
        return plant
    if plant.kind == "physical":
        return dataclasses.replace(plant, parameters={**plant.parameters, **VARIANTS[suffix]})
    return dataclasses.replace(plant, envelope={**plant.envelope, **VARIANTS[suffix]})


@pytest.fixture(scope="module")
def extracted(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler on this machine")
    folder = tmp_path_factory.mktemp("bundled_fmus")
    fmus = {}
    for name in NAMES:
        plant = _plant(name)
        for key, backend, version in (
            ("c", "c", "2.0"),
            ("python", "python", "2.0"),
            ("fmi3", "c", "3.0"),
        ):
            fmus[(name, key)] = export_fmu(plant, folder / key / f"{name}.fmu",
                                           backend=backend, model_name=name,
                                           provenance={"model": name},
                                           fmi_version=version)  # fmt: skip
    return extract_all(fmus, folder / "x")


def _inputs(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = read_record(path)
    times = np.arange(rec.n_samples) * rec.sample_period_s
    opening = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
    return times, opening, np.asarray(rec.flow_m3h)


@pytest.mark.parametrize("record", RECORDS, ids=lambda p: p.stem)
@pytest.mark.parametrize("name", NAMES)
def test_reference_c_and_python_fmus_agree_on_bundled_record(extracted, record, name):
    times, opening, flow = _inputs(record)
    plant = _plant(name)
    reference = reference_run(plant, times, opening, flow)
    got = {}
    for backend in ("c", "python", "fmi3"):
        driver = open_fmu(extracted[(name, backend)], f"{name}_{backend}", logging_on=False)
        try:
            got[backend] = fmu_run(driver, times, opening, flow)
        finally:
            driver.close()
        assert np.max(np.abs(got[backend] - reference)) <= TOLERANCE_MM, backend
    assert np.array_equal(got["fmi3"], got["c"])
