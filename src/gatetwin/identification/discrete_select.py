"""Choose the discrete model structure that simulates best: ARX, OE, ARMAX or Box-Jenkins.

An FMU always runs free: no measured level is fed back. Equation-error ARX (the reference
study's method) is a one-step predictor and is biased when the level noise is coloured;
output-error (:mod:`~gatetwin.identification.oe`), ARMAX (:mod:`~gatetwin.identification.armax`)
and Box-Jenkins (:mod:`~gatetwin.identification.bj`) fits are not, in their own noise
assumptions. For one gauge of a PRBS record, :func:`select_discrete`

1. prepares the signals exactly as :func:`~gatetwin.identification.prbs.identify_prbs` does
   (opening reconstructed during motion, rows, spike correction, hold-out split);
2. fits every structure with the same ``B`` and ``A``/``F`` orders (ARMAX's ``C`` and
   BJ's ``C``, ``D`` default to the order of ``A``/``F``) on all segments, and again on
   the estimation part (the first 70 % by time);
3. scores each: one-step metrics of its own predictor on its rows (for OE the one-step
   predictor is the simulation), free-run fit % on the hold-out part of the
   estimation-part model (initialised as in
   :func:`~gatetwin.identification.metrics.free_run_on_segments`), free run of the full model;
4. picks the stable candidate with the highest hold-out free-run fit; a tie (within
   :data:`TIE_PERCENT`) goes to the simpler structure, in the order ARX, OE, ARMAX, BJ.

The chosen model's deterministic part has the ARX coefficient layout
(``"simulation_coefficients"``); its noise model is reported, not simulated.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.armax import fit_armax
from gatetwin.identification.arx import ArxFit, deviations, fit_arx
from gatetwin.identification.bj import fit_bj
from gatetwin.identification.metrics import (
    OneStepMetrics,
    SimulationMetrics,
    Whiteness,
    dc_gain,
    dominant_pole,
    free_run_on_segments,
    one_step_metrics,
    residual_whiteness,
)
from gatetwin.identification.oe import fit_oe
from gatetwin.identification.pem import STRUCTURES, one_step_prediction
from gatetwin.identification.pemfit import PemFit, from_arx
from gatetwin.identification.prbs import PrbsSignals, prbs_signals
from gatetwin.identification.preprocess import Segments, segment_mask
from gatetwin.identification.serial import finite_or_none
from gatetwin.records import Record

__all__ = [
    "TIE_PERCENT",
    "DiscreteCandidate",
    "DiscreteSelection",
    "StructureOrders",
    "choose_structure",
    "compare_structures",
    "fit_estimation_summary",
    "fit_structure",
    "score_candidate",
    "select_discrete",
]

#: Hold-out fits closer than this (percentage points) count as a tie.
TIE_PERCENT = 1e-6


@dataclass(frozen=True)
class DiscreteCandidate:
    """One structure fitted and scored.

    Attributes
    ----------
    fit : PemFit
        Fitted on all segments.
    fit_estimation : PemFit
        Fitted on the estimation part only (scored on the hold-out part).
    one_step : OneStepMetrics
        One-step-ahead metrics of ``fit``'s own predictor on its rows (in-sample).
    simulation : SimulationMetrics
        Free run of ``fit_estimation`` on the hold-out part.
    simulation_full : SimulationMetrics
        Free run of ``fit`` over the whole record, scored on the segments.
    whiteness : Whiteness
        Residual tests of ``fit``'s one-step prediction errors.
    """

    fit: PemFit
    fit_estimation: PemFit
    one_step: OneStepMetrics
    simulation: SimulationMetrics
    simulation_full: SimulationMetrics
    whiteness: Whiteness

    @property
    def structure(self) -> str:
        return self.fit.structure

    @property
    def stable(self) -> bool:
        """Both fits stable with invertible noise filters."""
        return self.fit.stable and self.fit_estimation.stable

    def to_dict(self) -> dict[str, Any]:
        fit = self.fit
        return {
            "structure": fit.structure,
            "label": fit.orders.label(),
            "one_step": self.one_step.to_dict(),
            "simulation": self.simulation.to_dict(),
            "simulation_full": self.simulation_full.to_dict(),
            "dc_gain": finite_or_none(dc_gain(fit.a, fit.b)),
            "stable": self.stable,
            "poles": [[float(p.real), float(p.imag)] for p in fit.poles],
            "dominant_pole": dominant_pole(fit.a, fit.sample_period_s).to_dict(),
            "whiteness": self.whiteness.to_dict(),
            "model": fit.to_dict(),
            "model_estimation": fit_estimation_summary(self.fit_estimation),
        }


def fit_estimation_summary(fit: PemFit) -> dict[str, Any]:
    """Coefficients of the estimation-part fit (what the hold-out score belongs to)."""
    return {
        "a": list(fit.a),
        "b": list(fit.b),
        "c": list(fit.c),
        "d": list(fit.d),
        "n_rows": fit.n_rows,
        "stable": fit.stable,
    }


@dataclass(frozen=True)
class DiscreteSelection:
    """Candidates of one gauge of a PRBS record and the one that simulates best.

    Attributes
    ----------
    gauge, rows, rows_reason : str
        Gauge, the rows used (``"hold"``/``"all"``) and why.
    candidates : tuple of DiscreteCandidate
        In the order ARX, OE, ARMAX, BJ (those requested and fitted).
    failures : tuple of (str, str)
        ``(structure, message)`` of requested structures whose fit failed.
    structure : str
        The chosen structure.
    reason : str
        One line: why that structure.
    holdout_fraction : float
        Share of the record, by time, held out at its end.
    """

    gauge: str
    rows: str
    rows_reason: str
    candidates: tuple[DiscreteCandidate, ...]
    failures: tuple[tuple[str, str], ...]
    structure: str
    reason: str
    holdout_fraction: float

    @property
    def chosen(self) -> DiscreteCandidate:
        return next(c for c in self.candidates if c.structure == self.structure)

    @property
    def simulation_model(self) -> ArxFit:
        """The chosen model's deterministic part, for the ARX simulation and renderings."""
        return self.chosen.fit.as_arx()

    def to_dict(self) -> dict[str, Any]:
        fit = self.chosen.fit
        return {
            "test": "prbs",
            "gauge": self.gauge,
            "rows": self.rows,
            "rows_reason": self.rows_reason,
            "structure": self.structure,
            "reason": self.reason,
            "simulation_coefficients": {
                "na": fit.orders.na,
                "nb": fit.orders.nb,
                "nk": fit.orders.nk,
                "a": list(fit.a),
                "b": list(fit.b),
                "operating_point": {
                    "opening_mm": fit.opening_mean_mm,
                    "level_mm": fit.level_mean_mm,
                },
                "sample_period_s": fit.sample_period_s,
            },
            "noise_model": {"c": list(fit.c), "d": list(fit.d), "simulated": False},
            "holdout": f"last {self.holdout_fraction:.0%} of the record",
            "candidates": [c.to_dict() for c in self.candidates],
            "failed": {structure: message for structure, message in self.failures},
        }


@dataclass(frozen=True)
class StructureOrders:
    """Orders shared by the candidates: ``A``/``F`` (``na``), ``B`` (``nb``), delay
    ``nk`` (samples), and the noise orders ``nc`` (ARMAX, BJ) and ``nd`` (BJ)."""

    na: int
    nb: int
    nk: int
    nc: int
    nd: int


def fit_structure(
    structure: str,
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    orders: StructureOrders,
    *,
    sample_period_s: float = 1.2,
    oe: PemFit | None = None,
) -> PemFit:
    """Fit one structure of the family (``oe`` optionally seeds a BJ fit)."""
    o, ts = orders, sample_period_s
    if structure == "arx":
        return from_arx(fit_arx(u, y, segments, o.na, o.nb, o.nk, sample_period_s=ts))
    if structure == "oe":
        return fit_oe(u, y, segments, o.na, o.nb, o.nk, sample_period_s=ts)
    if structure == "armax":
        return fit_armax(u, y, segments, o.na, o.nb, o.nc, o.nk, sample_period_s=ts)
    if structure == "bj":
        return fit_bj(u, y, segments, o.na, o.nb, o.nc, o.nd, o.nk, sample_period_s=ts, oe=oe)
    raise IdentificationError(
        f"structure must be one of {', '.join(STRUCTURES)}, got {structure!r}"
    )


def _ljung_box_fitted(fit: PemFit) -> int:
    """Noise-model parameters subtracted from the Ljung-Box degrees of freedom."""
    o = fit.orders
    return {"arx": o.na, "oe": 0, "armax": o.na + o.nc, "bj": o.nc + o.nd}[o.structure]


def score_candidate(
    sig: PrbsSignals, fit: PemFit, fit_estimation: PemFit, max_lag: int = 25
) -> DiscreteCandidate:
    """One-step, free-run and whiteness metrics of a structure fitted on ``sig``."""
    u, y = sig.u, sig.y
    point = (fit.opening_mean_mm, fit.level_mean_mm)
    dev = deviations(u, y, sig.segments, operating_point=point)
    pred = one_step_prediction(fit.orders, fit.theta, dev) + fit.level_mean_mm
    inputs = np.where(segment_mask(sig.fit_segments, y.size), u, np.nan)
    return DiscreteCandidate(
        fit=fit,
        fit_estimation=fit_estimation,
        one_step=one_step_metrics(y, pred),
        simulation=free_run_on_segments(fit_estimation.as_arx(), u, y, sig.validation)[1],
        simulation_full=free_run_on_segments(fit.as_arx(), u, y, sig.fit_segments)[1],
        whiteness=residual_whiteness(
            y - pred, inputs, max_lag=max_lag, n_fitted=_ljung_box_fitted(fit)
        ),
    )


def compare_structures(
    sig: PrbsSignals,
    orders: StructureOrders,
    structures: Sequence[str] = STRUCTURES,
    max_lag: int = 25,
) -> tuple[tuple[DiscreteCandidate, ...], tuple[tuple[str, str], ...]]:
    """Fit and score every requested structure on prepared signals.

    Returns
    -------
    candidates : tuple of DiscreteCandidate
        In the family order ARX, OE, ARMAX, BJ.
    failures : tuple of (str, str)
        ``(structure, message)`` of the structures whose fit raised
        :class:`~gatetwin.errors.IdentificationError` (e.g. a noise model with a
        cancelling pole and zero, whose criterion is flat).
    """
    unknown = sorted(set(structures) - set(STRUCTURES))
    if unknown or not structures:
        raise IdentificationError(
            f"structures must be among {', '.join(STRUCTURES)}, got {list(structures)}"
        )
    ts = sig.sample_period_s
    fitted: dict[str, tuple[PemFit, PemFit]] = {}
    failures = []
    for structure in (s for s in STRUCTURES if s in structures):
        seeds = fitted.get("oe", (None, None)) if structure == "bj" else (None, None)
        spans = (sig.segments, sig.estimation)
        try:
            full, est = (
                fit_structure(structure, sig.u, sig.y, segs, orders, sample_period_s=ts, oe=seed)
                for segs, seed in zip(spans, seeds, strict=True)
            )
        except IdentificationError as exc:
            failures.append((structure, str(exc)))
            continue
        fitted[structure] = (full, est)
    candidates = tuple(score_candidate(sig, *pair, max_lag=max_lag) for pair in fitted.values())
    return candidates, tuple(failures)


def choose_structure(candidates: Sequence[DiscreteCandidate]) -> tuple[str, str]:
    """The stable candidate with the best hold-out free-run fit, and a one-line reason.

    Raises
    ------
    IdentificationError
        When no candidate is stable with a finite hold-out fit.
    """
    usable = [c for c in candidates if c.stable and np.isfinite(c.simulation.fit_percent)]
    if not usable:
        raise IdentificationError("no candidate structure fitted stable with a finite free run")
    best = usable[0]
    for c in usable[1:]:
        if c.simulation.fit_percent > best.simulation.fit_percent + TIE_PERCENT:
            best = c
    others = ", ".join(
        f"{c.structure} {c.simulation.fit_percent:.1f} %"
        + ("" if c.stable else " (unstable, not eligible)")
        for c in candidates
        if c is not best
    )
    reason = (
        f"{best.structure} simulates best: hold-out free-run fit "
        f"{best.simulation.fit_percent:.1f} %" + (f" (vs {others})" if others else "")
    )
    return best.structure, reason


def select_discrete(
    record: Record,
    gauge: str = "3F",
    orders: tuple[int, int, int] = (2, 2, 1),
    *,
    structures: Sequence[str] = STRUCTURES,
    noise_orders: tuple[int, int] | None = None,
    rows: str = "auto",
    holdout_fraction: float = 0.3,
    spike_floor_mm: float = 0.0,
    max_lag: int = 25,
) -> DiscreteSelection:
    """Fit ARX, OE, ARMAX and BJ to one gauge of a PRBS record and pick the best simulator.

    Parameters
    ----------
    record : Record
        A read PRBS record.
    gauge : str, optional
        Gauge name (default ``"3F"``).
    orders : (na, nb, nk), optional
        Orders of ``A``/``F``, ``B`` and the delay, samples (default the paper's 2, 2, 1).
    structures : sequence of str, optional
        Structures to compare (default all of ``"arx", "oe", "armax", "bj"``).
    noise_orders : (nc, nd), optional
        Orders of ``C`` (ARMAX, BJ) and ``D`` (BJ); default ``(na, na)``.
    rows, holdout_fraction, spike_floor_mm, max_lag : optional
        As in :func:`~gatetwin.identification.prbs.identify_prbs`.

    Returns
    -------
    DiscreteSelection

    Raises
    ------
    IdentificationError
        Unknown gauge or structure, too little data, a failed fit, or no stable candidate.
    """
    where = record.path or "record"
    if gauge not in record.levels_mm:
        raise IdentificationError(
            f"{where}: no gauge {gauge}; it has {', '.join(record.gauges) or 'none'}"
        )
    na, nb, nk = orders
    nc, nd = noise_orders if noise_orders is not None else (na, na)
    try:
        sig = prbs_signals(
            record,
            gauge,
            rows=rows,
            holdout_fraction=holdout_fraction,
            spike_floor_mm=spike_floor_mm,
        )
        shared = StructureOrders(na, nb, nk, nc, nd)
        candidates, failures = compare_structures(sig, shared, structures, max_lag)
        structure, reason = choose_structure(candidates)
    except IdentificationError as exc:
        raise IdentificationError(f"{where}, gauge {gauge}: {exc}") from None
    return DiscreteSelection(
        gauge=gauge,
        rows=sig.rows,
        rows_reason=sig.rows_reason,
        candidates=candidates,
        failures=failures,
        structure=structure,
        reason=reason,
        holdout_fraction=holdout_fraction,
    )
