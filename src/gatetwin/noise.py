"""The level noise of a record, estimated from its steady holds (the noise floor).

``sigma`` is the standard deviation of the level around a quadratic in time, fitted to the
*last half* of every steady stretch (hold samples at one opening with no step of the
discharge and no logging gap, at least :data:`MIN_STRETCH_SAMPLES` long), pooled over the
stretches, stretches more than three times the median SD dropped. Why this one: the last half
of a long hold is past the transient of the move that began it, the quadratic takes out what
is left of it and any slow drift, and unlike the SD of first differences it keeps correlated
noise (the surface waves of a flume are correlated over seconds; first differences see only
their fast part).

**Correlated noise.** A quadratic fitted to ``m`` samples of correlated noise takes out more
than three samples' worth of its variance: with noise covariance ``sigma^2 R`` and ``M`` the
residual projection, ``E[r'r] = sigma^2 trace(M R)``, which falls short of
``sigma^2 (m - 3)`` the more, the shorter the stretch and the slower the noise. On the
PRBS records (stretches of 15–35 samples, surface waves correlated over ~1.5 s at 1.2 s
sampling) the plain ``r'r / (m - 3)`` is 7–11 % low. So the noise is modelled as AR(1) plus
white, ``R = (1 - w) phi^|i-j| + w I``; ``phi`` and ``w`` are fitted to the residuals'
autocovariances at lags 0..:data:`CORRELATION_LAGS` pooled over the stretches (their
expectations are ``trace(M R M S_k)``), and ``sigma^2 = sum r'r / sum trace(M R)``. White
noise gives ``phi = 0`` or ``w = 1`` and the plain pooled SD back. Residuals whose best
fit wants a correlation time beyond :data:`MAX_CORRELATION_S` hold structure rather than
noise (a seiche the model lacks, ringing through the holds): the pool is then left
uncorrected and the method says so. Checked against the virtual flume's noise-free level
(``tests/validation/test_noise_correlated.py``): over the 75 bundled record × gauge cells
the floor's fit is the truth's within -2.8..+0.4 points, mean -0.5
(the plain pool: -1.3..+4.7, and +2.0 on average on the PRBS records C and D).

What it cannot separate is an oscillation still ringing in the second half of a hold (a
slowly decaying seiche): that raises ``sigma``. Without any such stretch it falls back to the
robust SD of first differences of hold samples divided by ``sqrt(2)``, and says so.

Plain functions on arrays, used by the diagnosis (:mod:`gatetwin.diagnosis.noise`) and by the
validation harness (:mod:`gatetwin.validation.harness`); :func:`record_noise_floor` applies them
to a :class:`~gatetwin.records.Record`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize

from gatetwin.records import Record
from gatetwin.records.record import per_record_memo

__all__ = [
    "CORRELATION_LAGS",
    "MAD_TO_SD",
    "MAX_CORRELATION_S",
    "METHOD_DIFFERENCES",
    "METHOD_HOLDS",
    "METHOD_UNCORRECTED",
    "MIN_STRETCH_SAMPLES",
    "STRETCH_GAP_FACTOR",
    "NoiseFloor",
    "flow_steps",
    "hold_openings",
    "noise_floor",
    "plain_pooled_sd",
    "record_noise_floor",
    "steady_stretches",
]

MIN_STRETCH_SAMPLES = 24
MAD_TO_SD = 1.4826
#: A time step longer than this many nominal periods ends a steady stretch (a logging gap).
STRETCH_GAP_FACTOR = 1.5

#: Autocovariance lags the noise's correlation is fitted to.
CORRELATION_LAGS = 2
#: Longest correlation time taken for noise, s. Surface waves and a gauge's own response
#: decorrelate within seconds (the flume's: 1.5 s). Residuals that want a longer one hold
#: structure, not noise: an oscillation still ringing (a seiche the model may lack) or a
#: transient the quadratic missed. Taken for noise it would inflate ``sigma`` and hide the
#: very mismatch the floor is there to show, so the pool is then left uncorrected.
MAX_CORRELATION_S = 5.0

METHOD_HOLDS = ("SD around a quadratic over the last half of steady holds, "
                "corrected for the noise's correlation (AR(1) plus white)")  # fmt: skip
METHOD_UNCORRECTED = ("SD around a quadratic over the last half of steady holds, not "
                      "corrected: the residuals' correlation outlasts MAX_CORRELATION_S "
                      "(structure such as a ringing oscillation, not noise)")  # fmt: skip
METHOD_DIFFERENCES = ("robust SD of first differences of hold samples / sqrt(2) "
                      "(no steady stretch long enough)")  # fmt: skip


@dataclass(frozen=True)
class NoiseFloor:
    """The record's noise floor.

    Attributes
    ----------
    sigma_mm : float
        Noise SD, mm (NaN when the record has no two consecutive hold levels).
    method : str
        How it was obtained (module docstring).
    n_stretches, n_samples : int
        Steady stretches and samples it rests on.
    ar1_coefficient, white_fraction : float
        The noise's correlation model ``R = (1 - w) phi^|i-j| + w I`` per sample
        (NaN for the first-differences fallback).
    """

    sigma_mm: float
    method: str
    n_stretches: int
    n_samples: int
    ar1_coefficient: float = math.nan
    white_fraction: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; the correlation model is None where it was not fitted."""
        return {"sigma_mm": self.sigma_mm, "method": self.method,
                "n_stretches": self.n_stretches, "n_samples": self.n_samples,
                "ar1_coefficient": _finite_or_none(self.ar1_coefficient),
                "white_fraction": _finite_or_none(self.white_fraction)}  # fmt: skip


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def flow_steps(flow_m3h: np.ndarray) -> np.ndarray:
    """Indices ``i`` where the discharge steps between samples ``i - 1`` and ``i``."""
    dq = np.diff(flow_m3h)
    sd = MAD_TO_SD * float(np.median(np.abs(dq - np.median(dq)))) if dq.size else 0.0
    return np.flatnonzero(np.abs(dq) > max(6.0 * sd, 0.5)) + 1


def steady_stretches(
    time_s: np.ndarray,
    hold: np.ndarray,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
    sample_period_s: float,
) -> list[tuple[int, int]]:
    """``(start, stop)`` runs of hold samples at one opening with no discharge step.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    hold : ndarray of bool
        The logger's actuator flag.
    opening_mm : ndarray
        The opening of every hold sample, mm (other samples are not looked at).
    flow_m3h : ndarray
        Discharge, m³/h, finite.
    sample_period_s : float
        Nominal sample period, s.
    """
    n = time_s.size
    cut = np.zeros(n, dtype=bool)
    cut[flow_steps(flow_m3h)] = True
    cut[1:] |= opening_mm[1:] != opening_mm[:-1]
    cut[1:] |= np.diff(time_s) > STRETCH_GAP_FACTOR * sample_period_s
    out, start = [], None
    for i in range(n):
        if start is not None and (cut[i] or not hold[i]):
            out.append((start, i))
            start = None
        if start is None and hold[i]:
            start = i
    if start is not None:
        out.append((start, n))
    return [(a, b) for a, b in out if b - a >= MIN_STRETCH_SAMPLES]


@dataclass(frozen=True)
class _Stretch:
    """The last half of one steady stretch: its residual around the quadratic ``r = M y``.

    ``M = I - Q X'`` with ``X`` the quadratic's design and ``Q = X (X'X)^-1``; sums along
    ``M``'s diagonals are taken from ``Q`` and ``X`` without forming ``M``.
    """

    residual_mm: np.ndarray
    design: np.ndarray  # X, (m, 3)
    hat: np.ndarray  # Q, (m, 3)

    def lag_sums(self, lags: int = CORRELATION_LAGS) -> np.ndarray:
        """``sum_t r_t r_(t+k)`` for ``k = 0..lags`` (0 beyond the stretch)."""
        r = self.residual_mm
        return np.array([r[: r.size - k] @ r[k:] if k < r.size else 0.0
                         for k in range(lags + 1)])  # fmt: skip

    def expected_lag_sums(self, phi: float, lags: int = CORRELATION_LAGS) -> np.ndarray:
        """``trace(M R M S_k)`` per unit AR(1) variance and ``trace(M S_k)`` per unit white.

        ``S_k`` picks the ``k``-th superdiagonal; rows ``k = 0..lags``.
        """
        x, q = self.design, self.hat
        m = x.shape[0]
        rx = _ar1_correlation_times(x, phi)  # R X
        qb = q @ (x.T @ rx)  # Q X'R X
        out = np.zeros((lags + 1, 2))
        for k in range(min(lags, m - 1) + 1):
            lo, hi = slice(0, m - k), slice(k, m)
            ar = ((m - k) * phi**k - np.sum(q[lo] * rx[hi]) - np.sum(rx[lo] * q[hi])
                  + np.sum(qb[lo] * q[hi]))  # fmt: skip
            out[k] = (ar, (m if k == 0 else 0) - np.sum(q[lo] * x[hi]))
        return out


def _ar1_correlation_times(x: np.ndarray, phi: float) -> np.ndarray:
    """``R x`` for the AR(1) correlation ``R_ij = phi^|i - j|`` along ``x``'s rows, without
    forming ``R``: the sum over ``j <= i`` is the first-order recursion ``f_i = x_i + phi
    f_(i-1)``, the one over ``j >= i`` the same run backwards, and ``x_i`` is in both. O(m)
    instead of the m x m matrix (a hold of hours at 10 s is thousands of samples: hundreds
    of MB and a second per product, taken tens of times per stretch by the fit of ``phi``)."""
    from scipy.signal import lfilter

    forward = lfilter([1.0], [1.0, -phi], x, axis=0)
    backward = lfilter([1.0], [1.0, -phi], x[::-1], axis=0)[::-1]
    return forward + backward - x


def _stretch(time_s: np.ndarray, level_mm: np.ndarray, start: int, stop: int) -> _Stretch | None:
    idx = np.arange(start + (stop - start) // 2, stop)
    idx = idx[np.isfinite(level_mm[idx])]
    if idx.size < 8:
        return None
    # time centred and scaled to [-1, 1]: the quadratic's columns are then of one size, and
    # the normal matrix of a hold of hours (t^4 ~ 1e16 s^4 in seconds) keeps its rank
    t = time_s[idx] - time_s[idx].mean()
    x = np.vander(t / max(float(np.max(np.abs(t))), 1e-300), 3)
    q = x @ np.linalg.pinv(x.T @ x)
    y = level_mm[idx]
    return _Stretch(y - q @ (x.T @ y), x, q)


def _expected_lag_sums(
    stretches: list[_Stretch], phi: float, lags: int = CORRELATION_LAGS
) -> np.ndarray:
    """Columns: the lag sums' expectations per unit AR(1) and per unit white variance."""
    return np.sum([s.expected_lag_sums(phi, lags) for s in stretches], axis=0)


def _correlation(stretches: list[_Stretch], phi_max: float) -> tuple[float, float] | None:
    """``(phi, w)`` whose expected lag sums best match the observed ones (module docstring),
    or None when the best ``phi`` is at ``phi_max`` (:data:`MAX_CORRELATION_S`)."""
    observed = np.sum([s.lag_sums() for s in stretches], axis=0)

    def misfit(phi: float) -> tuple[float, np.ndarray]:
        design = _expected_lag_sums(stretches, phi)
        var, residual = optimize.nnls(design, observed)
        return residual, var

    found = optimize.minimize_scalar(lambda phi: misfit(phi)[0], bounds=(0.0, phi_max),
                                     method="bounded", options={"xatol": 1e-3})  # fmt: skip
    phi = float(found.x)
    if phi >= phi_max - 1e-2:
        return None
    var = misfit(phi)[1]
    total = float(np.sum(var))
    return phi, (float(var[1]) / total if total > 0 else 1.0)


def plain_pooled_sd(
    time_s: np.ndarray, level_mm: np.ndarray, stretches: list[tuple[int, int]]
) -> float:
    """The uncorrected pool ``sqrt(sum r'r / sum (m - 3))`` over the stretches' last halves.

    Right for white noise only; :func:`noise_floor` corrects it for correlated noise. Kept
    to show what the correction changes (``benchmarks/bench_noise_floor.py``).
    """
    found = [s for a, b in stretches if (s := _stretch(time_s, level_mm, a, b)) is not None]
    rss = sum(float(s.lag_sums()[0]) for s in found)
    dof = sum(s.residual_mm.size - 3 for s in found)
    return math.sqrt(rss / dof) if dof > 0 else math.nan


def noise_floor(
    time_s: np.ndarray, level_mm: np.ndarray, hold: np.ndarray, stretches: list[tuple[int, int]]
) -> NoiseFloor:
    """The level's noise floor from its steady stretches (see the module docstring).

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    level_mm : ndarray
        Level, mm (NaN where missing).
    hold : ndarray of bool
        The logger's actuator flag (for the fallback).
    stretches : list of (int, int)
        From :func:`steady_stretches`.
    """
    found = [s for a, b in stretches if (s := _stretch(time_s, level_mm, a, b)) is not None]
    if found:
        sd = np.array([math.sqrt(s.lag_sums()[0] / (s.residual_mm.size - 3)) for s in found])
        kept = [s for s, v in zip(found, sd, strict=True) if v <= 3.0 * np.median(sd)]
        rss = sum(float(s.lag_sums()[0]) for s in kept)
        used = sum(s.residual_mm.size for s in kept)
        period_s = float(np.median(np.diff(time_s)))
        fitted = _correlation(kept, math.exp(-period_s / MAX_CORRELATION_S))
        if fitted is None:
            plain = math.sqrt(rss / (used - 3 * len(kept)))
            return NoiseFloor(plain, METHOD_UNCORRECTED, len(kept), used)
        phi, white = fitted
        dof = sum(_expected_lag_sums([s], phi)[0] @ (1.0 - white, white) for s in kept)
        return NoiseFloor(math.sqrt(rss / dof), METHOD_HOLDS, len(kept), used, phi, white)
    y = np.where(hold, level_mm, np.nan)
    d = np.diff(y)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return NoiseFloor(math.nan, METHOD_DIFFERENCES, 0, 0)
    sigma = MAD_TO_SD * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0)
    return NoiseFloor(sigma, METHOD_DIFFERENCES, 0, int(d.size))


def hold_openings(record: Record) -> np.ndarray:
    """The opening of every hold sample (its segment's), NaN on the others, mm."""
    opening = np.full(record.n_samples, np.nan)
    for seg in record.holds:
        opening[seg.slice] = seg.opening_mm
    return opening


@per_record_memo
def record_noise_floor(record: Record, gauge: str) -> NoiseFloor:
    """The noise floor of ``record``'s level at ``gauge`` (module docstring).

    Steady stretches run over hold segments (one opening each) and are cut at discharge steps
    and logging gaps, exactly as the diagnosis cuts them; missing discharges are interpolated
    in time. Computed once per record content in a process: validating a folder's FMUs asks
    for the same records' floors once per FMU (the run's validation: 23 of its ~120 CPU
    seconds went to recomputing them).
    """
    t = np.asarray(record.time_s, dtype=float)
    q = np.asarray(record.flow_m3h, dtype=float)
    ok = np.isfinite(q)
    if np.any(ok) and not np.all(ok):
        q = np.interp(t, t[ok], q[ok])
    hold = np.asarray(record.hold, dtype=bool)
    stretches = steady_stretches(t, hold, hold_openings(record), q, record.sample_period_s)
    level = np.asarray(record.levels_mm[gauge], dtype=float)
    return noise_floor(t, level, hold, stretches)
