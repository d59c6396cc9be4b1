"""The discrete model across the envelope: an ARX on the gate law's steady level.

At each PRBS condition the envelope ARX (:class:`~gatetwin.plant.model.ArxPlant` with an
``envelope``) is fitted by simulation error: its input is the steady level the physical
model's gate law gives for the opening and discharge (a Hammerstein input, mm), its steady
gain is 1, so only the pole ``a1`` and the split of the input between ``b1 .. b<nb>`` are
free (``sum b = 1 - a1``), plus a level offset that absorbs the gate law's error at that
condition (not exported: the twin's level stays the gate law's). ``time_constant_ref_s`` is
the pool's time constant at the condition (the median over the record of the storage
linearised at each steady point), against which the pole is scaled elsewhere in the
envelope. The record runs on its nominal sample grid, as the FMU harness drives it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from gatetwin.errors import IdentificationError
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.plant.model import ArxPlant, PhysicalPlant, Schedule, envelope_point
from gatetwin.plant.simulate import simulate
from gatetwin.records import Record

__all__ = ["POLE_BOUNDS", "EnvelopeArxCondition", "envelope_arx", "fit_condition"]

#: Bounds of the pole: a stable, non-oscillating first-order mode.
POLE_BOUNDS = (0.05, 0.9995)


@dataclass(frozen=True)
class EnvelopeArxCondition:
    """One PRBS condition's envelope ARX."""

    name: str
    flow_m3h: float
    opening_mm: float
    level_mm: float
    a1: float
    b: tuple[float, ...]
    time_constant_ref_s: float
    offset_mm: float
    fit_percent: float
    rmse_mm: float

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "flow_m3h": self.flow_m3h, "opening_mm": self.opening_mm,
                "level_mm": self.level_mm, "a1": self.a1, "b": list(self.b),
                "time_constant_ref_s": self.time_constant_ref_s, "offset_mm": self.offset_mm,
                "free_run_fit_percent": self.fit_percent, "rmse_mm": self.rmse_mm}  # fmt: skip


def _plant(physical: PhysicalPlant, sample_period_s: float, nb: int, nk: int, flow: float,
           opening_ref: float, a1: float, b: np.ndarray, tau_ref: float, level: float
           ) -> ArxPlant:  # fmt: skip
    values = {
        "a1": (a1,),
        **{f"b{j + 1}": (float(b[j]),) for j in range(nb)},
        "level_ref_mm": (level,),
        "time_constant_ref_s": (tau_ref,),
    }
    return ArxPlant(physical.gauge, opening_ref, sample_period_s, 1, nb, nk,
                    Schedule((flow,), values), effects=physical.effects,
                    envelope=dict(physical.parameters))  # fmt: skip


def _split(theta: np.ndarray, nb: int) -> tuple[float, np.ndarray]:
    """Pole and input coefficients from the free parameters (unit gain)."""
    a1 = float(theta[0])
    shares = np.append(theta[1:nb], 1.0 - np.sum(theta[1:nb]))
    return a1, (1.0 - a1) * shares


def fit_condition(name: str, record: Record, physical: PhysicalPlant, nb: int = 2,
                  nk: int = 1) -> EnvelopeArxCondition:  # fmt: skip
    """The envelope ARX of one PRBS record, by simulation error."""
    gauge = physical.gauge
    y = record.levels_mm.get(gauge)
    if y is None:
        raise IdentificationError(f"{name}: no level column for gauge {gauge}")
    ts = record.sample_period_s
    t = np.arange(record.n_samples) * ts
    e = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    q = np.asarray(record.flow_m3h, float)
    flow, opening = float(np.mean(q)), float(np.nanmean(record.opening_mm))
    p = physical.vector
    tau_ref = float(np.median([envelope_point(float(a), float(b), p)[1]
                               for a, b in zip(e[::10], q[::10], strict=True)]))  # fmt: skip
    level = envelope_point(opening, flow, p)[0]
    ok = np.isfinite(y)

    def residual(theta: np.ndarray) -> np.ndarray:
        a1, b = _split(theta, nb)
        plant = _plant(physical, ts, nb, nk, flow, opening, a1, b, tau_ref, level)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            sim = simulate(plant, t, e, q)
        return (sim + theta[-1] - y)[ok]

    start = np.array([float(np.exp(-ts / tau_ref)), *([1.0 / nb] * (nb - 1)), 0.0])
    lower = [POLE_BOUNDS[0], *([-20.0] * (nb - 1)), -50.0]
    upper = [POLE_BOUNDS[1], *([20.0] * (nb - 1)), 50.0]
    result = least_squares(residual, start, bounds=(lower, upper), x_scale="jac")
    if not result.success:
        raise IdentificationError(f"{name}: envelope ARX fit did not converge ({result.message})")
    a1, b = _split(result.x, nb)
    err = result.fun
    fit = 100.0 * (1.0 - np.linalg.norm(err) / np.linalg.norm(y[ok] - np.mean(y[ok])))
    return EnvelopeArxCondition(name, flow, opening, level, a1, tuple(float(v) for v in b),
                                tau_ref, float(result.x[-1]), float(fit),
                                float(np.sqrt(np.mean(err**2))))  # fmt: skip


def envelope_arx(conditions: list[EnvelopeArxCondition], physical: PhysicalPlant,
                 sample_period_s: float, nb: int = 2, nk: int = 1) -> ArxPlant:  # fmt: skip
    """The envelope ARX scheduled on Q over ``conditions`` (each column linear between
    them, held beyond), its validity the physical model's discharge range."""
    conds = sorted(conditions, key=lambda c: c.flow_m3h)
    knots = tuple(c.flow_m3h for c in conds)
    values = {"a1": tuple(c.a1 for c in conds),
              **{f"b{j + 1}": tuple(c.b[j] for c in conds) for j in range(nb)},
              "level_ref_mm": tuple(c.level_mm for c in conds),
              "time_constant_ref_s": tuple(c.time_constant_ref_s for c in conds)}  # fmt: skip
    plant = _plant(physical, sample_period_s, nb, nk, knots[0], conds[0].opening_mm,
                   conds[0].a1, np.array(conds[0].b), conds[0].time_constant_ref_s,
                   conds[0].level_mm)  # fmt: skip
    return replace(plant, schedule=Schedule(knots, values))
