"""The baseline the diagnosis starts from: a model file's plant, or one identified from the
record itself.

* Step-type and free records: one FOPDT fitted to *all* moves jointly, run free with the
  record's input (:mod:`gatetwin.diagnosis.data`): a grid over ``T`` and ``L`` with ``K`` and
  the level solved linearly at each node, then an output-error fit of all four.
  ``opening_ref_mm`` is the record's first commanded opening.
* PRBS records: ARX by :func:`gatetwin.identification.identify_prbs` (the paper's ARX(2,2,1)),
  its coefficients and level then refitted for the free run (output error).

The schedule has two identical knots at the record's lowest and highest discharge (one when the
discharge is constant), so the plant is valid over the whole record. Whichever the source, the
baseline the candidates are scored against is this plant with its adjustments refitted on the
fitted part of the record (:mod:`gatetwin.diagnosis.fitting`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.diagnosis.fitting import (
    Fit,
    baseline_bounds,
    fit_plant,
    grid_start,
    plant_parametrization,
)
from gatetwin.diagnosis.grid_sim import simulate_grid
from gatetwin.errors import IdentificationError
from gatetwin.identification.prbs import identify_prbs
from gatetwin.plant.model import ArxPlant, FopdtPlant, PhysicalPlant, Plant, Schedule
from gatetwin.records import Record

__all__ = [
    "Baseline",
    "flat_knots",
    "identify_baseline",
    "model_baseline",
    "record_span_s",
    "refit",
]

_T_GRID_S = np.geomspace(3.0, 400.0, 16)
_L_GRID_S = (0.0, 0.6, 1.5, 3.0, 6.0, 12.0, 24.0)


@dataclass(frozen=True)
class Baseline:
    """The plant the diagnosis starts from, and its refit.

    Attributes
    ----------
    plant : Plant
        As identified or as read from the model file.
    refit : Fit
        ``plant`` with its adjustments refitted on the fitted part (what candidates beat).
    source : str
        Where it came from, in words.
    """

    plant: Plant
    refit: Fit
    source: str


def flat_knots(data: DiagnosisData) -> tuple[float, ...]:
    lo, hi = data.flow_range_m3h
    return (lo, hi) if hi > lo else (lo,)


def _fopdt(data: DiagnosisData, gain: float, tau: float, delay: float, level: float) -> FopdtPlant:
    knots = flat_knots(data)
    values = {"gain_mm_per_mm": gain, "time_constant_s": tau, "dead_time_s": delay,
              "level_ref_mm": level}  # fmt: skip
    columns = {k: (float(v),) * len(knots) for k, v in values.items()}
    return FopdtPlant(data.gauge, float(data.command_mm[0]), Schedule(knots, columns))


def _grid_start(data: DiagnosisData) -> FopdtPlant:
    """Best node of the (T, L) grid, with K and the level solved linearly."""
    mask = data.fit_mask
    y = data.level_mm[mask]
    best = (np.inf, None)
    for tau in _T_GRID_S:
        for delay in _L_GRID_S:
            unit = simulate_grid(_fopdt(data, 1.0, tau, delay, 0.0), data.grid)[mask]
            design = np.column_stack([np.ones_like(unit), unit])
            coef, *_ = np.linalg.lstsq(design, y, rcond=None)
            rss = float(np.sum((design @ coef - y) ** 2))
            if rss < best[0] and coef[1] != 0.0:
                best = (rss, _fopdt(data, coef[1], tau, delay, coef[0]))
    if best[1] is None:
        raise IdentificationError("the level does not follow the opening at all")
    return best[1]


def _arx_plant(record: Record, data: DiagnosisData) -> ArxPlant:
    ident = identify_prbs(record, data.gauge)
    fit = ident.fit
    knots = flat_knots(data)
    values = {f"a{i + 1}": (float(a),) * len(knots) for i, a in enumerate(fit.a)}
    values |= {f"b{j + 1}": (float(b),) * len(knots) for j, b in enumerate(fit.b)}
    values["level_ref_mm"] = (float(fit.level_mean_mm),) * len(knots)
    return ArxPlant(data.gauge, float(fit.opening_mean_mm), float(fit.sample_period_s), fit.na,
                    fit.nb, fit.nk, Schedule(knots, values))  # fmt: skip


def record_span_s(data: DiagnosisData) -> float:
    """The longest time constant worth fitting: the record's duration, s."""
    return float(data.time_s[-1] - data.time_s[0])


def refit(plant: Plant, data: DiagnosisData) -> Fit:
    """``plant`` with its baseline adjustments fitted on the fitted part."""
    span = record_span_s(data)
    _, lo, hi, neutral = baseline_bounds(plant, span)
    param = plant_parametrization(plant, max_time_constant_s=span)
    grid = grid_start(param, data, plant)
    starts = [np.clip(neutral, lo, hi)] + ([] if grid is None else [grid])
    return fit_plant(param, starts, data)


def identify_baseline(record: Record, data: DiagnosisData) -> Baseline:
    """Identify the baseline from the record (see the module docstring)."""
    if not data.moves:
        raise IdentificationError(
            f"{record.path or 'record'}: only the discharge changes, so no baseline can be "
            "identified from gate moves; give the model to diagnose against (--model)"
        )
    if record.test == "prbs":
        plant: Plant = _arx_plant(record, data)
        source = (
            "ARX(2,2,1) identified from the record (identify_prbs), coefficients and level "
            "refitted for the free run (output error)"
        )
        fit = refit(plant, data)
        return Baseline(plant, fit, source)
    fit = refit(_grid_start(data), data)
    source = f"FOPDT fitted jointly to all {len(data.moves)} moves of the record, run free"
    return Baseline(fit.plant, fit, source)


def model_baseline(plant: Plant, data: DiagnosisData, path: str) -> Baseline:
    """A model file's plant as the baseline.

    An envelope FOPDT is diagnosed in its local form (its schedule on the operating line,
    without ``envelope``): the effect blocks and the fast simulator render the local FOPDT
    and ARX only; the source says so. A physical model and an envelope ARX are refused for
    the same reason.
    """
    if plant.gauge != data.gauge:
        raise IdentificationError(f"model {path} is of gauge {plant.gauge}, not {data.gauge}")
    if isinstance(plant, PhysicalPlant):
        raise IdentificationError(
            f"model {path} is a physical model; the diagnosis takes FOPDT and ARX models"
        )
    if isinstance(plant, ArxPlant) and plant.envelope is not None:
        raise IdentificationError(
            f"model {path} is an envelope ARX (its input is the gate law's level, not the "
            "opening); diagnose against the record's own baseline or an FOPDT model"
        )
    source = f"model file {path}"
    if isinstance(plant, FopdtPlant) and plant.envelope is not None:
        plant = replace(plant, envelope=None)
        source += " (its local form: the schedule on the operating line, without the envelope)"
    return Baseline(plant, refit(plant, data), source)
