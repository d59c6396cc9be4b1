"""Candidate ``actuator_rate_limit``: the gate moves at a finite speed (mm/s).

Signature: the logger flags ``open`` for several samples per move, longer for larger moves,
and the response lags more behind large moves than behind small ones. Start: ``|move| /
(open samples - 1/2) Ts`` from the logger, else the size-dependence of the apparent delay.
Immaterial when a typical move's ramp lasts less than one sample.
"""

from __future__ import annotations

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit

__all__ = ["RateLimitCandidate"]


class RateLimitCandidate(Candidate):
    kind = "actuator_rate_limit"
    names = ("rate_mm_per_s",)
    needs_moves = True

    def applies(self, ctx: Context) -> str:
        if ctx.data.input_kind != "command":
            return "the input is the reconstructed opening, which already ramps the moves"
        return super().applies(ctx)

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [0.02], [100.0]

    def starts(self, ctx: Context) -> list[list[float]]:
        move, ts = ctx.typical_move_mm, ctx.data.sample_period_s
        guess = ctx.estimate(self.kind, "rate_mm_per_s", move / (4.0 * ts))
        return [[guess], [move / (15.0 * ts)], [move / (1.5 * ts)]]

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        ramp = ctx.typical_move_mm / fit.value("rate_mm_per_s")
        if ramp < ctx.data.sample_period_s:
            return f"a typical move's ramp lasts {ramp:.2g} s, less than one sample"
        return ""
