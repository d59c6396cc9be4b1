"""Goodness-of-fit, residual whiteness and pole metrics of identified ARX models.

* One-step-ahead metrics (the reference study's): R², MAE, RMSE.
* Free-run (simulation) metrics: fit % = ``100 (1 - ||y - y_sim|| / ||y - mean(y)||)``
  (NRMSE fit) and RMSE -- the harder test a co-simulation FMU faces.
* Residual whiteness: autocorrelation to lag 25 with its 99 % band, Ljung-Box Q and
  p-value, input-residual cross-correlation.
* Poles: stability, DC gain, dominant time constant.

These are findings; what counts as failing is the caller's decision.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import ArxFit, simulate_free
from gatetwin.identification.lagproducts import inner
from gatetwin.identification.preprocess import Segments, as_segments, segment_mask
from gatetwin.identification.serial import finite_or_none

__all__ = [
    "Z99",
    "DominantPole",
    "OneStepMetrics",
    "SimulationMetrics",
    "Whiteness",
    "arx_poles",
    "dc_gain",
    "dominant_pole",
    "free_run_on_segments",
    "is_stable",
    "one_step_metrics",
    "residual_whiteness",
    "simulation_metrics",
]

#: Two-sided 99 % quantile of the standard normal distribution.
Z99 = 2.576


def _pairs(y: np.ndarray, y_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    ok = np.isfinite(y) & np.isfinite(y_hat)
    if np.count_nonzero(ok) < 2:
        raise IdentificationError("fewer than 2 samples with both measured and model level")
    return y[ok], y_hat[ok]


@dataclass(frozen=True)
class OneStepMetrics:
    """One-step-ahead prediction metrics (paper's definitions).

    Attributes
    ----------
    r2 : float
        ``1 - sum (y - y_hat)^2 / sum (y - mean y)^2``.
    mae_mm, rmse_mm : float
        Mean absolute and root-mean-square prediction error, mm.
    n : int
        Samples compared.
    """

    r2: float
    mae_mm: float
    rmse_mm: float
    n: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "r2": finite_or_none(self.r2),
            "mae_mm": finite_or_none(self.mae_mm),
            "rmse_mm": finite_or_none(self.rmse_mm),
            "n": self.n,
        }


def one_step_metrics(y: np.ndarray, y_hat: np.ndarray) -> OneStepMetrics:
    """R², MAE and RMSE over the samples where both ``y`` and ``y_hat`` are finite (mm)."""
    y, y_hat = _pairs(y, y_hat)
    err = y - y_hat
    sst = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - inner(err, err) / sst if sst > 0 else float("nan")
    return OneStepMetrics(
        r2=r2,
        mae_mm=float(np.mean(np.abs(err))),
        rmse_mm=float(np.sqrt(np.mean(err**2))),
        n=int(y.size),
    )


@dataclass(frozen=True)
class SimulationMetrics:
    """Free-run (simulation) metrics.

    Attributes
    ----------
    fit_percent : float
        ``100 (1 - ||y - y_sim|| / ||y - mean(y)||)``; 100 is perfect, 0 is no better than
        the mean, negative is worse.
    rmse_mm : float
        Root-mean-square simulation error, mm.
    n : int
        Samples compared.
    """

    fit_percent: float
    rmse_mm: float
    n: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "fit_percent": finite_or_none(self.fit_percent),
            "rmse_mm": finite_or_none(self.rmse_mm),
            "n": self.n,
        }


def simulation_metrics(y: np.ndarray, y_sim: np.ndarray) -> SimulationMetrics:
    """Fit % (NRMSE) and RMSE over the samples where the measured ``y`` is finite (mm).

    A simulation that is not finite on one of those samples (an unstable model that
    blew up) scores ``fit_percent = -inf`` and ``rmse_mm = inf``.
    """
    y = np.asarray(y, dtype=float)
    y_sim = np.asarray(y_sim, dtype=float)
    ok = np.isfinite(y)
    if np.count_nonzero(ok) < 2:
        raise IdentificationError("fewer than 2 measured samples to score a simulation")
    y, y_sim = y[ok], y_sim[ok]
    if not np.all(np.isfinite(y_sim)):
        return SimulationMetrics(float("-inf"), float("inf"), int(y.size))
    centred, diff = y - y.mean(), y - y_sim
    spread = float(np.sqrt(inner(centred, centred)))
    err = float(np.sqrt(inner(diff, diff)))
    fit = 100.0 * (1.0 - err / spread) if spread > 0 else float("nan")
    return SimulationMetrics(float(fit), float(err / np.sqrt(y.size)), int(y.size))


def free_run_on_segments(
    fit: ArxFit, u: np.ndarray, y: np.ndarray, segments: Segments
) -> tuple[np.ndarray, SimulationMetrics]:
    """Simulate the model freely over the span of ``segments`` and score it there.

    The run starts at the first segment's start and ends at the last one's stop; it is
    initialised from the measured levels and openings just before the start when they
    are finite (else at equilibrium). Only samples inside the segments are scored.

    Parameters
    ----------
    fit : ArxFit
        The model.
    u : ndarray
        Opening at every sample, mm, finite over the span (reconstructed during motion).
    y : ndarray
        Measured level, mm.
    segments : sequence of (int, int) or ndarray
        The samples to score (e.g. hold segments of the hold-out part).

    Returns
    -------
    y_sim : ndarray
        Simulated level, mm, over the whole record length (NaN outside the span).
    metrics : SimulationMetrics
    """
    y = np.asarray(y, dtype=float)
    u = np.asarray(u, dtype=float)
    seg = as_segments(segments, y.size)
    if seg.size == 0:
        raise IdentificationError("free run needs at least one segment")
    start, stop = int(seg[0, 0]), int(seg[-1, 1])
    n_y, n_u = fit.na, fit.nk + fit.nb - 1
    y_init = y[start - n_y : start] if start >= n_y else None
    u_init = u[start - n_u : start] if start >= n_u else None
    if y_init is not None and not np.all(np.isfinite(y_init)):
        y_init = None
    if u_init is not None and not np.all(np.isfinite(u_init)):
        u_init = None
    out = np.full(y.size, np.nan)
    out[start:stop] = simulate_free(fit, u[start:stop], y_init=y_init, u_init=u_init)
    scored = np.where(segment_mask(seg, y.size), y, np.nan)
    return out, simulation_metrics(scored, out)


@dataclass(frozen=True)
class Whiteness:
    """Residual whiteness tests.

    Attributes
    ----------
    n : int
        Residuals used (finite ones).
    max_lag : int
        Largest lag tested.
    autocorrelation : tuple of float
        Residual autocorrelation at lags 1..max_lag.
    band : float
        99 % band ``2.576 / sqrt(n)`` for both correlation tests.
    n_outside : int
        Autocorrelation lags outside the band.
    ljung_box_q : float
        ``n (n + 2) sum r(k)^2 / (n - k)``, k = 1..max_lag.
    ljung_box_dof : int
        Degrees of freedom: ``max_lag - n_fitted`` (``n_fitted`` = autoregressive
        coefficients estimated, ``na`` for an ARX model).
    ljung_box_p : float
        Upper-tail chi-square probability of ``ljung_box_q``; small means not white.
    cross_correlation : tuple of float
        Correlation of residual ``eps(k)`` with input ``u(k - lag)``, lags 0..max_lag
        (empty when no input was given).
    n_cross_outside : int
        Cross-correlation lags outside the band.
    """

    n: int
    max_lag: int
    autocorrelation: tuple[float, ...]
    band: float
    n_outside: int
    ljung_box_q: float
    ljung_box_dof: int
    ljung_box_p: float
    cross_correlation: tuple[float, ...]
    n_cross_outside: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": self.n,
            "max_lag": self.max_lag,
            "band_99": self.band,
            "autocorrelation": list(self.autocorrelation),
            "n_outside": self.n_outside,
            "ljung_box_q": self.ljung_box_q,
            "ljung_box_dof": self.ljung_box_dof,
            "ljung_box_p": self.ljung_box_p,
            "cross_correlation": list(self.cross_correlation),
            "n_cross_outside": self.n_cross_outside,
        }


def _lagged_sums(e0: np.ndarray, x0: np.ndarray, lags: range) -> np.ndarray:
    n = e0.size
    return np.array([inner(e0[k:], x0[: n - k]) for k in lags])


def _cross_correlation(
    e0: np.ndarray, ok: np.ndarray, c0: float, x: np.ndarray, max_lag: int
) -> tuple[float, ...]:
    """Normalised ``sum e0(k) x0(k - lag)``, lags 0..max_lag (empty if undefined)."""
    both = np.isfinite(x) & ok
    if not np.any(both):
        return ()
    x0 = np.where(np.isfinite(x), x - np.mean(x[both]), 0.0)
    denom = np.sqrt(c0 * float(np.sum(x0[both] ** 2)))
    if not denom > 0:
        return ()
    return tuple(float(v) for v in _lagged_sums(e0, x0, range(0, max_lag + 1)) / denom)


def residual_whiteness(
    residuals: np.ndarray,
    inputs: np.ndarray | None = None,
    *,
    max_lag: int = 25,
    n_fitted: int = 0,
) -> Whiteness:
    """Autocorrelation, Ljung-Box and input cross-correlation of residuals.

    Parameters
    ----------
    residuals : ndarray
        Residuals in time order, mm; NaN where there is no residual (the pair is then
        left out of every lagged sum, so gaps between segments are not bridged by
        invented values).
    inputs : ndarray, optional
        Input (opening, mm) on the same samples; NaN where unknown.
    max_lag : int, optional
        Largest lag (default 25).
    n_fitted : int, optional
        Autoregressive parameters fitted, subtracted from the Ljung-Box degrees of
        freedom (default 0).

    Returns
    -------
    Whiteness
    """
    e = np.asarray(residuals, dtype=float)
    ok = np.isfinite(e)
    n = int(np.count_nonzero(ok))
    if n <= max_lag + 1:
        raise IdentificationError(f"whiteness test needs more than {max_lag + 1} residuals")
    e0 = np.where(ok, e - np.mean(e[ok]), 0.0)
    c0 = inner(e0, e0)
    r = _lagged_sums(e0, e0, range(1, max_lag + 1)) / c0
    band = Z99 / np.sqrt(n)
    lags = np.arange(1, max_lag + 1)
    q = float(n * (n + 2) * np.sum(r**2 / (n - lags)))
    dof = max(max_lag - int(n_fitted), 1)
    cross: tuple[float, ...] = ()
    if inputs is not None:
        cross = _cross_correlation(e0, ok, c0, np.asarray(inputs, dtype=float), max_lag)
    return Whiteness(
        n=n,
        max_lag=max_lag,
        autocorrelation=tuple(float(v) for v in r),
        band=float(band),
        n_outside=int(np.sum(np.abs(r) > band)),
        ljung_box_q=q,
        ljung_box_dof=dof,
        ljung_box_p=float(stats.chi2.sf(q, dof)),
        cross_correlation=cross,
        n_cross_outside=int(np.sum(np.abs(np.asarray(cross)) > band)),
    )


def arx_poles(a: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """Roots of ``z^na - a1 z^(na-1) - ... - a_na`` (paper's sign convention)."""
    return np.roots(np.concatenate(([1.0], -np.asarray(a, dtype=float))))


def is_stable(a: tuple[float, ...] | np.ndarray) -> bool:
    """True when every pole lies strictly inside the unit circle."""
    return bool(np.all(np.abs(arx_poles(a)) < 1.0))


def dc_gain(a: tuple[float, ...] | np.ndarray, b: tuple[float, ...] | np.ndarray) -> float:
    """Steady-state gain ``sum(b) / (1 - sum(a))``, mm/mm (inf for a pole at z = 1)."""
    denom = 1.0 - float(np.sum(a))
    return float(np.sum(b)) / denom if denom != 0.0 else float("inf")


@dataclass(frozen=True)
class DominantPole:
    """The largest-modulus pole of an ARX model and its time constant.

    Attributes
    ----------
    real, imag : float
        The pole (of the pair, the one with ``imag >= 0``).
    modulus : float
        ``|p|``.
    kind : str
        ``"real"`` (real, positive: a first-order decay), ``"complex"`` (oscillatory
        pair; the time constant is that of the envelope) or ``"negative"`` (real,
        negative: sign-alternating, no physical time constant).
    time_constant_s : float or None
        ``-Ts / ln|p|``, s, when ``0 < |p| < 1`` and ``kind`` is not ``"negative"``.
    """

    real: float
    imag: float
    modulus: float
    kind: str
    time_constant_s: float | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "real": self.real,
            "imag": self.imag,
            "modulus": self.modulus,
            "kind": self.kind,
            "time_constant_s": self.time_constant_s,
        }


def dominant_pole(a: tuple[float, ...] | np.ndarray, sample_period_s: float) -> DominantPole:
    """Dominant (largest-modulus) pole and time constant ``-Ts / ln|p|``."""
    poles = arx_poles(a)
    p = poles[np.argmax(np.abs(poles) + 1e-12 * (poles.imag >= 0))]
    p = complex(p.real, abs(p.imag))
    mod = abs(p)
    scale = max(mod, 1e-300)
    if abs(p.imag) > 1e-9 * scale:
        kind = "complex"
    elif p.real < 0:
        kind = "negative"
    else:
        kind = "real"
    tau = None
    if 0.0 < mod < 1.0 and kind != "negative":
        tau = -float(sample_period_s) / float(np.log(mod))
    return DominantPole(float(p.real), float(p.imag), float(mod), kind, tau)
