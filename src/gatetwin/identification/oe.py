"""Output-error models: the deterministic part fitted by its free-run (simulation) error.

Model (deviations from the operating point; ``+`` convention of the reference study)::

    x(k)  = f1 x(k-1) + ... + f_nf x(k-nf) + b1 u'(k-nk) + ... + b_nb u'(k-nk-nb+1)
    y'(k) = x(k) + eps(k)

i.e. ``y' = B/F u' + eps``. The coefficients minimise ``sum (y'(k) - x(k))^2``: the error
of a *simulation* that never sees a measured level, which is how an FMU runs. An
equation-error ARX fit of the same data feeds the measured (noisy) level back as a
regressor; with any noise on the level its ``a`` are biased (the noise is coloured in
ARX's equation error ``F(q) eps``), an OE fit is not (for any noise independent of the
opening).

Segments are never bridged: each is simulated from its own first ``max(nf, nk+nb-1)``
*measured* levels and openings and scored after them (the rows of the ARX fit). The
minimisation starts from the equation-error ARX estimate; an unstable optimum is mirrored
into the unit circle and refined once (see :func:`gatetwin.identification.pemfit.fit_pem`).

``F`` is stored as ``a`` on the fit, so :meth:`~gatetwin.identification.pemfit.PemFit.as_arx`
gives a model for :func:`~gatetwin.identification.arx.simulate_free` and every ARX rendering.
The standard errors assume white ``eps``; with coloured noise they are too small (use
Box-Jenkins, :mod:`gatetwin.identification.bj`, for honest ones).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gatetwin.identification.arx import deviations, fit_arx
from gatetwin.identification.pem import PemOrders
from gatetwin.identification.pemfit import PemFit, fit_pem
from gatetwin.identification.preprocess import Segments

__all__ = ["fit_oe"]


def fit_oe(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    nf: int,
    nb: int,
    nk: int,
    *,
    sample_period_s: float = 1.2,
    start: Sequence[float] | None = None,
) -> PemFit:
    """Output-error OE(nf, nb, nk) fit on segments (free-run error minimised).

    Parameters
    ----------
    u : ndarray
        Gate opening, mm (absolute; NaN splits a segment).
    y : ndarray
        Level, mm (absolute; NaN splits a segment).
    segments : sequence of (int, int) or ndarray
        Segments, ``stop`` exclusive; cut at NaNs as in
        :func:`~gatetwin.identification.arx.fit_arx`.
    nf, nb, nk : int
        Orders of ``F`` and ``B`` and the input delay, samples (the ARX layout
        ``na, nb, nk``).
    sample_period_s : float, optional
        Sample period stored on the fit, s (default 1.2).
    start : sequence of float, optional
        Start value ``(f1..f_nf, b1..b_nb)``; default the equation-error ARX estimate.

    Returns
    -------
    PemFit
        Structure ``"oe"``; ``a`` holds ``f``. The operating point is that of the ARX fit
        (means over the clean segments).

    Raises
    ------
    IdentificationError
        Bad orders, too few rows, ``b`` not identifiable (see :func:`fit_arx`), or a flat
        criterion at the optimum.
    """
    orders = PemOrders("oe", nf, nb, nk)
    if start is None:
        arx = fit_arx(u, y, segments, nf, nb, nk, sample_period_s=sample_period_s)
        start = arx.a + arx.b
    dev = deviations(u, y, segments)
    return fit_pem(orders, dev, np.asarray(start, float), sample_period_s=sample_period_s)
