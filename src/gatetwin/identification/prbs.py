"""PRBS-test identification of a :class:`~gatetwin.records.Record`: one gauge, one ARX model.

The chain, each step a plain function of :mod:`gatetwin.identification`:

1. opening during actuator motion reconstructed (constant actuator speed);
2. rows: ``"hold"`` (the reference study: hold samples only, lags inside one hold
   segment) or ``"all"`` (every sample with a finite level, segments cut only at time
   gaps, the reconstructed opening used during motion). ``"auto"`` takes ``"hold"``
   unless the opening is constant within every hold segment -- then hold rows identify
   only ``b1 + ... + b_nb`` and ``"all"`` is used; the output says which and why;
3. spikes corrected by a Hampel filter inside each segment; NaNs split segments;
4. orders fixed, or searched over na, nb in 1..5, nk in 0..2 and chosen by a criterion;
5. final fit on all segments; one-step metrics (in-sample, as in the paper), residual
   whiteness, poles; free-run fit % and RMSE on the hold-out part (the last 30 % by
   time) of a model fitted on the estimation part only, and of the final model over
   the whole record.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import ArxFit, fit_arx, predict_one_step
from gatetwin.identification.metrics import (
    DominantPole,
    OneStepMetrics,
    SimulationMetrics,
    Whiteness,
    arx_poles,
    dc_gain,
    dominant_pole,
    free_run_on_segments,
    is_stable,
    one_step_metrics,
    residual_whiteness,
)
from gatetwin.identification.orders import OrderChoice, OrderRow, choose, search_orders
from gatetwin.identification.preprocess import (
    constant_within_segments,
    continuous_segments,
    hampel_filter,
    holdout_split,
    reconstructed_opening,
    record_segments,
    segment_mask,
    split_segments,
)
from gatetwin.identification.serial import finite_or_none
from gatetwin.identification.step import hold_mean_flow
from gatetwin.records import Record

__all__ = ["ROWS", "PrbsIdentification", "PrbsSignals", "identify_prbs", "prbs_signals"]

ROWS = ("auto", "hold", "all")


@dataclass(frozen=True)
class PrbsIdentification:
    """ARX identification of one gauge of a PRBS record.

    Attributes
    ----------
    gauge : str
        Gauge name.
    rows : str
        ``"hold"`` or ``"all"``: which samples formed regression rows.
    rows_reason : str
        Why those rows.
    fit : ArxFit
        Final model, fitted on every segment.
    one_step : OneStepMetrics
        One-step-ahead metrics of ``fit`` on its own rows (the paper's R², MAE, RMSE).
    simulation : SimulationMetrics
        Free run on the hold-out part of a model fitted on the estimation part.
    simulation_full : SimulationMetrics
        Free run of ``fit`` over the whole record, scored on the segments.
    whiteness : Whiteness
        Residual tests of ``fit``.
    dominant : DominantPole
        Dominant pole and time constant of ``fit``.
    criterion : str
        ``"fixed"`` when the orders were given, else the criterion that chose them.
    choice : OrderChoice or None
        The order choice, when searched.
    orders_table : tuple of OrderRow
        The order search table (empty when the orders were given).
    spikes_replaced : int
        Level samples replaced by the Hampel filter.
    flow_m3h : float
        Mean discharge over hold samples, m³/h.
    holdout_fraction : float
        Share of the record (by time) held out for the simulation metrics.
    """

    gauge: str
    rows: str
    rows_reason: str
    fit: ArxFit
    one_step: OneStepMetrics
    simulation: SimulationMetrics
    simulation_full: SimulationMetrics
    whiteness: Whiteness
    dominant: DominantPole
    criterion: str
    choice: OrderChoice | None
    orders_table: tuple[OrderRow, ...]
    spikes_replaced: int
    flow_m3h: float
    holdout_fraction: float

    @property
    def dc_gain_mm_per_mm(self) -> float:
        return dc_gain(self.fit.a, self.fit.b)

    @property
    def stable(self) -> bool:
        return is_stable(self.fit.a)

    def to_dict(self) -> dict[str, Any]:
        fit = self.fit
        return {
            "test": "prbs",
            "gauge": self.gauge,
            "na": fit.na,
            "nb": fit.nb,
            "nk": fit.nk,
            "a": list(fit.a),
            "b": list(fit.b),
            "a_se": list(fit.a_se),
            "b_se": list(fit.b_se),
            "operating_point": {
                "opening_mm": fit.opening_mean_mm,
                "level_mm": fit.level_mean_mm,
            },
            "noise_variance_mm2": fit.noise_variance_mm2,
            "n_rows": fit.n_rows,
            "sample_period_s": fit.sample_period_s,
            "rows": self.rows,
            "rows_reason": self.rows_reason,
            "one_step": self.one_step.to_dict(),
            "simulation": {
                **self.simulation.to_dict(),
                "span": f"last {self.holdout_fraction:.0%} of the record",
                "model": "fitted on the estimation part only",
            },
            "simulation_full": self.simulation_full.to_dict(),
            "dc_gain": finite_or_none(self.dc_gain_mm_per_mm),
            "time_constant_s": self.dominant.time_constant_s,
            "dominant_pole": self.dominant.to_dict(),
            "stable": self.stable,
            "poles": [[float(p.real), float(p.imag)] for p in arx_poles(fit.a)],
            "whiteness": self.whiteness.to_dict(),
            "criterion": self.criterion,
            "choice_reason": self.choice.reason if self.choice else "orders given",
            "orders": [r.to_dict() for r in self.orders_table],
            "spikes_replaced": self.spikes_replaced,
            "flow_m3h": finite_or_none(self.flow_m3h),
            "model": fit.to_dict(),
        }


def _pick_rows(
    record: Record, u: np.ndarray, level: np.ndarray, rows: str
) -> tuple[str, np.ndarray, str]:
    """Segments and a one-line reason for the row choice."""
    if rows not in ROWS:
        raise IdentificationError(f"rows must be one of {', '.join(ROWS)}, got {rows!r}")
    holds = split_segments(record_segments(record), u, level)
    if rows == "hold":
        return "hold", holds, "hold samples only, as in the reference study (requested)"
    everything = continuous_segments(record.time_s, record.sample_period_s)
    if rows == "all":
        return "all", everything, "all samples, opening reconstructed during motion (requested)"
    if holds.size and not constant_within_segments(u, holds):
        return "hold", holds, "hold samples only, as in the reference study"
    return (
        "all",
        everything,
        (
            "all samples, opening reconstructed during motion: the opening is constant within "
            "every hold segment, so hold rows identify only the sum of the b coefficients"
        ),
    )


def identify_prbs(
    record: Record,
    gauge: str = "3F",
    orders: tuple[int, int, int] | str = (2, 2, 1),
    *,
    criterion: str = "bic",
    rows: str = "auto",
    holdout_fraction: float = 0.3,
    max_lag: int = 25,
    spike_floor_mm: float = 0.0,
) -> PrbsIdentification:
    """Identify an ARX model of one gauge from a PRBS record.

    Parameters
    ----------
    record : Record
        A read record.
    gauge : str, optional
        Gauge name (default ``"3F"``, as in the reference study).
    orders : (na, nb, nk) or "auto", optional
        Fixed orders (default the paper's ARX(2,2,1)) or ``"auto"`` for an order search
        over na, nb in 1..5 and nk in 0..2.
    criterion : {"bic", "aic", "holdout_rmse", "holdout_fit"}, optional
        Order criterion for ``orders="auto"`` (default BIC).
    rows : {"auto", "hold", "all"}, optional
        Regression rows (see the module docstring; default ``"auto"``).
    holdout_fraction : float, optional
        Share of the record, by time, held out at its end (default 0.3).
    max_lag : int, optional
        Largest lag of the whiteness tests (default 25).
    spike_floor_mm : float, optional
        Smallest deviation from the window median that the Hampel filter may call a
        spike, mm (default 0: the plain ``4 x 1.4826 x MAD`` rule, which on clean noisy
        data also replaces ~0.2-0.3 % of the samples).

    Returns
    -------
    PrbsIdentification

    Raises
    ------
    IdentificationError
        Unknown gauge, too little data, singular regression.
    """
    where = record.path or "record"
    if gauge not in record.levels_mm:
        raise IdentificationError(
            f"{where}: no gauge {gauge}; it has {', '.join(record.gauges) or 'none'}"
        )
    try:
        return _identify(
            record,
            gauge,
            orders,
            criterion=criterion,
            rows=rows,
            fraction=holdout_fraction,
            max_lag=max_lag,
            spike_floor=spike_floor_mm,
        )
    except IdentificationError as exc:
        raise IdentificationError(f"{where}, gauge {gauge}: {exc}") from None


@dataclass(frozen=True)
class PrbsSignals:
    """One gauge of a PRBS record, prepared for fitting (steps 1-3 of the module docstring).

    Attributes
    ----------
    u : ndarray
        Opening, mm, reconstructed during actuator motion (finite everywhere).
    y : ndarray
        Level after spike correction, mm.
    segments : ndarray of shape (n, 2)
        Segments of the chosen rows (before cutting at NaNs).
    fit_segments : ndarray of shape (n, 2)
        ``segments`` cut at every NaN of ``u`` or ``y``.
    estimation, validation : ndarray of shape (n, 2)
        ``fit_segments`` split at ``1 - holdout_fraction`` of the record's duration.
    rows, rows_reason : str
        ``"hold"`` or ``"all"`` and why.
    spikes_replaced : int
        Level samples replaced by the Hampel filter.
    time_s : ndarray
        Sample times, s.
    sample_period_s : float
        Sample period, s.
    """

    u: np.ndarray
    y: np.ndarray
    segments: np.ndarray
    fit_segments: np.ndarray
    estimation: np.ndarray
    validation: np.ndarray
    rows: str
    rows_reason: str
    spikes_replaced: int
    time_s: np.ndarray
    sample_period_s: float


def prbs_signals(
    record: Record, gauge: str, *, rows: str, holdout_fraction: float, spike_floor_mm: float
) -> PrbsSignals:
    """Reconstruct the opening, pick the rows, correct spikes and split off the hold-out.

    Parameters are those of :func:`identify_prbs`; ``gauge`` must be in the record.
    """
    u = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    raw = np.asarray(record.levels_mm[gauge], dtype=float)
    used, segs, reason = _pick_rows(record, u, raw, rows)
    spikes = hampel_filter(raw, segs, floor=spike_floor_mm)
    y = spikes.values
    fit_segments = split_segments(segs, u, y)
    est, val = holdout_split(fit_segments, y.size, fraction=holdout_fraction, time_s=record.time_s)
    return PrbsSignals(
        u=u,
        y=y,
        segments=segs,
        fit_segments=fit_segments,
        estimation=est,
        validation=val,
        rows=used,
        rows_reason=reason,
        spikes_replaced=spikes.n_replaced,
        time_s=record.time_s,
        sample_period_s=record.sample_period_s,
    )


def _identify(
    record: Record,
    gauge: str,
    orders: tuple[int, int, int] | str,
    *,
    criterion: str,
    rows: str,
    fraction: float,
    max_lag: int,
    spike_floor: float,
) -> PrbsIdentification:
    sig = prbs_signals(
        record, gauge, rows=rows, holdout_fraction=fraction, spike_floor_mm=spike_floor
    )
    u, y, segs = sig.u, sig.y, sig.segments
    ts, t = sig.sample_period_s, sig.time_s
    table: tuple[OrderRow, ...] = ()
    choice = None
    if isinstance(orders, str):
        if orders != "auto":
            raise IdentificationError(f"orders must be (na, nb, nk) or 'auto', got {orders!r}")
        table = search_orders(u, y, segs, holdout=fraction, time_s=t, sample_period_s=ts)
        choice = choose(table, criterion)
        orders = choice.row.orders
    na, nb, nk = orders
    fit = fit_arx(u, y, segs, na, nb, nk, sample_period_s=ts)
    pred = predict_one_step(fit, u, y, segs)
    inputs = np.where(segment_mask(sig.fit_segments, y.size), u, np.nan)
    fit_est = fit_arx(u, y, sig.estimation, na, nb, nk, sample_period_s=ts)
    return PrbsIdentification(
        gauge=gauge,
        rows=sig.rows,
        rows_reason=sig.rows_reason,
        fit=fit,
        one_step=one_step_metrics(y, pred),
        simulation=free_run_on_segments(fit_est, u, y, sig.validation)[1],
        simulation_full=free_run_on_segments(fit, u, y, sig.fit_segments)[1],
        whiteness=residual_whiteness(y - pred, inputs, max_lag=max_lag, n_fitted=na),
        dominant=dominant_pole(fit.a, ts),
        criterion=choice.criterion if choice else "fixed",
        choice=choice,
        orders_table=table,
        spikes_replaced=sig.spikes_replaced,
        flow_m3h=hold_mean_flow(record),
        holdout_fraction=fraction,
    )
