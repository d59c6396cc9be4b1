"""Normal equations of segment-wise ARX regressions, from lagged dot products.

An ARX regression row at sample ``k`` is
``z(k) = [y(k), y(k-1), ..., u(k-nk), ..., u(k-nk-nb+1)]``; least squares needs only
``M = sum_k z(k) z(k)^T`` over the rows in use. This module forms ``M`` *without building
the regressor matrix*:

1. the deviation signals are zero-filled outside the (clean) segments (done by
   :func:`gatetwin.identification.arx.deviations`);
2. every entry ``sum_k a(k-p) b(k-q)`` over the whole record is a dot product of two
   shifted views of the signals; entries with the same signal pair and lag difference
   share one pass over the data (they differ by a few end terms);
3. rows that are not in use but still touch a segment -- the first ``drop`` samples of
   each segment and the ``max lag`` samples after its end -- are few (about
   ``2 * drop`` per segment); their contribution is gathered and subtracted.

Every other row has only zero-filled lags and contributes nothing. The result is exact
up to round-off. With all lags wanted up front (``y`` lags ``0..Ly``, ``u`` lags
``0..Lu``), sub-blocks of one :class:`LagProducts` give the normal equations of every
smaller order, which is what makes an order search cheap.

This module knows nothing about records; :mod:`gatetwin.identification.arx` uses it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gatetwin.errors import IdentificationError

__all__ = ["Key", "LagProducts", "inner", "lag_products"]

Key = tuple[str, int]


@dataclass(frozen=True)
class LagProducts:
    """Lag-product matrix of a segmented pair of deviation signals.

    Attributes
    ----------
    keys : tuple of (str, int)
        ``("y", lag)`` or ``("u", lag)`` for each row/column of ``matrix``.
    matrix : ndarray of shape (D, D)
        ``sum_k z(k) z(k)^T`` over the rows in use, with ``z(k)[i] = signal(k - lag)``.
    n_rows : int
        Number of regression rows in use.
    drop : int
        Samples dropped at the start of each segment (no row there).
    """

    keys: tuple[Key, ...]
    matrix: np.ndarray
    n_rows: int
    drop: int

    def index(self, key: Key) -> int:
        """Position of ``key`` in :attr:`keys`."""
        return self.keys.index(key)

    def block(self, na: int, nb: int, nk: int) -> tuple[np.ndarray, np.ndarray, float]:
        """Normal equations of ARX(na, nb, nk).

        Returns
        -------
        gram : ndarray (na+nb, na+nb)
            ``Phi^T Phi`` with ``Phi`` columns ``y(k-1..k-na), u(k-nk..k-nk-nb+1)``.
        rhs : ndarray (na+nb,)
            ``Phi^T y``.
        yy : float
            ``y^T y``.
        """
        cols = [self.index(("y", i)) for i in range(1, na + 1)]
        cols += [self.index(("u", nk + j)) for j in range(nb)]
        i0 = self.index(("y", 0))
        gram = self.matrix[np.ix_(cols, cols)]
        return gram, self.matrix[cols, i0], float(self.matrix[i0, i0])


def inner(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two 1-D arrays without BLAS threads.

    ``numpy.einsum`` runs a single-threaded SIMD loop; a multi-threaded BLAS ``ddot`` on
    a busy machine can be 10-30 times slower than that while its threads wait for a core.
    """
    return float(np.einsum("i,i->", a, b))


def _boundary_rows(segments: np.ndarray, drop: int, max_lag: int, n: int) -> np.ndarray:
    """Rows not in use whose lag vector still reaches into a segment."""
    if segments.size == 0 or (max_lag == 0 and drop == 0):
        return np.zeros(0, dtype=np.int64)
    heads = (segments[:, :1] + np.arange(drop)).ravel()
    tails = (segments[:, 1:] + np.arange(max_lag)).ravel()
    mark = np.zeros(n + drop + max_lag, dtype=bool)
    mark[heads] = True
    mark[tails] = True
    rows = np.flatnonzero(mark[:n])
    return rows[rows >= max_lag]


def _full_products(signal: dict[str, np.ndarray], keys: tuple[Key, ...], lo: int) -> np.ndarray:
    """``F[i, j] = sum_{k=lo}^{n-1} s_i(k - p_i) s_j(k - p_j)`` over the whole record.

    Entries with the same pair of signals and the same lag difference ``d`` share one
    long dot product ``B = sum_{k=lo}^{n-1} s_i(k) s_j(k - d)``; each entry then differs
    from ``B`` by at most ``lo`` terms at either end (a Toeplitz structure), so only one
    pass over the data is made per (pair, ``d``) instead of per entry.
    """
    n = next(iter(signal.values())).size
    base: dict[tuple[str, str, int], float] = {}
    dim = len(keys)
    full = np.empty((dim, dim))
    for i in range(dim):
        for j in range(i, dim):
            (si, pi), (sj, pj) = keys[i], keys[j]
            if pi > pj:
                (si, pi), (sj, pj) = (sj, pj), (si, pi)
            a, b, d = signal[si], signal[sj], pj - pi
            if (si, sj, d) not in base:
                base[(si, sj, d)] = inner(a[lo:], b[lo - d : n - d])
            tail = inner(a[n - pi :], b[n - pi - d : n - d]) if pi else 0.0
            head = inner(a[lo - pi : lo], b[lo - pi - d : lo - d]) if pi else 0.0
            full[i, j] = full[j, i] = base[(si, sj, d)] - tail + head
    return full


def lag_products(
    u0: np.ndarray,
    y0: np.ndarray,
    segments: np.ndarray,
    y_lags: Sequence[int],
    u_lags: Sequence[int],
    drop: int,
) -> LagProducts:
    """Form the lag-product matrix of zero-filled deviation signals.

    Parameters
    ----------
    u0, y0 : ndarray
        Input and output deviations (mm), **zero outside the segments** and finite
        everywhere (see :func:`gatetwin.identification.arx.deviations`).
    segments : ndarray of shape (n, 2)
        Clean segments (no missing sample inside), ``stop`` exclusive.
    y_lags, u_lags : sequence of int
        Lags wanted for each signal; ``y_lags`` must contain 0.
    drop : int
        Rows skipped at the start of each segment; must be at least the largest lag so
        that no row uses a sample outside its own segment.

    Returns
    -------
    LagProducts
    """
    keys: tuple[Key, ...] = tuple(("y", int(p)) for p in y_lags) + tuple(
        ("u", int(p)) for p in u_lags
    )
    max_lag = max(p for _, p in keys)
    if drop < max_lag or min(p for _, p in keys) < 0:
        raise IdentificationError("lags must be >= 0 and no larger than the dropped rows")
    n = y0.size
    signal = {"y": y0, "u": u0}
    full = _full_products(signal, keys, max_lag)
    dim = len(keys)
    rows = _boundary_rows(segments, drop, max_lag, n)
    edge = np.empty((dim, rows.size))
    for i, (s, p) in enumerate(keys):
        np.take(signal[s], rows - p, out=edge[i])
    for i in range(dim):
        for j in range(i, dim):
            full[i, j] -= inner(edge[i], edge[j])
            full[j, i] = full[i, j]
    n_rows = int(np.maximum(segments[:, 1] - segments[:, 0] - drop, 0).sum())
    return LagProducts(keys, full, n_rows, int(drop))
