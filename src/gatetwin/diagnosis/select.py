"""Fit every candidate on top of the baseline and pick the one that earns its parameters.

Criterion, all on free-run residuals (never one-step predictions):

* **score** -- the BIC difference with an effective sample size,
  ``n_eff ln(RSS_base / RSS_cand) - k ln(n_eff)`` on the fitted part, ``k`` the block's
  parameters and ``n_eff = n (1 - r1) / (1 + r1)`` from the candidate's residual lag-1
  autocorrelation (correlated residuals carry less information than their count);
  positive favours the candidate, above :data:`SCORE_THRESHOLD` (10, "very strong") it is
  *significant* -- if it also lowers the RMSE on the **held-out** part;
* **material** -- the block must change the simulated level by at least the noise floor
  (moving RMS over :data:`CONTRIBUTION_WINDOW` samples) and pass its own physical check
  (:meth:`Candidate.immaterial`); a significant but immaterial fit counts as ``none``;
* **whiteness** -- the Ljung-Box statistic of the whole-record residual, reported, and the
  tie-breaker between scores within :data:`TIE_SCORE`.

The winner is the significant, material candidate with the highest score; else ``none``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from gatetwin.diagnosis.baseline import record_span_s
from gatetwin.diagnosis.candidates import CANDIDATES, Candidate, Context
from gatetwin.diagnosis.fitting import Fit, fit_plant, grid_start, plant_parametrization, rmse
from gatetwin.diagnosis.grid_sim import simulate_grid
from gatetwin.errors import GatetwinError
from gatetwin.identification.metrics import Whiteness, residual_whiteness

__all__ = [
    "CONTRIBUTION_WINDOW",
    "SCORE_THRESHOLD",
    "TIE_SCORE",
    "WHITENESS_LAGS",
    "CandidateResult",
    "block_contribution",
    "choose",
    "evaluate",
    "fit_candidate",
    "rmse_parts",
    "score",
    "whiteness",
]

SCORE_THRESHOLD = 10.0
TIE_SCORE = 2.0
CONTRIBUTION_WINDOW = 20
WHITENESS_LAGS = 25


@dataclass(frozen=True)
class CandidateResult:
    """One candidate's fit and verdict.

    Attributes
    ----------
    effect : str
        Block kind.
    suggested : bool
        Its residual signature pointed at it.
    not_applicable : str
        Why it was not fitted ("" when it was).
    fit : Fit or None
        The joint fit (baseline adjustments and block).
    rmse_mm : dict
        RMSE on the ``fit``, ``holdout`` and ``all`` samples, mm.
    score : float
        BIC difference against the refitted baseline (module docstring).
    significant : bool
        Score above the threshold and a lower hold-out RMSE.
    immaterial : str
        Why the fit is physically immaterial ("" when material).
    whiteness : Whiteness or None
        Residual tests over the whole record.
    """

    effect: str
    suggested: bool
    not_applicable: str = ""
    fit: Fit | None = None
    rmse_mm: dict[str, float] | None = None
    score: float = -math.inf
    significant: bool = False
    immaterial: str = ""
    whiteness: Whiteness | None = None

    @property
    def eligible(self) -> bool:
        return self.fit is not None and self.significant and not self.immaterial

    def block_parameters(self, candidate: Candidate) -> dict[str, Any]:
        if self.fit is None:
            return {}
        all_params = self.fit.parameters()
        return {name: all_params[name] for name in candidate.names}

    def to_dict(self, candidate: Candidate) -> dict[str, Any]:
        out: dict[str, Any] = {"effect": self.effect, "suggested_by_signature": self.suggested}
        if self.fit is None:
            return {**out, "params": None, "rmse_mm": None, "score": None,
                    "significant": False, "not_fitted": self.not_applicable}  # fmt: skip
        params = self.block_parameters(candidate)
        return {
            **out,
            "params": {k: v["value"] for k, v in params.items()},
            "standard_errors": {k: v["se"] for k, v in params.items()},
            "ci95": {k: v["ci95"] for k, v in params.items()},
            "baseline_adjustments": {n: float(self.fit.theta[i]) for i, n in
                                     enumerate(self.fit.names) if n not in candidate.names},
            "rmse_mm": self.rmse_mm["all"], "rmse_fit_mm": self.rmse_mm["fit"],
            "rmse_holdout_mm": self.rmse_mm["holdout"], "score": self.score,
            "significant": self.significant, "material": not self.immaterial,
            "immaterial_because": self.immaterial or None,
            "ljung_box_q": self.whiteness.ljung_box_q if self.whiteness else None,
            "converged": self.fit.converged,
        }  # fmt: skip


def rmse_parts(ctx: Context, simulated: np.ndarray) -> dict[str, float]:
    d = ctx.data
    return {"fit": rmse(d.level_mm, simulated, d.fit_mask),
            "holdout": rmse(d.level_mm, simulated, d.holdout_mask),
            "all": rmse(d.level_mm, simulated, d.valid)}  # fmt: skip


def whiteness(ctx: Context, simulated: np.ndarray) -> Whiteness | None:
    r = np.where(ctx.data.valid, ctx.data.level_mm - simulated, np.nan)
    try:
        return residual_whiteness(r[np.isfinite(r)], max_lag=WHITENESS_LAGS)
    except GatetwinError:
        return None


def score(base: Fit, cand: Fit, k: int) -> float:
    """``n_eff ln(RSS_base / RSS_cand) - k ln(n_eff)``."""
    n_eff = cand.n_effective
    if cand.rss_mm2 <= 0 or base.rss_mm2 <= 0:
        return math.inf if cand.rss_mm2 < base.rss_mm2 else -math.inf
    return float(n_eff * math.log(base.rss_mm2 / cand.rss_mm2) - k * math.log(n_eff))


def _without(fit: Fit, kind: str) -> Any:
    return replace(fit.plant, effects=tuple(e for e in fit.plant.effects if e["kind"] != kind))


def block_contribution(ctx: Context, fit: Fit, kind: str) -> float:
    """Peak moving RMS of what block ``kind`` adds to the simulated level, mm."""
    delta = fit.simulated_mm - simulate_grid(_without(fit, kind), ctx.data.grid)
    w = CONTRIBUTION_WINDOW
    ms = np.convolve(delta * delta, np.ones(w) / w, mode="valid")
    return float(np.sqrt(ms.max())) if ms.size else float(np.max(np.abs(delta)))


def _immaterial(candidate: Candidate, ctx: Context, fit: Fit) -> str:
    reason = candidate.immaterial(fit, ctx)
    if reason:
        return reason
    size = block_contribution(ctx, fit, candidate.kind)
    if size < ctx.sigma_mm:
        return (f"it changes the simulated level by at most {size:.2g} mm (moving RMS), below "
                f"the noise floor {ctx.sigma_mm:.2g} mm")  # fmt: skip
    return ""


def _starts(candidate: Candidate, ctx: Context, param: Any) -> list[np.ndarray]:
    """The refitted baseline with each block start, and a grid start for each (FOPDT)."""
    adjust = ctx.base_fit.theta
    blocks = [np.asarray(s, float) for s in candidate.starts(ctx)]
    starts = [np.concatenate([adjust, b]) for b in blocks]
    amp = candidate.names.index(candidate.amplitude) if candidate.amplitude else None
    grid = (grid_start(param, ctx.data, ctx.base, b, amp) for b in blocks)
    return starts + [s for s in grid if s is not None]


def fit_candidate(candidate: Candidate, ctx: Context, suggested: bool) -> CandidateResult:
    """Fit one candidate jointly with the baseline adjustments and judge it."""
    why_not = candidate.applies(ctx)
    if why_not:
        return CandidateResult(candidate.kind, suggested, not_applicable=why_not)
    lower, upper = candidate.bounds(ctx)
    param = plant_parametrization(
        ctx.base, candidate.names, lower, upper,
        lambda plant, values: candidate.make(plant, values, ctx),
        max_time_constant_s=record_span_s(ctx.data),
    )  # fmt: skip
    try:
        fit = fit_plant(
            param, _starts(candidate, ctx, param), ctx.data, max_starts=candidate.max_starts
        )
    except GatetwinError as exc:
        return CandidateResult(candidate.kind, suggested, not_applicable=f"fit failed: {exc}")
    parts = rmse_parts(ctx, fit.simulated_mm)
    base_parts = rmse_parts(ctx, ctx.base_fit.simulated_mm)
    value = score(ctx.base_fit, fit, len(candidate.names))
    significant = value > SCORE_THRESHOLD and parts["holdout"] < base_parts["holdout"]
    return CandidateResult(
        candidate.kind, suggested, fit=fit, rmse_mm=parts, score=value, significant=significant,
        immaterial=_immaterial(candidate, ctx, fit), whiteness=whiteness(ctx, fit.simulated_mm),
    )  # fmt: skip


def evaluate(ctx: Context) -> list[CandidateResult]:
    """Every candidate's result, in the blocks' evaluation order."""
    return [
        fit_candidate(c, ctx, bool(ctx.signatures.get(c.kind) and ctx.signatures[c.kind].suggests))
        for c in CANDIDATES
    ]


def choose(results: list[CandidateResult]) -> CandidateResult | None:
    """The winner (module docstring), or None for ``none``."""
    eligible = sorted((r for r in results if r.eligible), key=lambda r: -r.score)
    if not eligible:
        return None
    best = eligible[0]
    close = [r for r in eligible if best.score - r.score <= TIE_SCORE and r.whiteness]
    if len(close) > 1:
        return min(close, key=lambda r: r.whiteness.ljung_box_q)
    return best
