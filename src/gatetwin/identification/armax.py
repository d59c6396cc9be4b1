"""ARMAX models: equation error with a moving-average noise, fitted by prediction error.

Model (deviations; ``+`` convention of the reference study on every right-hand side)::

    y'(k) = a1 y'(k-1) + ... + a_na y'(k-na) + b1 u'(k-nk) + ... + b_nb u'(k-nk-nb+1)
            + eps(k) + c1 eps(k-1) + ... + c_nc eps(k-nc)

i.e. ``A y' = B u' + C eps`` with ``C = 1 + c1 q^-1 + ...``. Equation-error ARX is the
case ``C = 1``; when the level noise is coloured, ARX is biased and ARMAX, which models
the colour, is not (as long as the noise is a moving average through ``C/A``).

The coefficients minimise the squared one-step prediction errors
``eps = (A y' - B u') / C`` (the predictor of the model) over ARX's rows; the filter
``1/C`` starts at rest in each segment, so segments are never bridged. The criterion can
have more than one local minimum (record D has two), so the minimisation
(:func:`gatetwin.identification.pemfit.fit_pem`) runs from two start values and keeps the
lower criterion:

1. the equation-error ARX estimate with ``C = 1``;
2. Hannan-Rissanen: the innovations estimated by a long ARX(:data:`HR_ORDER`,
   :data:`HR_ORDER`, nk) fit, then ``y'`` regressed by least squares on its own lags,
   the input lags and the lagged estimated innovations (rows whose lags stay inside one
   segment).

A ``C`` with a root outside the unit circle is mirrored inside (the same noise spectrum)
and refined once.

The deterministic part ``B/A`` is the simulation model: ``a`` and ``b`` have the ARX
layout (:meth:`~gatetwin.identification.pemfit.PemFit.as_arx`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import (
    Deviations,
    deviations,
    fit_arx,
    predict_one_step,
    regression_rows,
)
from gatetwin.identification.pem import PemOrders
from gatetwin.identification.pemfit import PemFit, fit_pem
from gatetwin.identification.preprocess import Segments

__all__ = ["HR_ORDER", "fit_armax", "hannan_rissanen"]

#: Orders ``na = nb`` of the long ARX model of the Hannan-Rissanen start.
HR_ORDER = 10


def _lagged(x: np.ndarray, lag: int) -> np.ndarray:
    out = np.full(x.size, np.nan)
    out[lag:] = x[: x.size - lag]
    return out


def hannan_rissanen(
    u: np.ndarray, y: np.ndarray, dev: Deviations, orders: PemOrders
) -> np.ndarray | None:
    """Hannan-Rissanen start ``(a, b, c)``, or None when the long ARX cannot be fitted."""
    try:
        long = fit_arx(u, y, dev.segments, HR_ORDER, HR_ORDER, orders.nk)
    except IdentificationError:
        return None
    eps = y - predict_one_step(long, u, y, dev.segments)
    cols = [_lagged(dev.y0, i) for i in range(1, orders.na + 1)]
    cols += [_lagged(dev.u0, orders.nk + j) for j in range(orders.nb)]
    cols += [_lagged(eps, i) for i in range(1, orders.nc + 1)]
    rows = regression_rows(dev.segments, long.max_lag + orders.nc, y.size)
    if np.count_nonzero(rows) <= 2 * orders.n_params:
        return None
    x = np.column_stack(cols)[rows]
    return np.linalg.lstsq(x, dev.y0[rows], rcond=None)[0]


def fit_armax(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    na: int,
    nb: int,
    nc: int,
    nk: int,
    *,
    sample_period_s: float = 1.2,
    start: Sequence[float] | None = None,
) -> PemFit:
    """ARMAX(na, nb, nc, nk) fit on segments (one-step prediction error minimised).

    Parameters
    ----------
    u : ndarray
        Gate opening, mm (absolute; NaN splits a segment).
    y : ndarray
        Level, mm (absolute; NaN splits a segment).
    segments : sequence of (int, int) or ndarray
        Segments, ``stop`` exclusive.
    na, nb, nc, nk : int
        Orders of ``A``, ``B``, ``C`` (``nc >= 1``) and the input delay, samples.
    sample_period_s : float, optional
        Sample period stored on the fit, s (default 1.2).
    start : sequence of float, optional
        A single start value ``(a, b, c)``; default: the better of the two starts of the
        module docstring.

    Returns
    -------
    PemFit
        Structure ``"armax"``.

    Raises
    ------
    IdentificationError
        Bad orders, too few rows, ``b`` not identifiable, or a flat criterion.
    """
    if not int(nc) == nc >= 1:
        raise IdentificationError(f"ARMAX needs nc >= 1 (got {nc}); nc = 0 is ARX")
    orders = PemOrders("armax", na, nb, nk, nc=nc)
    dev = deviations(u, y, segments)
    if start is not None:
        return fit_pem(orders, dev, np.asarray(start, float), sample_period_s=sample_period_s)
    arx = fit_arx(u, y, segments, na, nb, nk, sample_period_s=sample_period_s)
    best = fit_pem(orders, dev, np.r_[arx.theta, np.zeros(nc)], sample_period_s=sample_period_s)
    hr = hannan_rissanen(u, y, dev, orders)
    if hr is not None:
        other = fit_pem(orders, dev, hr, sample_period_s=sample_period_s)
        if other.stable >= best.stable and other.noise_variance_mm2 < best.noise_variance_mm2:
            best = other
    return best
