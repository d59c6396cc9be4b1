"""Candidate ``opening_nonlinearity``: the gain depends on the opening, ``K exp(s (e - e_ref))``.

Signature: the per-move gains fall (or rise) with the opening at which the move happens.
Start: the slope of their logarithm against the move's mid opening.
"""

from __future__ import annotations

import numpy as np

from gatetwin.diagnosis.candidates.base import Candidate, Context

__all__ = ["NonlinearityCandidate"]


class NonlinearityCandidate(Candidate):
    kind = "opening_nonlinearity"
    names = ("gain_slope_per_mm",)

    def applies(self, ctx: Context) -> str:
        if np.unique(ctx.data.command_mm).size < 3:
            return "fewer than three openings: a gain varying with the opening is not identifiable"
        return super().applies(ctx)

    def bounds(self, ctx: Context) -> tuple[list[float], list[float]]:
        return [-0.2], [0.2]

    def starts(self, ctx: Context) -> list[list[float]]:
        guess = ctx.estimate(self.kind, "gain_slope_per_mm", -0.02)
        return [[guess], [-0.03], [0.03]]
