"""The fitted polynomial model and its prediction-error minimisation.

:class:`PemFit` holds a member of the family of :mod:`gatetwin.identification.pem` (ARX, OE,
ARMAX, BJ) with its standard errors; :func:`fit_pem` minimises the squared innovations
from a start value; :func:`from_arx` wraps an equation-error ARX fit in the same form.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg, optimize

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import ArxFit, Deviations
from gatetwin.identification.metrics import arx_poles
from gatetwin.identification.pem import (
    PemOrders,
    is_admissible,
    jacobian,
    stabilised,
    stacked_innovations,
)
from gatetwin.identification.preprocess import constant_within_segments

__all__ = ["PemFit", "fit_pem", "from_arx"]


@dataclass(frozen=True)
class PemFit:
    """A fitted member of the polynomial family (see the module docstring).

    Attributes
    ----------
    orders : PemOrders
        Structure and orders.
    a : tuple of float
        Simulation denominator coefficients (``A`` for ARX/ARMAX, ``F`` for OE/BJ),
        dimensionless, ``+`` convention: ``x(k) = a1 x(k-1) + ... + b1 u'(k-nk) + ...``.
    b : tuple of float
        Input coefficients, mm of level per mm of opening.
    c, d : tuple of float
        Noise polynomials ``C = 1 + c1 q^-1 + ...``, ``D = 1 - d1 q^-1 - ...`` (empty
        where the structure has none), dimensionless.
    a_se, b_se, c_se, d_se : tuple of float
        Standard errors (``sqrt(diag(covariance))``, white-innovation assumption).
    covariance : tuple of tuple of float
        Covariance of ``theta = (a, b, c, d)``: ``sigma^2 (J^T J)^-1``.
    noise_variance_mm2 : float
        Innovation variance ``sigma^2 = SSR / (n_rows - p)``, mm².
    n_rows : int
        Rows (innovations) in the criterion.
    opening_mean_mm, level_mean_mm : float
        Operating point the deviations are taken from, mm.
    sample_period_s : float
        Sample period, s.
    n_evaluations : int
        Criterion evaluations of the minimiser (0 for ARX: solved in closed form).
    converged : bool
        The minimiser reported convergence (always True for ARX).
    message : str
        The minimiser's message, or how the fit was obtained.
    """

    orders: PemOrders
    a: tuple[float, ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    d: tuple[float, ...]
    a_se: tuple[float, ...]
    b_se: tuple[float, ...]
    c_se: tuple[float, ...]
    d_se: tuple[float, ...]
    covariance: tuple[tuple[float, ...], ...]
    noise_variance_mm2: float
    n_rows: int
    opening_mean_mm: float
    level_mean_mm: float
    sample_period_s: float
    n_evaluations: int
    converged: bool
    message: str

    @property
    def structure(self) -> str:
        return self.orders.structure

    @property
    def theta(self) -> np.ndarray:
        return np.array(self.a + self.b + self.c + self.d)

    @property
    def stable(self) -> bool:
        """Simulation stable and noise filters invertible (see :func:`is_admissible`)."""
        return is_admissible(self.orders, self.theta)

    @property
    def poles(self) -> np.ndarray:
        """Poles of the deterministic part (roots of ``A`` or ``F``)."""
        return arx_poles(self.a)

    def as_arx(self) -> ArxFit:
        """The deterministic part as an :class:`ArxFit`: its ``a``, ``b`` and operating
        point drive :func:`~gatetwin.identification.arx.simulate_free` and every ARX rendering
        unchanged (the noise model is dropped; ``noise_variance_mm2`` is the innovation
        variance of this fit)."""
        p = self.orders.na + self.orders.nb
        return ArxFit(
            na=self.orders.na,
            nb=self.orders.nb,
            nk=self.orders.nk,
            a=self.a,
            b=self.b,
            a_se=self.a_se,
            b_se=self.b_se,
            covariance=tuple(r[:p] for r in self.covariance[:p]),
            noise_variance_mm2=self.noise_variance_mm2,
            n_rows=self.n_rows,
            opening_mean_mm=self.opening_mean_mm,
            level_mean_mm=self.level_mean_mm,
            sample_period_s=self.sample_period_s,
        )

    def to_dict(self) -> dict[str, Any]:
        o = self.orders
        return {
            "structure": o.structure,
            "label": o.label(),
            "denominator": "F" if o.simulated else "A",
            "na": o.na,
            "nb": o.nb,
            "nc": o.nc,
            "nd": o.nd,
            "nk": o.nk,
            "a": list(self.a),
            "b": list(self.b),
            "c": list(self.c),
            "d": list(self.d),
            "a_se": list(self.a_se),
            "b_se": list(self.b_se),
            "c_se": list(self.c_se),
            "d_se": list(self.d_se),
            "covariance": [list(r) for r in self.covariance],
            "noise_variance_mm2": self.noise_variance_mm2,
            "n_rows": self.n_rows,
            "opening_mean_mm": self.opening_mean_mm,
            "level_mean_mm": self.level_mean_mm,
            "sample_period_s": self.sample_period_s,
            "n_evaluations": self.n_evaluations,
            "converged": self.converged,
            "message": self.message,
            "stable": self.stable,
        }


def from_arx(fit: ArxFit) -> PemFit:
    """An :class:`ArxFit` as the ``"arx"`` member of the family (same numbers)."""
    return PemFit(
        orders=PemOrders("arx", fit.na, fit.nb, fit.nk),
        a=fit.a,
        b=fit.b,
        c=(),
        d=(),
        a_se=fit.a_se,
        b_se=fit.b_se,
        c_se=(),
        d_se=(),
        covariance=fit.covariance,
        noise_variance_mm2=fit.noise_variance_mm2,
        n_rows=fit.n_rows,
        opening_mean_mm=fit.opening_mean_mm,
        level_mean_mm=fit.level_mean_mm,
        sample_period_s=fit.sample_period_s,
        n_evaluations=0,
        converged=True,
        message="equation-error least squares (normal equations)",
    )


def _least_squares(
    orders: PemOrders, dev: Deviations, theta0: np.ndarray, max_evaluations: int
) -> optimize.OptimizeResult:
    """Levenberg-Marquardt on the stacked innovations from ``theta0``."""
    return optimize.least_squares(
        lambda theta: stacked_innovations(orders, theta, dev),
        np.asarray(theta0, dtype=float),
        method="lm",
        x_scale="jac",
        max_nfev=max_evaluations,
    )


def _tuple(values: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def fit_pem(
    orders: PemOrders,
    dev: Deviations,
    theta0: np.ndarray,
    *,
    sample_period_s: float = 1.2,
    max_evaluations: int = 2000,
) -> PemFit:
    """Minimise the squared innovations of ``orders`` on ``dev`` from ``theta0``.

    When the optimum is not admissible (simulation unstable, or ``C``/``D`` with a root
    outside the unit circle) its offending roots are mirrored into the disc and the
    minimisation is run once more from there; the result says whether it ended
    admissible (:attr:`PemFit.stable`).

    Parameters
    ----------
    orders : PemOrders
        Structure and orders.
    dev : Deviations
        Deviation signals and clean segments (:func:`gatetwin.identification.arx.deviations`).
    theta0 : ndarray
        Start value ``(a, b, c, d)``.
    sample_period_s : float, optional
        Sample period stored on the fit, s.
    max_evaluations : int, optional
        Largest number of criterion evaluations per minimisation (default 2000).

    Returns
    -------
    PemFit

    Raises
    ------
    IdentificationError
        No more rows than parameters, ``nb >= 2`` with an opening constant within every
        segment, or a singular Jacobian at the optimum (parameters
        not identifiable from these data).
    """
    p = orders.n_params
    n_rows = int(np.maximum(dev.segments[:, 1] - dev.segments[:, 0] - orders.drop, 0).sum())
    if n_rows <= p:
        raise IdentificationError(
            f"{orders.label()} needs more than {p} rows, the segments give {n_rows}"
        )
    if orders.nb >= 2 and constant_within_segments(dev.u0, dev.segments, dev.mask):
        raise IdentificationError(
            f"{orders.label()}: the opening is constant within every segment, so only "
            "the sum of the b coefficients is identifiable; fit nb=1, or fit on all "
            "samples with the opening reconstructed during actuator motion"
        )
    res = _least_squares(orders, dev, theta0, max_evaluations)
    n_eval = int(res.nfev)
    if not is_admissible(orders, res.x):
        res = _least_squares(orders, dev, stabilised(orders, res.x), max_evaluations)
        n_eval += int(res.nfev)
    return _finish(orders, dev, res, n_eval, n_rows, sample_period_s)


def _finish(
    orders: PemOrders,
    dev: Deviations,
    res: optimize.OptimizeResult,
    n_evaluations: int,
    n_rows: int,
    sample_period_s: float,
) -> PemFit:
    """Covariance from the Jacobian at the optimum, and the :class:`PemFit`."""
    theta = res.x
    e = stacked_innovations(orders, theta, dev)
    sigma2 = float(e @ e) / (n_rows - orders.n_params)
    jac = jacobian(orders, theta, dev)
    try:
        info = linalg.cho_factor(jac.T @ jac)
        cov = sigma2 * linalg.cho_solve(info, np.eye(theta.size))
    except linalg.LinAlgError:
        raise IdentificationError(
            f"{orders.label()}: the criterion is flat in some direction at the optimum "
            "(parameters not identifiable: input not exciting enough, or orders too high)"
        ) from None
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    a, b, c, d = orders.split(theta)
    sa, sb, sc, sd = orders.split(se)
    return PemFit(
        orders=orders,
        a=_tuple(a),
        b=_tuple(b),
        c=_tuple(c),
        d=_tuple(d),
        a_se=_tuple(sa),
        b_se=_tuple(sb),
        c_se=_tuple(sc),
        d_se=_tuple(sd),
        covariance=tuple(_tuple(r) for r in cov),
        noise_variance_mm2=sigma2,
        n_rows=n_rows,
        opening_mean_mm=dev.opening_mean_mm,
        level_mean_mm=dev.level_mean_mm,
        sample_period_s=float(sample_period_s),
        n_evaluations=n_evaluations,
        converged=bool(res.success),
        message=str(res.message),
    )
