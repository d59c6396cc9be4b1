"""Prediction-error fits of the polynomial model family ARX, OE, ARMAX and Box-Jenkins.

Every structure is a special case of (deviations from the operating point, ``q^-1`` the
one-sample delay)::

    A(q) y'(k) = B(q)/F(q) u'(k) + C(q)/D(q) eps(k)

written, as in the reference study, with ``+`` signs on the right-hand side of every
difference equation:

* ``A(q) = 1 - a1 q^-1 - ... - a_na q^-na`` (ARX, ARMAX) or
  ``F(q) = 1 - f1 q^-1 - ...`` (OE, BJ) -- the *simulation denominator*; its
  coefficients are stored as ``a`` in both cases, so that the deterministic part
  ``x(k) = a1 x(k-1) + ... + b1 u'(k-nk) + b2 u'(k-nk-1) + ...`` has exactly the
  coefficient layout of :class:`~gatetwin.identification.arx.ArxFit`;
* ``B(q) = q^-nk (b1 + b2 q^-1 + ...)``, mm of level per mm of opening;
* ``C(q) = 1 + c1 q^-1 + ...`` (moving average of the noise);
* ``D(q) = 1 - d1 q^-1 - ...`` (autoregression of the noise, BJ only).

====== ================================= ==========================================
name   model                             innovation ``eps(k)`` used as residual
====== ================================= ==========================================
arx    ``A y' = B u' + eps``             ``A y' - B u'``
oe     ``y' = B/F u' + eps``             ``y' - B/F u'`` (the free-run error)
armax  ``A y' = B u' + C eps``           ``(A y' - B u') / C``
bj     ``y' = B/F u' + C/D eps``         ``D/C (y' - B/F u')``
====== ================================= ==========================================

The parameters minimise the sum of squared innovations over the same rows as the ARX
fit: sample ``k`` of a segment is a row once all its ``max(na, nk+nb-1)`` lags lie in that
segment, so **segments are never bridged**. Initial conditions, per segment:

* ``B/F u'`` (OE, BJ) is simulated from the segment's own first ``max(na, nk+nb-1)``
  *measured* levels and openings (the simulated output is set equal to the measured level
  there) -- the same start as a regression row of ARX;
* the noise filters ``1/C`` and ``D/C`` start at rest (zero past innovations).

The minimisation (:func:`gatetwin.identification.pemfit.fit_pem`) is
:func:`scipy.optimize.least_squares` (Levenberg-Marquardt) on the stacked innovations of
this module, from a start value the method modules supply. Standard errors come
from the Jacobian at the optimum, ``sigma^2 (J^T J)^-1`` with
``sigma^2 = SSR / (n_rows - p)``; they assume the innovations are white, i.e. that the
noise model is right (an OE fit to data with coloured noise reports too small ones).

The method modules are :mod:`~gatetwin.identification.oe`,
:mod:`~gatetwin.identification.armax` and :mod:`~gatetwin.identification.bj`;
:mod:`~gatetwin.identification.discrete_select` compares them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import Deviations, check_orders, regression_rows
from gatetwin.identification.metrics import is_stable

__all__ = [
    "BLOWN_UP_MM",
    "STRUCTURES",
    "PemOrders",
    "innovations",
    "is_admissible",
    "jacobian",
    "one_step_prediction",
    "reflect_into_unit_disc",
    "simulate_segment",
    "stabilised",
    "stacked_innovations",
]

#: The structures of the family, simplest first (the order ties are broken in).
STRUCTURES = ("arx", "oe", "armax", "bj")

#: Innovation value substituted for a non-finite one (an unstable trial point), mm.
BLOWN_UP_MM = 1e10


@dataclass(frozen=True)
class PemOrders:
    """Orders of one member of the polynomial family.

    Attributes
    ----------
    structure : str
        ``"arx"``, ``"oe"``, ``"armax"`` or ``"bj"``.
    na : int
        Order of the simulation denominator (``A`` for ARX/ARMAX, ``F`` for OE/BJ).
    nb : int
        Number of input coefficients.
    nk : int
        Input delay, samples.
    nc, nd : int
        Orders of ``C`` and ``D`` (0 where the structure has none).
    """

    structure: str
    na: int
    nb: int
    nk: int
    nc: int = 0
    nd: int = 0

    def __post_init__(self) -> None:
        if self.structure not in STRUCTURES:
            raise IdentificationError(
                f"structure must be one of {', '.join(STRUCTURES)}, got {self.structure!r}"
            )
        check_orders(self.na, self.nb, self.nk)
        has_c = self.structure in ("armax", "bj")
        if has_c != (self.nc >= 1) or (self.structure == "bj") != (self.nd >= 1):
            raise IdentificationError(
                f"{self.structure}: nc >= 1 exactly for armax and bj, nd >= 1 exactly for bj "
                f"(got nc={self.nc}, nd={self.nd})"
            )

    @property
    def simulated(self) -> bool:
        """True when the deterministic part is simulated (``B/F``: OE and BJ)."""
        return self.structure in ("oe", "bj")

    @property
    def drop(self) -> int:
        """Samples at the start of each segment that give no row: ``max(na, nk+nb-1)``."""
        return max(self.na, self.nk + self.nb - 1)

    @property
    def n_params(self) -> int:
        return self.na + self.nb + self.nc + self.nd

    def split(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """``theta`` cut into ``(a, b, c, d)``."""
        edges = np.cumsum([self.na, self.nb, self.nc])
        return tuple(np.split(np.asarray(theta, dtype=float), edges))

    def label(self) -> str:
        """E.g. ``"OE(nf=2, nb=2, nk=1)"``."""
        den = "nf" if self.simulated else "na"
        parts = [f"{den}={self.na}", f"nb={self.nb}"]
        parts += [f"nc={self.nc}"] if self.nc else []
        parts += [f"nd={self.nd}"] if self.nd else []
        return f"{self.structure.upper()}({', '.join(parts + [f'nk={self.nk}'])})"


def _den(coefficients: np.ndarray) -> np.ndarray:
    """``[1, -c1, -c2, ...]``: a polynomial with the ``+`` right-hand-side convention."""
    return np.concatenate(([1.0], -np.asarray(coefficients, dtype=float)))


def simulate_segment(
    orders: PemOrders, a: np.ndarray, b: np.ndarray, u0: np.ndarray, y0: np.ndarray, span: tuple
) -> np.ndarray:
    """``B/F u'`` on the rows of one segment, started from its first measured samples.

    Parameters
    ----------
    orders : PemOrders
        Orders (``na``, ``nb``, ``nk``, ``drop`` are used).
    a, b : ndarray
        Simulation coefficients.
    u0, y0 : ndarray
        Opening and level deviations, mm.
    span : (int, int)
        The segment, ``stop`` exclusive; it must be longer than ``orders.drop``.

    Returns
    -------
    ndarray
        Simulated level deviation, mm, on samples ``start + drop .. stop - 1``.
    """
    start, stop = int(span[0]) + orders.drop, int(span[1])
    n_u = orders.nk + orders.nb - 1
    num = np.concatenate((np.zeros(orders.nk), b))
    den = _den(a)
    y_past = y0[start - orders.na : start][::-1]
    u_past = u0[start - n_u : start][::-1] if n_u else np.zeros(0)
    zi = signal.lfiltic(num, den, y_past, u_past)
    return signal.lfilter(num, den, u0[start:stop], zi=zi)[0]


def _equation_error(orders: PemOrders, a: np.ndarray, b: np.ndarray, dev: Deviations) -> np.ndarray:
    """``A y' - B u'`` at every sample (zero-filled lags; only rows are meaningful)."""
    n = dev.y0.size
    w = dev.y0.copy()
    for i, a_i in enumerate(a, start=1):
        w[i:] -= a_i * dev.y0[: n - i]
    for j, b_j in enumerate(b):
        lag = orders.nk + j
        w[lag:] -= b_j * dev.u0[: n - lag]
    return w


def innovations(orders: PemOrders, theta: np.ndarray, dev: Deviations) -> list[np.ndarray]:
    """Innovations ``eps(k)`` of every segment's rows (list, one array per segment).

    Segments not longer than ``orders.drop`` give an empty array.
    """
    a, b, c, d = orders.split(theta)
    wide = None if orders.simulated else _equation_error(orders, a, b, dev)
    noise_num, noise_den = _den(d), np.concatenate(([1.0], c))
    out = []
    for start, stop in dev.segments:
        if stop - start <= orders.drop:
            out.append(np.zeros(0))
            continue
        if wide is None:
            rows = slice(start + orders.drop, stop)
            v = dev.y0[rows] - simulate_segment(orders, a, b, dev.u0, dev.y0, (start, stop))
        else:
            v = wide[start + orders.drop : stop]
        if orders.nc or orders.nd:
            v = signal.lfilter(noise_num, noise_den, v)
        out.append(v)
    return out


def stacked_innovations(orders: PemOrders, theta: np.ndarray, dev: Deviations) -> np.ndarray:
    """All rows' innovations in one array; non-finite values replaced by a large number."""
    parts = innovations(orders, theta, dev)
    e = np.concatenate(parts) if parts else np.zeros(0)
    if not np.all(np.isfinite(e)):
        e = np.nan_to_num(e, nan=BLOWN_UP_MM, posinf=BLOWN_UP_MM, neginf=-BLOWN_UP_MM)
    return e


def one_step_prediction(orders: PemOrders, theta: np.ndarray, dev: Deviations) -> np.ndarray:
    """One-step-ahead predicted level deviation ``y' - eps``, mm; NaN off the rows.

    For OE the one-step predictor *is* the free-run simulation (its noise model is 1).
    """
    n = dev.y0.size
    pred = np.full(n, np.nan)
    rows = regression_rows(dev.segments, orders.drop, n)
    if np.any(rows):
        eps = np.concatenate(innovations(orders, theta, dev))
        pred[rows] = dev.y0[rows] - eps
    return pred


def jacobian(orders: PemOrders, theta: np.ndarray, dev: Deviations) -> np.ndarray:
    """Central-difference Jacobian of the stacked innovations, shape ``(n_rows, p)``."""
    theta = np.asarray(theta, dtype=float)
    cols = []
    for i in range(theta.size):
        step = 1e-6 * max(1.0, abs(theta[i]))
        hi, lo = theta.copy(), theta.copy()
        hi[i] += step
        lo[i] -= step
        diff = stacked_innovations(orders, hi, dev) - stacked_innovations(orders, lo, dev)
        cols.append(diff / (2.0 * step))
    return np.column_stack(cols)


def reflect_into_unit_disc(coefficients: np.ndarray, plus: bool) -> np.ndarray:
    """Mirror roots outside the unit circle to ``1/conj(root)`` (same spectrum shape).

    ``plus`` says the polynomial is ``1 + c1 q^-1 + ...`` (else ``1 - c1 q^-1 - ...``).
    """
    coefficients = np.asarray(coefficients, dtype=float)
    if coefficients.size == 0:
        return coefficients
    sign = 1.0 if plus else -1.0
    roots = np.roots(np.concatenate(([1.0], sign * coefficients)))
    outside = np.abs(roots) > 1.0
    roots[outside] = 1.0 / np.conj(roots[outside])
    return sign * np.real(np.poly(roots))[1:]


def stabilised(orders: PemOrders, theta: np.ndarray) -> np.ndarray:
    """``theta`` with the simulation denominator and ``C``, ``D`` reflected into the disc."""
    a, b, c, d = orders.split(theta)
    return np.concatenate(
        (
            reflect_into_unit_disc(a, plus=False),
            b,
            reflect_into_unit_disc(c, plus=True),
            reflect_into_unit_disc(d, plus=False),
        )
    )


def is_admissible(orders: PemOrders, theta: np.ndarray) -> bool:
    """Simulation denominator stable and ``C``, ``D`` with every root inside the circle."""
    a, _, c, d = orders.split(theta)
    minimum_phase = c.size == 0 or bool(np.all(np.abs(np.roots(np.concatenate(([1.0], c)))) < 1))
    return is_stable(a) and minimum_phase and (d.size == 0 or is_stable(d))
