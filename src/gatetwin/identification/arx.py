"""ARX models fitted on hold segments, in the reference study's sign convention.

Model (deviations from the operating point, ``Ts`` = one sample)::

    y'(k) = a1 y'(k-1) + ... + a_na y'(k-na)
            + b1 u'(k-nk) + b2 u'(k-nk-1) + ... + b_nb u'(k-nk-nb+1) + eps(k)

with ``u' = e - mean(e)`` (gate opening, mm) and ``y' = H - mean(H)`` (level, mm), the
means taken over the samples used (hold samples with finite opening and level); they
are the operating point and are stored on the fit.

Least squares uses hold samples only. A row at sample ``k`` is formed only when ``k`` and
all its lags lie in the same segment, so the first ``max(na, nk+nb-1)`` samples of each
segment are dropped; a NaN splits its segment (see
:func:`gatetwin.identification.preprocess.split_segments`). The normal equations are formed
from lagged dot products (:mod:`gatetwin.identification.lagproducts`) and solved by Cholesky.

**Identifiability on hold rows.** Inside a hold segment the opening is one value, so on
every hold row ``u(k-nk) = u(k-nk-1) = ...``: the input columns are identical and only
``b1 + ... + b_nb`` is identifiable (the autoregressive part is, from the transients that
follow each gate move). :func:`fit_arx` refuses ``nb >= 2`` in that case with a message
saying so. The remedy is to fit on *all* samples -- segments from
:func:`~gatetwin.identification.preprocess.continuous_segments` and the opening during motion
from :func:`~gatetwin.identification.preprocess.reconstructed_opening`; the ramps of the gate
moves then separate the ``b`` coefficients (:func:`gatetwin.identification.prbs.identify_prbs`
does this with ``rows="auto"``).

Spike correction and the reconstruction of the opening during actuator motion are the
caller's choice (:mod:`gatetwin.identification.preprocess`); :func:`fit_arx` fits what it gets.
Order search is in :mod:`gatetwin.identification.orders`, metrics in
:mod:`gatetwin.identification.metrics`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg, signal

from gatetwin.errors import IdentificationError
from gatetwin.identification.lagproducts import LagProducts, lag_products
from gatetwin.identification.preprocess import (
    Segments,
    as_segments,
    clean_segments,
    constant_within_segments,
    segment_mask,
)

__all__ = [
    "MAX_CONDITION",
    "ArxFit",
    "Deviations",
    "check_orders",
    "deviations",
    "fit_arx",
    "fit_from_lag_products",
    "predict_one_step",
    "regression_rows",
    "simulate_free",
]


@dataclass(frozen=True)
class ArxFit:
    """A fitted ARX(na, nb, nk) model.

    Attributes
    ----------
    na, nb, nk : int
        Output order, input order, input delay (samples).
    a : tuple of float
        Autoregressive coefficients ``a1..a_na`` (dimensionless).
    b : tuple of float
        Input coefficients ``b1..b_nb``, mm of level per mm of opening.
    a_se, b_se : tuple of float
        Standard errors of ``a`` and ``b`` (``sqrt(diag(covariance))``).
    covariance : tuple of tuple of float
        Covariance of ``theta = (a1..a_na, b1..b_nb)``: ``sigma^2 (Phi^T Phi)^-1``.
    noise_variance_mm2 : float
        ``sigma^2 = SSR / (n_rows - na - nb)``, mm².
    n_rows : int
        Regression rows used.
    opening_mean_mm : float
        Operating-point opening (mean opening over the samples used), mm.
    level_mean_mm : float
        Operating-point level (mean level over the samples used), mm.
    sample_period_s : float
        Sample period the model steps at, s.
    """

    na: int
    nb: int
    nk: int
    a: tuple[float, ...]
    b: tuple[float, ...]
    a_se: tuple[float, ...]
    b_se: tuple[float, ...]
    covariance: tuple[tuple[float, ...], ...]
    noise_variance_mm2: float
    n_rows: int
    opening_mean_mm: float
    level_mean_mm: float
    sample_period_s: float = 1.2

    @property
    def n_params(self) -> int:
        return self.na + self.nb

    @property
    def max_lag(self) -> int:
        """Samples dropped at the start of each segment: ``max(na, nk + nb - 1)``."""
        return max(self.na, self.nk + self.nb - 1)

    @property
    def theta(self) -> np.ndarray:
        return np.array(self.a + self.b)

    def to_dict(self) -> dict[str, Any]:
        return {
            "na": self.na,
            "nb": self.nb,
            "nk": self.nk,
            "a": list(self.a),
            "b": list(self.b),
            "a_se": list(self.a_se),
            "b_se": list(self.b_se),
            "covariance": [list(r) for r in self.covariance],
            "noise_variance_mm2": self.noise_variance_mm2,
            "n_rows": self.n_rows,
            "opening_mean_mm": self.opening_mean_mm,
            "level_mean_mm": self.level_mean_mm,
            "sample_period_s": self.sample_period_s,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ArxFit:
        try:
            return cls(
                na=int(data["na"]),
                nb=int(data["nb"]),
                nk=int(data["nk"]),
                a=tuple(float(v) for v in data["a"]),
                b=tuple(float(v) for v in data["b"]),
                a_se=tuple(float(v) for v in data["a_se"]),
                b_se=tuple(float(v) for v in data["b_se"]),
                covariance=tuple(tuple(float(v) for v in r) for r in data["covariance"]),
                noise_variance_mm2=float(data["noise_variance_mm2"]),
                n_rows=int(data["n_rows"]),
                opening_mean_mm=float(data["opening_mean_mm"]),
                level_mean_mm=float(data["level_mean_mm"]),
                sample_period_s=float(data.get("sample_period_s", 1.2)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise IdentificationError(f"ARX fit: malformed dictionary ({exc})") from None


#: Largest condition number of the unit-diagonal normal matrix accepted as identifiable.
MAX_CONDITION = 1e10


def check_orders(na: int, nb: int, nk: int) -> None:
    """Refuse orders the fit cannot use (``na >= 1``, ``nb >= 1``, ``nk >= 0``)."""
    if not (int(na) == na >= 1 and int(nb) == nb >= 1 and int(nk) == nk >= 0):
        raise IdentificationError(
            f"ARX orders need na >= 1, nb >= 1, nk >= 0 (got {na}, {nb}, {nk})"
        )


@dataclass(frozen=True)
class Deviations:
    """Zero-filled deviation signals of one data set (see :func:`deviations`).

    Attributes
    ----------
    u0, y0 : ndarray
        Opening and level deviations from the operating point, mm; 0 outside ``segments``.
    segments : ndarray of shape (n, 2)
        Clean segments: the given segments cut at every NaN of opening or level.
    mask : ndarray of bool
        The samples inside ``segments``.
    opening_mean_mm, level_mean_mm : float
        The operating point the deviations are taken from, mm.
    """

    u0: np.ndarray
    y0: np.ndarray
    segments: np.ndarray
    mask: np.ndarray
    opening_mean_mm: float
    level_mean_mm: float


def deviations(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    operating_point: tuple[float, float] | None = None,
) -> Deviations:
    """Cut segments at NaNs and form zero-filled deviations.

    Parameters
    ----------
    u, y : ndarray
        Gate opening and level, mm, equal length.
    segments : sequence of (int, int) or ndarray
        Hold segments, ``stop`` exclusive.
    operating_point : (float, float), optional
        ``(opening_mm, level_mm)`` to subtract; default: their means over the clean
        segments.
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.shape != y.shape or u.ndim != 1:
        raise IdentificationError("opening and level must be 1-D arrays of equal length")
    finite = np.isfinite(u)
    finite &= np.isfinite(y)
    clean, mask = clean_segments(as_segments(segments, y.size), finite)
    u0 = np.where(mask, u, 0.0)
    y0 = np.where(mask, y, 0.0)
    count = int(np.count_nonzero(mask))
    if count == 0:
        raise IdentificationError("no hold sample with finite opening and level")
    if operating_point is None:
        operating_point = (float(u0.sum()) / count, float(y0.sum()) / count)
    u_mean, y_mean = operating_point
    for values, mean in ((u0, u_mean), (y0, y_mean)):
        values -= mean  # finite everywhere after np.where, so the product re-zeroes
        values *= mask
    return Deviations(u0, y0, clean, mask, float(u_mean), float(y_mean))


def fit_from_lag_products(
    products: LagProducts,
    na: int,
    nb: int,
    nk: int,
    operating_point: tuple[float, float],
    sample_period_s: float = 1.2,
) -> ArxFit:
    """Solve the normal equations of ARX(na, nb, nk) from a :class:`LagProducts`.

    Parameters
    ----------
    products : LagProducts
        Must hold the lags ``y 0..na`` and ``u nk..nk+nb-1``.
    na, nb, nk : int
        Orders.
    operating_point : (float, float)
        ``(opening_mean_mm, level_mean_mm)`` the deviations were taken from.
    sample_period_s : float, optional
        Sample period, s.

    Returns
    -------
    ArxFit

    Raises
    ------
    IdentificationError
        Too few rows, or normal equations not positive definite (input not exciting).
    """
    p = na + nb
    n = products.n_rows
    if n <= p:
        raise IdentificationError(
            f"ARX({na},{nb},{nk}) needs more than {p} regression rows, the segments give {n}"
        )
    gram, rhs, yy = products.block(na, nb, nk)
    scale = np.sqrt(np.diag(gram))
    singular = not np.all(scale > 0)
    if not singular:
        singular = np.linalg.cond(gram / np.outer(scale, scale)) > MAX_CONDITION
    try:
        factor = linalg.cho_factor(gram)
    except linalg.LinAlgError:
        singular = True
    if singular:
        raise IdentificationError(
            f"ARX({na},{nb},{nk}): normal equations are singular "
            "(the regressors are collinear: input not exciting enough for these orders)"
        )
    theta = linalg.cho_solve(factor, rhs)
    ssr = max(yy - float(theta @ rhs), 0.0)
    sigma2 = ssr / (n - p)
    cov = sigma2 * linalg.cho_solve(factor, np.eye(p))
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return ArxFit(
        na=na,
        nb=nb,
        nk=nk,
        a=tuple(float(v) for v in theta[:na]),
        b=tuple(float(v) for v in theta[na:]),
        a_se=tuple(float(v) for v in se[:na]),
        b_se=tuple(float(v) for v in se[na:]),
        covariance=tuple(tuple(float(v) for v in r) for r in cov),
        noise_variance_mm2=float(sigma2),
        n_rows=n,
        opening_mean_mm=float(operating_point[0]),
        level_mean_mm=float(operating_point[1]),
        sample_period_s=float(sample_period_s),
    )


def fit_arx(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    na: int,
    nb: int,
    nk: int,
    *,
    sample_period_s: float = 1.2,
) -> ArxFit:
    """Least-squares ARX(na, nb, nk) on hold segments (paper's sign convention).

    Parameters
    ----------
    u : ndarray
        Gate opening, mm (absolute; NaN allowed outside or inside segments).
    y : ndarray
        Upstream level, mm (absolute; NaN allowed).
    segments : sequence of (int, int) or ndarray
        Hold segments, ``stop`` exclusive. They are cut at every NaN of ``u`` or ``y``;
        the first ``max(na, nk+nb-1)`` samples of each resulting segment give no row.
    na, nb, nk : int
        Orders, ``na >= 1``, ``nb >= 1``, ``nk >= 0``.
    sample_period_s : float, optional
        Sample period stored on the fit, s (default 1.2).

    Returns
    -------
    ArxFit
        Coefficients, their covariance, the noise variance and the operating point (means
        of ``u`` and ``y`` over the clean segments).

    Raises
    ------
    IdentificationError
        Bad orders; no more rows than parameters; ``nb >= 2`` while ``u`` is constant
        within every segment (only the sum of the ``b`` is identifiable: see the module
        docstring); or collinear regressors (condition number of the unit-diagonal
        normal matrix above :data:`MAX_CONDITION`).

    Notes
    -----
    The normal equations are built from lagged dot products of the zero-filled
    deviations (no regressor matrix) and solved through a Cholesky factorisation; the
    result equals ``numpy.linalg.lstsq`` on the explicit regressor up to round-off.
    """
    check_orders(na, nb, nk)
    dev = deviations(u, y, segments)
    if nb >= 2 and constant_within_segments(dev.u0, dev.segments, dev.mask):
        raise IdentificationError(
            f"ARX({na},{nb},{nk}): the opening is constant within every segment, so only "
            f"b1+...+b{nb} is identifiable from these rows; fit nb=1, or fit on all samples "
            "with the opening reconstructed during actuator motion"
        )
    drop = max(na, nk + nb - 1)
    products = lag_products(
        dev.u0, dev.y0, dev.segments, range(0, na + 1), range(nk, nk + nb), drop
    )
    point = (dev.opening_mean_mm, dev.level_mean_mm)
    return fit_from_lag_products(products, na, nb, nk, point, sample_period_s)


def regression_rows(segments: np.ndarray, drop: int, n_samples: int) -> np.ndarray:
    """Boolean mask of the samples that are regression rows (``drop`` skipped per segment)."""
    rows = np.column_stack((segments[:, 0] + drop, segments[:, 1]))
    return segment_mask(rows[rows[:, 1] > rows[:, 0]], n_samples)


def predict_one_step(fit: ArxFit, u: np.ndarray, y: np.ndarray, segments: Segments) -> np.ndarray:
    """One-step-ahead prediction of the level on hold segments.

    Parameters
    ----------
    fit : ArxFit
        The model.
    u, y : ndarray
        Gate opening and measured level, mm.
    segments : sequence of (int, int) or ndarray
        Hold segments, ``stop`` exclusive (cut at NaNs as in :func:`fit_arx`).

    Returns
    -------
    ndarray
        Predicted level, mm (absolute: operating point added back); NaN on samples that are
        not regression rows (outside segments, first ``max_lag`` samples of a segment, or
        missing data).
    """
    point = (fit.opening_mean_mm, fit.level_mean_mm)
    dev = deviations(u, y, segments, operating_point=point)
    n = dev.y0.size
    pred = np.zeros(n)
    for i, a_i in enumerate(fit.a, start=1):
        pred[i:] += a_i * dev.y0[: n - i]
    for j, b_j in enumerate(fit.b):
        lag = fit.nk + j
        pred[lag:] += b_j * dev.u0[: n - lag]
    rows = regression_rows(dev.segments, fit.max_lag, n)
    return np.where(rows, pred + fit.level_mean_mm, np.nan)


def _history(
    given: np.ndarray | None, count: int, default: float, offset: float, name: str
) -> np.ndarray:
    """Past values (most recent first, deviations) for :func:`scipy.signal.lfiltic`."""
    if count == 0:
        return np.zeros(0)
    if given is None:
        return np.full(count, default)
    past = np.asarray(given, dtype=float)
    if past.size < count or not np.all(np.isfinite(past[-count:])):
        raise IdentificationError(f"{name} needs {count} finite past values")
    return past[-count:][::-1] - offset


def simulate_free(
    fit: ArxFit,
    u: np.ndarray,
    *,
    y_init: np.ndarray | None = None,
    u_init: np.ndarray | None = None,
) -> np.ndarray:
    """Free-run (simulation) response of the ARX model: no measured level is fed back.

    Parameters
    ----------
    fit : ArxFit
        The model.
    u : ndarray
        Gate opening at every sample, mm, finite (use
        :func:`~gatetwin.identification.preprocess.reconstructed_opening` to fill the
        actuator-motion samples).
    y_init : ndarray, optional
        Levels before the first sample, mm, oldest first (at least ``na``). Default: the
        equilibrium for ``u[0]``.
    u_init : ndarray, optional
        Openings before the first sample, mm, oldest first (at least ``nk + nb - 1``).
        Default: ``u[0]`` held.

    Returns
    -------
    ndarray
        Simulated level, mm (absolute), one value per sample of ``u``. Samples are stepped
        one sample period apart; time gaps in a record are not filled.
    """
    u = np.asarray(u, dtype=float)
    if u.size == 0 or not np.all(np.isfinite(u)):
        raise IdentificationError(
            "free-run simulation needs a finite opening at every sample "
            "(fill actuator motion with reconstructed_opening)"
        )
    ud = u - fit.opening_mean_mm
    b_full = np.concatenate((np.zeros(fit.nk), fit.b))
    a_full = np.concatenate(([1.0], -np.asarray(fit.a)))
    denom = 1.0 - sum(fit.a)
    y_eq = sum(fit.b) / denom * ud[0] if denom != 0.0 else 0.0
    y_past = _history(y_init, fit.na, y_eq, fit.level_mean_mm, "y_init")
    x_past = _history(u_init, fit.nk + fit.nb - 1, ud[0], fit.opening_mean_mm, "u_init")
    zi = signal.lfiltic(b_full, a_full, y_past, x_past)
    out, _ = signal.lfilter(b_full, a_full, ud, zi=zi)
    return out + fit.level_mean_mm
