"""What every candidate effect provides, and the context it is fitted in.

A :class:`Candidate` is one effect block of :mod:`gatetwin.plant.effects` seen from the
diagnosis: its free parameters with bounds, start values (from the residual signatures of
:mod:`gatetwin.diagnosis.signatures` and physical defaults), how parameter values become the
block, whether it applies to a record at all, and when a fit is physically immaterial (it
then counts as ``none`` however well it scores).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.diagnosis.fitting import Fit
from gatetwin.plant.effects import effect_dict
from gatetwin.plant.model import Plant

__all__ = ["Candidate", "Context"]


@dataclass(frozen=True)
class Context:
    """Everything a candidate may look at.

    Attributes
    ----------
    data : DiagnosisData
        The prepared record.
    base : Plant
        The baseline plant (before adjustments).
    base_fit : Fit
        The refitted baseline.
    sigma_mm : float
        The noise floor, mm.
    signatures : dict
        Residual signatures by effect kind (``Signature`` objects).
    """

    data: DiagnosisData
    base: Plant
    base_fit: Fit
    sigma_mm: float
    signatures: dict[str, Any]

    @property
    def typical_move_mm(self) -> float:
        return float(np.median([abs(m.delta_mm) for m in self.data.moves]))

    @property
    def duration_s(self) -> float:
        return float(self.data.time_s[-1] - self.data.time_s[0])

    @property
    def gain_mm_per_mm(self) -> float:
        """The refitted baseline's static gain at the record's median discharge."""
        plant = self.base_fit.plant
        q = float(np.median(self.data.flow_m3h))
        if plant.kind == "fopdt":
            return plant.schedule.at("gain_mm_per_mm", q)
        a, b = plant.coefficients(q)
        return float(np.sum(b) / (1.0 - np.sum(a)))

    @property
    def time_constant_s(self) -> float:
        plant = self.base_fit.plant
        if plant.kind == "fopdt":
            return plant.schedule.at("time_constant_s", float(np.median(self.data.flow_m3h)))
        return 30.0

    def estimate(self, kind: str, name: str, default: float) -> float:
        """A signature's estimate of a block parameter, or ``default``."""
        sig = self.signatures.get(kind)
        value = sig.estimate.get(name) if sig is not None else None
        return float(value) if value is not None and np.isfinite(value) else default


class Candidate:
    """One candidate effect (subclasses: one per block kind)."""

    kind: ClassVar[str] = ""
    #: Free block parameters, in fit order.
    names: ClassVar[tuple[str, ...]] = ()
    #: The block acts on gate moves: it does not apply where the gate never moves.
    needs_moves: ClassVar[bool] = False
    #: The parameter the block's output is proportional to, if any (seiche amplitude, inflow
    #: gain, drift rate): solved linearly in the grid starts.
    amplitude: ClassVar[str | None] = None
    #: How many of the best starts are refined by least squares.
    max_starts: ClassVar[int] = 3

    def applies(self, ctx: Context) -> str:
        """Why the candidate does not apply to this record ("" when it does)."""
        if any(e["kind"] == self.kind for e in ctx.base.effects):
            return "the baseline already carries this block"
        if self.needs_moves and not ctx.data.moves:
            return "the gate never moves (a record where only the discharge changes)"
        return ""

    def bounds(self, ctx: Context) -> tuple[Sequence[float], Sequence[float]]:
        raise NotImplementedError

    def starts(self, ctx: Context) -> list[Sequence[float]]:
        raise NotImplementedError

    def effect(self, values: np.ndarray, ctx: Context) -> dict[str, Any]:
        """The block's dictionary for parameter values (constants added)."""
        return effect_dict(self.kind, **dict(zip(self.names, map(float, values), strict=True)))

    def make(self, plant: Plant, values: np.ndarray, ctx: Context) -> Plant:
        return replace(plant, effects=(*plant.effects, self.effect(values, ctx)))

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        """Why the fitted block is physically immaterial ("" when it is material)."""
        return ""
