"""Candidate ``flow_dependent_gain``: K and T follow the discharge (FOPDT plants).

Signature: the per-move gains (and response times) change with the discharge at the move.
The reference opening -- where a change of K moves the level least -- is freed with it, since
a discharge step then moves the level by ``dK (e - e_ref)``; moving it keeps the level at the
old reference opening, and it is started from five places over the record's openings (the
fit has local minima in it).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.plant.effects import effect_dict
from gatetwin.plant.model import FopdtPlant, Plant

__all__ = ["FlowGainCandidate"]


class FlowGainCandidate(Candidate):
    kind = "flow_dependent_gain"
    names = ("gain_slope_per_m3h", "time_constant_slope_per_m3h", "opening_ref_mm")
    max_starts = 8

    def applies(self, ctx: Context) -> str:
        if not isinstance(ctx.base, FopdtPlant):
            return "applies to FOPDT plants only"
        lo, hi = ctx.data.flow_range_m3h
        if hi - lo < 5.0:
            return f"the discharge spans only {hi - lo:.2g} m3/h"
        return super().applies(ctx)

    def _flow_ref(self, ctx: Context) -> float:
        return float(np.round(np.median(ctx.data.flow_m3h), 1))

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        e = ctx.data.command_mm
        return [-0.08, -0.08, float(e.min()) - 20.0], [0.08, 0.08, float(e.max()) + 20.0]

    def starts(self, ctx: Context) -> list[list[float]]:
        guess = ctx.estimate(self.kind, "gain_slope_per_m3h", -0.01)
        pivots = np.quantile(ctx.data.command_mm, [0.0, 0.25, 0.5, 0.75, 1.0])
        return [[guess, guess, float(p)] for p in pivots] + [[0.01, 0.01, float(pivots[2])]]

    def effect(self, values: np.ndarray, ctx: Context) -> dict[str, Any]:
        return effect_dict(self.kind, gain_slope_per_m3h=float(values[0]),
                           time_constant_slope_per_m3h=float(values[1]),
                           flow_ref_m3h=self._flow_ref(ctx))  # fmt: skip

    def make(self, plant: Plant, values: np.ndarray, ctx: Context) -> Plant:
        """Move the pivot to ``values[2]`` keeping the level at the old reference opening (at
        the reference discharge) where it was, so the pivot and the level offset do not trade."""
        pivot = float(values[2])
        v = dict(plant.schedule.values)
        shift = np.asarray(v["gain_mm_per_mm"]) * (pivot - plant.opening_ref_mm)
        v["level_ref_mm"] = tuple(float(x) for x in np.asarray(v["level_ref_mm"]) + shift)
        moved = replace(plant, opening_ref_mm=pivot, schedule=replace(plant.schedule, values=v))
        return super().make(moved, values, ctx)
