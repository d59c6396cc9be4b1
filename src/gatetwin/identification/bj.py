"""Box-Jenkins models: a simulated deterministic part and an ARMA noise model.

Model (deviations; ``+`` convention of the reference study on every right-hand side)::

    x(k)  = f1 x(k-1) + ... + b1 u'(k-nk) + ... + b_nb u'(k-nk-nb+1)
    v(k)  = d1 v(k-1) + ... + d_nd v(k-nd) + eps(k) + c1 eps(k-1) + ... + c_nc eps(k-nc)
    y'(k) = x(k) + v(k)

i.e. ``y' = B/F u' + C/D eps``. The deterministic part is the output-error model of
:mod:`gatetwin.identification.oe`; the noise model whitens the simulation error, which makes the
fit efficient and its standard errors honest when the level noise is coloured.

The coefficients minimise the squared one-step prediction errors
``eps = D/C (y' - B/F u')`` over ARX's rows. Per segment, ``B/F u'`` is simulated from the
segment's first measured samples (as in OE) and ``D/C`` starts at rest. Start value: the
OE fit for ``F``, ``B``; ``C = 1``; ``D`` from a least-squares AR(nd) fit of the OE
simulation error.
"""

from __future__ import annotations

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import Deviations, deviations
from gatetwin.identification.oe import fit_oe
from gatetwin.identification.pem import PemOrders, innovations, reflect_into_unit_disc
from gatetwin.identification.pemfit import PemFit, fit_pem
from gatetwin.identification.preprocess import Segments

__all__ = ["bj_start", "fit_bj"]


def _ar_start(residuals: list[np.ndarray], nd: int) -> np.ndarray:
    """Least-squares AR(nd) coefficients (``+`` convention) of per-segment residuals."""
    rows, targets = [], []
    for v in residuals:
        if v.size <= nd:
            continue
        rows.append(np.column_stack([v[nd - i : v.size - i] for i in range(1, nd + 1)]))
        targets.append(v[nd:])
    if not rows:
        return np.zeros(nd)
    coef = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)[0]
    return reflect_into_unit_disc(coef, plus=False)


def bj_start(oe: PemFit, dev: Deviations, nc: int, nd: int) -> np.ndarray:
    """Start value ``(f, b, c, d)`` of a BJ fit from an OE fit of the same data."""
    oe_orders = PemOrders("oe", oe.orders.na, oe.orders.nb, oe.orders.nk)
    theta = np.array(oe.a + oe.b)
    d0 = _ar_start(innovations(oe_orders, theta, dev), nd)
    return np.concatenate((theta, np.zeros(nc), d0))


def fit_bj(
    u: np.ndarray,
    y: np.ndarray,
    segments: Segments,
    nf: int,
    nb: int,
    nc: int,
    nd: int,
    nk: int,
    *,
    sample_period_s: float = 1.2,
    oe: PemFit | None = None,
) -> PemFit:
    """Box-Jenkins BJ(nf, nb, nc, nd, nk) fit on segments (prediction error minimised).

    Parameters
    ----------
    u : ndarray
        Gate opening, mm (absolute; NaN splits a segment).
    y : ndarray
        Level, mm (absolute; NaN splits a segment).
    segments : sequence of (int, int) or ndarray
        Segments, ``stop`` exclusive.
    nf, nb, nc, nd, nk : int
        Orders of ``F``, ``B``, ``C`` (>= 1), ``D`` (>= 1) and the input delay, samples.
    sample_period_s : float, optional
        Sample period stored on the fit, s (default 1.2).
    oe : PemFit, optional
        An OE(nf, nb, nk) fit of the same data and segments to start from (fitted here
        when not given).

    Returns
    -------
    PemFit
        Structure ``"bj"``; ``a`` holds ``f``.

    Raises
    ------
    IdentificationError
        Bad orders, too few rows, ``b`` not identifiable, a flat criterion, or an ``oe``
        start of other orders.
    """
    orders = PemOrders("bj", nf, nb, nk, nc=nc, nd=nd)
    dev = deviations(u, y, segments)
    if oe is None:
        oe = fit_oe(u, y, segments, nf, nb, nk, sample_period_s=sample_period_s)
    elif (oe.orders.na, oe.orders.nb, oe.orders.nk) != (nf, nb, nk):
        raise IdentificationError(f"{orders.label()}: the OE start has other orders")
    start = bj_start(oe, dev, nc, nd)
    return fit_pem(orders, dev, start, sample_period_s=sample_period_s)
