"""FOPDT fitted with the opening as the plant sees it: the input-driven least squares.

:func:`~gatetwin.identification.fopdt.fit_fopdt` treats the step as instantaneous at its onset,
so its dead time absorbs the gate's travel. An FMU, the harness and the MPC drive the model
with the opening reconstructed during the motion (linear between the holds); a model meant
for them must be fitted the same way, or the travel is counted twice. This fit simulates
``T dx/dt = K·(e(t − L) − e₀) − x`` for the reconstructed opening (piecewise linear: exact
first-order-hold response on a fine grid) and finds K, T, L (continuous, ≥ 0) and the
baseline by least squares over every valid sample of the record, with standard errors from
the Jacobian. It fits any number of steps at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

from gatetwin.errors import IdentificationError

__all__ = ["DEAD_TIME_MAX_S", "GRID_S", "TAU_MAX_S", "DrivenFopdtFit", "fit_fopdt_driven",
           "fopdt_response"]  # fmt: skip

#: Simulation grid of the fit, s (the response is exact for input linear between points).
GRID_S = 0.1
#: Upper bounds of the time constant and the dead time, s, unless ten times the start value is
#: larger (:func:`fit_fopdt_driven`).
TAU_MAX_S = 5000.0
DEAD_TIME_MAX_S = 120.0


@dataclass(frozen=True)
class DrivenFopdtFit:
    """Input-driven FOPDT fit (parameters ± one standard error)."""

    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    baseline_mm: float
    gain_se_mm_per_mm: float
    time_constant_se_s: float
    dead_time_se_s: float
    rmse_mm: float
    n: int
    opening_ref_mm: float


def fopdt_response(time_s: np.ndarray, opening_mm: np.ndarray, gain: float, tau_s: float,
                   delay_s: float, opening_ref_mm: float) -> np.ndarray:  # fmt: skip
    """Deviation response at ``time_s`` to an opening linear between its samples."""
    t_fine = np.arange(time_s[0], time_s[-1] + GRID_S, GRID_S)
    u = np.interp(t_fine - delay_s, time_s, opening_mm) - opening_ref_mm
    a = np.exp(-GRID_S / tau_s)
    # first-order hold: exact for u linear between grid points
    b1 = gain * (1.0 - tau_s / GRID_S * (1.0 - a))
    b0 = gain * (tau_s / GRID_S * (1.0 - a) - a)
    x0 = gain * u[0]
    y, _ = signal.lfilter([b1, b0], [1.0, -a], u, zi=[x0 - b1 * u[0]])
    return np.interp(time_s, t_fine, y)


def fit_fopdt_driven(time_s: np.ndarray, opening_mm: np.ndarray, level_mm: np.ndarray,
                     initial: tuple[float, float, float] = (-10.0, 50.0, 1.0),
                     ) -> DrivenFopdtFit:  # fmt: skip
    """Least-squares FOPDT driven by ``opening_mm`` (no NaN) against ``level_mm``."""
    t = np.asarray(time_s, float)
    e = np.asarray(opening_mm, float)
    y = np.asarray(level_mm, float)
    ok = np.isfinite(y)
    if not np.all(np.isfinite(e)) or ok.sum() < 10 or np.ptp(e) < 1.0:
        raise IdentificationError(
            "driven FOPDT: needs a finite opening that changes by >= 1 mm and >= 10 levels"
        )
    e_ref = float(e[0])

    def residual(p: np.ndarray) -> np.ndarray:
        k, tau, delay, h0 = p
        return (h0 + fopdt_response(t, e, k, tau, delay, e_ref))[ok] - y[ok]

    k0, tau0, l0 = initial
    p0 = np.array([k0, tau0, l0, float(np.nanmedian(y[: max(5, ok.sum() // 20)]))])
    # T and L bounded above by the flume-scale caps or ten times the step fit's start, the
    # larger: a canal pool's hour-long time constant starts inside its bounds
    tau_hi, delay_hi = max(TAU_MAX_S, 10.0 * tau0), max(DEAD_TIME_MAX_S, 10.0 * l0)
    res = optimize.least_squares(residual, p0, bounds=([-np.inf, 0.5, 0.0, -np.inf],
                                                       [np.inf, tau_hi, delay_hi, np.inf]),
                                 x_scale=[1.0, 10.0, 1.0, 10.0], diff_step=1e-6)  # fmt: skip
    n, dof = int(ok.sum()), max(1, int(ok.sum()) - 4)
    sigma2 = float(res.fun @ res.fun) / dof
    cov = sigma2 * np.linalg.pinv(res.jac.T @ res.jac)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    k, tau, delay, h0 = (float(v) for v in res.x)
    delay = max(delay, 0.0)  # the bound, up to the solver's round-off
    return DrivenFopdtFit(k, tau, delay, h0, float(se[0]), float(se[1]), float(se[2]),
                          float(np.sqrt(np.mean(res.fun**2))), n, e_ref)  # fmt: skip
