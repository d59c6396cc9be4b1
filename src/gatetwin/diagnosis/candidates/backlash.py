"""Candidate ``actuator_backlash``: a dead band crossed on every reversal of the gate (mm).

Signature: moves that reverse the direction change the level by less than moves that
continue it, by about ``|K| x band``. Start: that shortfall divided by ``|K|``. Immaterial
when ``|K| x band`` is below the noise floor.
"""

from __future__ import annotations

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit

__all__ = ["BacklashCandidate"]


class BacklashCandidate(Candidate):
    kind = "actuator_backlash"
    names = ("deadband_mm",)

    def applies(self, ctx: Context) -> str:
        if not any(m.reversal for m in ctx.data.moves):
            return "the gate never reverses"
        return super().applies(ctx)

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [0.0], [max(4.0 * ctx.typical_move_mm, 1.0)]

    def starts(self, ctx: Context) -> list[list[float]]:
        guess = ctx.estimate(self.kind, "deadband_mm", 1.0)
        return [[max(guess, 0.1)], [0.3 * ctx.typical_move_mm]]

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        effect = abs(ctx.gain_mm_per_mm) * fit.value("deadband_mm")
        if effect < ctx.sigma_mm:
            return f"the band moves the level by {effect:.2g} mm, below the noise floor"
        return ""
