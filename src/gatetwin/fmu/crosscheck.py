"""FMI cross-check packages: an FMU with the inputs of a record and the reference result.

A platform team verifies a gatetwin FMU in its own importer in one step: run
``<Model>.fmu`` with ``<Model>_in.csv`` as input, on the settings of ``<Model>_ref.opt``
(start and stop time, communication step, tolerance), and compare its output with
``<Model>_ref.csv``, which :mod:`gatetwin.plant.simulate` (the reference both backends are
held to within 1e-9 mm) computed from the same inputs. The layout follows the FMI
cross-check repository's (one folder per model; CSV with a header row, time first).
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np

from gatetwin._io import write_text_atomic
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.modelfile import ModelFile
from gatetwin.plant.simulate import simulate
from gatetwin.records import Record

__all__ = ["REL_TOL", "write_cross_check"]

#: Relative tolerance an importer compares the output with (far above the 1e-9 mm agreement
#: of the renderings, far below any model error).
REL_TOL = 1e-6


def _csv(path: Path, header: list[str], columns: list[np.ndarray]) -> Path:
    lines = [",".join(f'"{h}"' for h in header)]
    lines += [",".join(repr(float(v)) for v in row) for row in zip(*columns, strict=True)]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def write_cross_check(model: ModelFile, fmu: Path, record: Record, folder: Path) -> list[Path]:
    """Write the cross-check package of ``fmu`` (exported from ``model``) into ``folder``,
    driven by ``record``'s inputs on its nominal sample grid; returns the files written."""
    name = model.name
    folder.mkdir(parents=True, exist_ok=True)
    ts = record.sample_period_s
    time = np.arange(record.n_samples) * ts
    opening = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    flow = np.asarray(record.flow_m3h, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # outside the schedule: clamped
        level = simulate(model.plant, time, opening, flow)
    output = f"level_{model.plant.gauge}_mm"
    shutil.copyfile(fmu, folder / f"{name}.fmu")
    paths = [folder / f"{name}.fmu"]
    paths.append(_csv(folder / f"{name}_in.csv", ["time", "opening_mm", "flow_m3h"],
                      [time, opening, flow]))  # fmt: skip
    paths.append(_csv(folder / f"{name}_ref.csv", ["time", output], [time, level]))
    stop, step = float(time[-1]), float(ts)
    opt = f"StartTime, 0.0\nStopTime, {stop!r}\nStepSize, {step!r}\nRelTol, {REL_TOL!r}\n"
    paths.append(write_text_atomic(folder / f"{name}_ref.opt", opt))
    readme = (
        f"{name}: run {name}.fmu (FMI 2.0 co-simulation) from StartTime to StopTime with "
        f"communication step StepSize ({name}_ref.opt), the inputs of {name}_in.csv held "
        f"over each step, and compare {output} with {name}_ref.csv within RelTol (the "
        f"reference is gatetwin's Python simulator on record {Path(record.path).name}).\n"
    )
    paths.append(write_text_atomic(folder / "README.txt", readme))
    return paths
