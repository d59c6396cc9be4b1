"""Candidate ``seiche``: a lightly damped oscillation of the pool excited by gate moves.

Signature: a peak in the residual's spectrum between 2.5 samples and a minute (or 24 samples,
where longer: :func:`~gatetwin.diagnosis.signatures.seiche_longest_period_s`). Start: the
peak's period, a decay of two periods, the amplitude regressed on the unit oscillation.
Immaterial when a typical move excites less than the noise floor, when the period is shorter
than two samples (not observable) or when it decays within a quarter period (no oscillation).
"""

from __future__ import annotations

from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.fitting import Fit
from gatetwin.diagnosis.signatures import seiche_longest_period_s

__all__ = ["SeicheCandidate"]


class SeicheCandidate(Candidate):
    kind = "seiche"
    names = ("period_s", "decay_time_s", "amplitude_mm_per_mm")
    amplitude = "amplitude_mm_per_mm"
    needs_moves = True

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        """Period from two samples to twice the longest searched, decay up to twenty times
        that (120 s and 1200 s at the flume's 1.2 s), amplitude within ±50 mm per mm."""
        ts = ctx.data.sample_period_s
        longest = seiche_longest_period_s(ts)
        return [2.0 * ts, 0.5 * ts, -50.0], [2.0 * longest, 20.0 * longest, 50.0]

    def starts(self, ctx: Context) -> list[list[float]]:
        period = ctx.estimate(self.kind, "period_s", 10.0)
        amp = ctx.estimate(self.kind, "amplitude_mm_per_mm", ctx.sigma_mm / ctx.typical_move_mm)
        decay = ctx.estimate(self.kind, "decay_time_s", 2.0 * period)
        return [[period, decay, amp], [period, 4.0 * period, amp], [period, decay, -amp]]

    def immaterial(self, fit: Fit, ctx: Context) -> str:
        period, decay = fit.value("period_s"), fit.value("decay_time_s")
        amplitude = abs(fit.value("amplitude_mm_per_mm")) * ctx.typical_move_mm
        if amplitude < ctx.sigma_mm:
            return f"a typical move excites {amplitude:.2g} mm, below the noise floor"
        if period < 2.0 * ctx.data.sample_period_s:
            return f"a period of {period:.2g} s is not observable at this sample period"
        if decay < period / 4.0:
            return "it decays within a quarter period: no oscillation"
        return ""
