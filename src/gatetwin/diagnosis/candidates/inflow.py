"""Candidate ``inflow_disturbance``: the level answers measured discharge changes.

Signature: the residual correlates with first-order filtered discharge changes. Start: the
regression gain and the best of a few time constants. Immaterial when the discharge range of
the record moves the level by less than the noise floor.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit
from gatetwin.plant.effects import effect_dict

__all__ = ["InflowCandidate"]


class InflowCandidate(Candidate):
    kind = "inflow_disturbance"
    names = ("gain_mm_per_m3h", "time_constant_s")
    amplitude = "gain_mm_per_m3h"

    def applies(self, ctx: Context) -> str:
        lo, hi = ctx.data.flow_range_m3h
        if hi - lo < 1.0:
            return f"the discharge spans only {hi - lo:.2g} m3/h"
        return super().applies(ctx)

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [-100.0, 0.5 * ctx.data.sample_period_s], [100.0, 2000.0]

    def starts(self, ctx: Context) -> list[list[float]]:
        gain = ctx.estimate(self.kind, "gain_mm_per_m3h", 1.0)
        tau = ctx.estimate(self.kind, "time_constant_s", 30.0)
        return [[gain, tau], [gain, 3.0 * tau], [-gain, tau]]

    def effect(self, values: np.ndarray, ctx: Context) -> dict[str, Any]:
        return effect_dict(self.kind, gain_mm_per_m3h=float(values[0]),
                           time_constant_s=float(values[1]),
                           flow_ref_m3h=float(np.round(ctx.data.flow_m3h[0], 2)))  # fmt: skip

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        lo, hi = ctx.data.flow_range_m3h
        effect = abs(fit.value("gain_mm_per_m3h")) * (hi - lo)
        if effect < ctx.sigma_mm:
            return f"the discharge range moves the level by {effect:.2g} mm, below the noise floor"
        return ""
