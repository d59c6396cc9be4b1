"""ARMAX models: equation error with a moving-average noise, fitted by prediction error.

Model (deviations; ``+`` convention of the reference study on every right-hand side)::

    y'(k) = a1 y'(k-1) + ... + a_na y'(k-na) + b1 u'(k-nk) + ... + b_nb u'(k-nk-nb+1)
            + eps(k) + c1 eps(k-1) + ... + c_nc eps(k-nc)

i.e. ``A y' = B u' + C eps`` with ``C = 1 + c1 q^-1 + ...``. Equation-error ARX is the
case ``C = 1``; when the level noise is coloured, ARX is biased and ARMAX, which models
the colour, is not (as long as the noise is a moving average through ``C/A``).

The coefficients minimise the squared one-step prediction errors
``eps = (A y' - B u') / C`` (the predictor of the model) over ARX's rows; the filter
``1/C`` starts at rest in each segment, so segments are never bridged. The minimisation
(:func:`gatetwin.identify.pemfit.fit_pem`) starts from the equation-error ARX estimate
with ``C = 1``; a ``C`` with a root outside the unit circle is mirrored inside (the same
noise spectrum) and refined once.

The deterministic part ``B/A`` is the simulation model: ``a`` and ``b`` have the ARX
layout (:meth:`~gatetwin.identify.pemfit.PemFit.as_arx`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identify.arx import deviations, fit_arx
from gatetwin.identify.pem import PemOrders
from gatetwin.identify.pemfit import PemFit, fit_pem
from gatetwin.identify.preprocess import Segments


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
        Start value ``(a, b, c)``; default the ARX estimate and ``c = 0``.

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
    if start is None:
        arx = fit_arx(u, y, segments, na, nb, nk, sample_period_s=sample_period_s)
        start = arx.a + arx.b + (0.0,) * nc
    dev = deviations(u, y, segments)
    return fit_pem(orders, dev, np.asarray(start, float), sample_period_s=sample_period_s)
