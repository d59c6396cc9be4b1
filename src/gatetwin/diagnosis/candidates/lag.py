"""Candidate ``sensor_lag``: the gauge reports a first-order filtered level (s).

Signature: responses start rounder than an FOPDT's corner, the same for every move size.
Start: from that curvature. The lag is kept shorter than the plant's time constant (the two are
otherwise interchangeable). Immaterial below a quarter sample.
"""

from __future__ import annotations

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit

__all__ = ["LagCandidate"]


class LagCandidate(Candidate):
    kind = "sensor_lag"
    names = ("time_constant_s",)

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [0.05 * ctx.data.sample_period_s], [max(0.5 * ctx.time_constant_s, 2.0)]

    def starts(self, ctx: Context) -> list[list[float]]:
        guess = ctx.estimate(self.kind, "time_constant_s", 3.0 * ctx.data.sample_period_s)
        return [[guess], [ctx.data.sample_period_s], [0.25 * ctx.time_constant_s]]

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        lag = fit.value("time_constant_s")
        if lag < ctx.data.sample_period_s / 4.0:
            return f"a lag of {lag:.2g} s is below a quarter sample"
        return ""
