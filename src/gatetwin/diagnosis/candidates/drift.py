"""Candidate ``sensor_drift``: the gauge's zero drifts linearly in time (mm/s).

Signature: a linear trend in the residual. Start: its slope. Immaterial when the drift over
the record stays below the noise floor.
"""

from __future__ import annotations

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit

__all__ = ["DriftCandidate"]


class DriftCandidate(Candidate):
    kind = "sensor_drift"
    names = ("rate_mm_per_s",)
    amplitude = "rate_mm_per_s"

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [-1.0], [1.0]

    def starts(self, ctx: Context) -> list[list[float]]:
        return [[ctx.estimate(self.kind, "rate_mm_per_s", 0.0)]]

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        total = abs(fit.value("rate_mm_per_s")) * ctx.duration_s
        if total < ctx.sigma_mm:
            return f"it drifts {total:.2g} mm over the record, below the noise floor"
        return ""
