"""ARX order search: information criteria and hold-out validation over an order grid.

Every candidate ARX(na, nb, nk) is fitted on the *estimation* part and judged by

* AIC = ``N ln(SSR/N) + 2p`` and BIC = ``N ln(SSR/N) + p ln N`` on the estimation part,
* the one-step RMSE on the hold-out part, and
* the free-run fit % and RMSE on the hold-out part (simulation, no measured level fed
  back; the opening during actuator motion must already be reconstructed).

All candidates use the **same regression rows**: the first ``L = max(na, nk+nb-1)`` over
the whole grid are dropped from every segment, so the criteria compare models on one
data set. The lag-product matrix is formed once for the largest lags and every candidate
solves a sub-block of it (:mod:`gatetwin.identification.lagproducts`), which is what makes the
75-model search cheap. The hold-out one-step error is a quadratic form in the hold-out
lag-product matrix; only the free runs touch the samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import ArxFit, check_orders, deviations, fit_from_lag_products
from gatetwin.identification.lagproducts import LagProducts, lag_products
from gatetwin.identification.metrics import free_run_on_segments, is_stable
from gatetwin.identification.preprocess import Segments, constant_within_segments, holdout_split
from gatetwin.identification.serial import finite_or_none

__all__ = ["CRITERIA", "Holdout", "OrderChoice", "OrderRow", "choose", "search_orders"]

#: A hold-out given as a fraction of the record duration or as explicit segment sets.
Holdout = float | tuple[Segments, Segments]

#: Criteria :func:`choose` knows, and whether larger is better.
CRITERIA = {"aic": False, "bic": False, "holdout_rmse": False, "holdout_fit": True}


@dataclass(frozen=True)
class OrderRow:
    """One candidate of an order search.

    Attributes
    ----------
    na, nb, nk : int
        Orders.
    n_params : int
        ``na + nb``.
    n_rows : int
        Estimation rows (common to all candidates).
    aic, bic : float
        Information criteria on the estimation part.
    holdout_rmse_mm : float
        One-step-ahead RMSE on the hold-out part, mm.
    holdout_fit_percent : float
        Free-run fit % on the hold-out part (NaN for an unstable model: not simulated).
    holdout_sim_rmse_mm : float
        Free-run RMSE on the hold-out part, mm (NaN for an unstable model).
    stable : bool
        All poles inside the unit circle.
    identifiable : bool
        False when the candidate's normal equations are singular (e.g. ``nb >= 2`` on
        hold-only rows with one opening per segment); its scores are then NaN.
    """

    na: int
    nb: int
    nk: int
    n_params: int
    n_rows: int
    aic: float
    bic: float
    holdout_rmse_mm: float
    holdout_fit_percent: float
    holdout_sim_rmse_mm: float
    stable: bool
    identifiable: bool = True

    @property
    def orders(self) -> tuple[int, int, int]:
        return (self.na, self.nb, self.nk)

    def value(self, criterion: str) -> float:
        """The row's value of a :data:`CRITERIA` name."""
        return {
            "aic": self.aic,
            "bic": self.bic,
            "holdout_rmse": self.holdout_rmse_mm,
            "holdout_fit": self.holdout_fit_percent,
        }[criterion]

    def to_dict(self) -> dict[str, Any]:
        return {
            "na": self.na,
            "nb": self.nb,
            "nk": self.nk,
            "n_params": self.n_params,
            "n_rows": self.n_rows,
            "aic": finite_or_none(self.aic),
            "bic": finite_or_none(self.bic),
            "holdout_rmse_mm": finite_or_none(self.holdout_rmse_mm),
            "holdout_fit_percent": finite_or_none(self.holdout_fit_percent),
            "holdout_sim_rmse_mm": finite_or_none(self.holdout_sim_rmse_mm),
            "stable": self.stable,
            "identifiable": self.identifiable,
        }


def _grid(
    na_range: Sequence[int], nb_range: Sequence[int], nk_range: Sequence[int]
) -> list[tuple[int, int, int]]:
    grid = [(int(a), int(b), int(k)) for a in na_range for b in nb_range for k in nk_range]
    if not grid:
        raise IdentificationError("order search needs at least one candidate order")
    for orders in grid:
        check_orders(*orders)
    return grid


def _holdout_rmse(products: LagProducts, theta: np.ndarray, orders: tuple[int, int, int]) -> float:
    gram, rhs, yy = products.block(*orders)
    ssr = yy - 2.0 * float(theta @ rhs) + float(theta @ gram @ theta)
    return float(np.sqrt(max(ssr, 0.0) / products.n_rows)) if products.n_rows else float("nan")


def search_orders(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    na_range: Sequence[int] = range(1, 6),
    nb_range: Sequence[int] = range(1, 6),
    nk_range: Sequence[int] = range(0, 3),
    *,
    holdout: Holdout = 0.3,
    time_s: np.ndarray | None = None,
    sample_period_s: float = 1.2,
) -> tuple[OrderRow, ...]:
    """Fit and score every ARX order of a grid.

    Parameters
    ----------
    u : ndarray
        Gate opening at every sample, mm. Only hold-segment values enter the fits; the
        free runs need it finite over the hold-out span (use
        :func:`~gatetwin.identification.preprocess.reconstructed_opening`).
    y : ndarray
        Level, mm (NaN allowed; it splits segments).
    segments : sequence of (int, int) or ndarray
        Hold segments, ``stop`` exclusive.
    na_range, nb_range, nk_range : sequence of int
        Candidate orders (default 1..5, 1..5, 0..2: 75 models).
    holdout : float or (segments, segments), optional
        Share of the record, by time, held out at its end (default 0.3), or explicit
        ``(estimation_segments, validation_segments)``.
    time_s : ndarray, optional
        Sample times, s, for a fractional split by time (by index without it).
    sample_period_s : float, optional
        Sample period, s.

    Returns
    -------
    tuple of OrderRow
        One row per candidate, in grid order.
    """
    y = np.asarray(y, dtype=float)
    grid = _grid(na_range, nb_range, nk_range)
    if isinstance(holdout, tuple):
        est_seg, val_seg = holdout
    else:
        est_seg, val_seg = holdout_split(segments, y.size, fraction=holdout, time_s=time_s)
    drop = max(max(na, nk + nb - 1) for na, nb, nk in grid)
    y_lags = range(0, max(g[0] for g in grid) + 1)
    u_lags = range(min(g[2] for g in grid), max(g[2] + g[1] for g in grid))
    est = deviations(u, y, est_seg)
    point = (est.opening_mean_mm, est.level_mean_mm)
    val = deviations(u, y, val_seg, operating_point=point)
    lp_est = lag_products(est.u0, est.y0, est.segments, y_lags, u_lags, drop)
    lp_val = lag_products(val.u0, val.y0, val.segments, y_lags, u_lags, drop)
    constant_input = constant_within_segments(est.u0, est.segments, est.mask)
    rows = []
    for orders in grid:
        if constant_input and orders[1] >= 2:
            rows.append(_unidentifiable(orders, lp_est.n_rows))
            continue
        try:
            fit = fit_from_lag_products(lp_est, *orders, point, sample_period_s)
        except IdentificationError:
            rows.append(_unidentifiable(orders, lp_est.n_rows))
            continue
        rows.append(_score(fit, lp_est.n_rows, lp_val, u, y, val.segments))
    return tuple(rows)


def _unidentifiable(orders: tuple[int, int, int], n_rows: int) -> OrderRow:
    nan = float("nan")
    p = orders[0] + orders[1]
    return OrderRow(*orders, p, n_rows, nan, nan, nan, nan, nan, False, identifiable=False)


def _score(
    fit: ArxFit,
    n: int,
    lp_val: LagProducts,
    u: np.ndarray,
    y: np.ndarray,
    val_segments: np.ndarray,
) -> OrderRow:
    p = fit.n_params
    log_term = n * np.log(max(fit.noise_variance_mm2 * (n - p) / n, 1e-300))
    stable = is_stable(fit.a)
    sim_fit, sim_rmse = float("nan"), float("nan")
    if stable:
        _, sim = free_run_on_segments(fit, u, y, val_segments)
        sim_fit, sim_rmse = sim.fit_percent, sim.rmse_mm
    orders = (fit.na, fit.nb, fit.nk)
    return OrderRow(
        *orders,
        n_params=p,
        n_rows=n,
        aic=float(log_term + 2 * p),
        bic=float(log_term + p * np.log(n)),
        holdout_rmse_mm=_holdout_rmse(lp_val, fit.theta, orders),
        holdout_fit_percent=sim_fit,
        holdout_sim_rmse_mm=sim_rmse,
        stable=stable,
    )


@dataclass(frozen=True)
class OrderChoice:
    """The order picked from a search table, and why.

    Attributes
    ----------
    row : OrderRow
        The chosen candidate.
    criterion : str
        The criterion that chose it (a :data:`CRITERIA` name).
    reason : str
        One sentence saying so, for reports.
    """

    row: OrderRow
    criterion: str
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"criterion": self.criterion, "reason": self.reason, **self.row.to_dict()}


def choose(table: Sequence[OrderRow], criterion: str = "bic") -> OrderChoice:
    """Pick the best candidate of an order-search table.

    Parameters
    ----------
    table : sequence of OrderRow
        Output of :func:`search_orders`.
    criterion : {"bic", "aic", "holdout_rmse", "holdout_fit"}
        Minimum BIC / AIC / hold-out one-step RMSE, or maximum hold-out free-run fit %.
        Unstable candidates are passed over whenever a stable one exists; ties go to the
        candidate with fewer parameters, then to lower orders.

    Returns
    -------
    OrderChoice
    """
    if criterion not in CRITERIA:
        raise IdentificationError(
            f"unknown order criterion {criterion!r} (expected one of {', '.join(CRITERIA)})"
        )
    rows = [r for r in table if np.isfinite(r.value(criterion))]
    stable_rows = [r for r in rows if r.stable]
    pool = stable_rows or rows
    if not pool:
        raise IdentificationError(f"no candidate has a finite {criterion}")
    sign = -1.0 if CRITERIA[criterion] else 1.0
    best = min(pool, key=lambda r: (sign * r.value(criterion), r.n_params, r.orders))
    scope = "stable candidates" if stable_rows else "candidates (none stable)"
    better = "highest" if CRITERIA[criterion] else "lowest"
    reason = (
        f"ARX({best.na},{best.nb},{best.nk}) has the {better} {criterion} "
        f"({best.value(criterion):.6g}) of {len(pool)} {scope}"
    )
    return OrderChoice(best, criterion, reason)
