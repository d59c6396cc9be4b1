"""What a diagnosis writes besides its JSON: the augmented model file, its FMUs re-validated
through fmpy against the record, and the figure.

Re-validation drives each FMU with the diagnosis's own input (the commanded opening, see
:mod:`gatetwin.diagnosis.data`) on the communication grid of the FMU validation harness
(:func:`gatetwin.validation.fmu_runner.communication_grid`; steps of the nominal sample period,
several across a logging gap) and reports its RMSE against the measured level, its largest
difference from the Python reference run on the same grid (round-off: ~1e-12 mm), and fmpy's
static validation findings.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.modelfile import model_document, write_model_file
from gatetwin.plant.model import Plant
from gatetwin.plant.simulate import PlantSimulator
from gatetwin.records import Record

__all__ = [
    "export_and_validate",
    "harness_inputs",
    "model_name",
    "reference_on_grid",
    "write_augmented_model",
]


def model_name(record: Record, gauge: str, effect: str) -> str:
    """A C identifier for the augmented model: ``<record>_<gauge>_<effect>``."""
    stem = "".join(c if c.isalnum() else "_" for c in Path(record.path).stem) or "record"
    name = f"{stem}_{gauge}_{effect}"
    return name if not name[0].isdigit() else f"m_{name}"


def write_augmented_model(path: Path, name: str, plant: Plant, data: DiagnosisData,
                          record: Record, summary: dict[str, Any]) -> Path:  # fmt: skip
    """The augmented plant as a model file, with the diagnosis that named its block.

    Valid around the record's openings: the operating opening is the middle of the commanded
    range at every knot, the band half that range.
    """
    where = Path(record.path).name
    lo, hi = float(np.min(data.command_mm)), float(np.max(data.command_mm))
    doc = model_document(
        name, plant,
        description=f"{plant.kind.upper()} of gauge {plant.gauge} with the effect block "
                    f"{summary['named_effect']} named by gatetwin diagnose on {where}",
        conditions=[], rating={},
        provenance={"method": "gatetwin diagnose: baseline plus the winning effect block, fitted "
                              "jointly (output error, free run) on the first part of the record",
                    "records": [{"name": Path(record.path).name, "sha256": record.sha256,
                                 "role": "fit"}],
                    "metrics": {"rmse_before_mm": summary["rmse_before_mm"],
                                "rmse_after_mm": summary["rmse_after_mm"]}},
        operating_openings_mm=[0.5 * (lo + hi)] * len(plant.schedule.flow_m3h),
        opening_band_mm=max(0.5 * (hi - lo), 1.0),
        extra={"diagnosis": summary["effect_fit"]},
    )  # fmt: skip
    return write_model_file(path, doc)


def harness_inputs(data: DiagnosisData) -> tuple[Any, np.ndarray, np.ndarray]:
    """The harness's communication grid and the opening and discharge at every sample."""
    from gatetwin.validation.fmu_runner import communication_grid

    opening = data.grid.command_mm[np.minimum(data.grid.sample_point, data.grid.n_intervals - 1)]
    return communication_grid(data.time_s, data.sample_period_s), opening, data.flow_m3h


def reference_on_grid(plant: Plant, data: DiagnosisData) -> np.ndarray:
    """The Python reference stepped exactly as the harness steps an FMU (RuntimeWarnings,
    e.g. a discharge outside the schedule, are left to the caller)."""
    grid, opening, flow = harness_inputs(data)
    sim = PlantSimulator(plant)
    out = np.empty(opening.size)
    sim.initialize(float(opening[0]), float(flow[0]), grid.start_time_s)
    out[0] = sim.level_mm
    for k in range(opening.size - 1):
        for _ in range(int(grid.steps[k])):
            sim.do_step(grid.step_s, float(opening[k]), float(flow[k]))
        out[k + 1] = sim.level_mm
    return out


def export_and_validate(plant: Plant, data: DiagnosisData, name: str, folder: Path,
                        provenance: dict[str, Any], backends: tuple[str, ...]
                        ) -> list[dict[str, Any]]:  # fmt: skip
    """Export ``plant`` with each backend and re-validate it through fmpy (module docstring)."""
    from fmpy.validation import validate_fmu

    from gatetwin.fmu import export_fmu
    from gatetwin.validation.fmu_runner import inspect_fmu, output_for_gauge, run_fmu

    grid, opening, flow = harness_inputs(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # reported by the diagnosis already
        reference = reference_on_grid(plant, data)
    out = []
    for backend in backends:
        path = export_fmu(plant, folder / f"{name}_{backend}.fmu", backend=backend,
                          model_name=name, provenance=provenance)  # fmt: skip
        info = inspect_fmu(path)
        levels = run_fmu(info, output_for_gauge(info, data.gauge), grid, opening, flow)
        d = (data.level_mm - levels)[data.valid]
        out.append({
            "backend": backend, "path": str(path),
            "rmse_mm": float(math.sqrt(float(np.mean(d * d)))),
            "max_abs_diff_from_reference_mm": float(np.max(np.abs(levels - reference))),
            "fmpy_validation_findings": list(validate_fmu(str(path))),
        })  # fmt: skip
    return out
