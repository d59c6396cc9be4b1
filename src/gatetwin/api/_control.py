"""A model's small-signal dynamics at one operating point as a python-control system.

FOPDT, envelope FOPDT and physical models: ``K e^{-Ls} / (T s + 1)`` with K, T, L from
:meth:`Model.at <gatetwin.api.Model.at>`; continuous with the delay as a Padé
approximant, or discrete with the delay exact (zero-order-hold equivalent, the delay split
into whole samples and a fraction). ARX models: their own discrete transfer function.
Effect blocks and the nonlinearity away from the operating point are not represented.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gatetwin.errors import GatetwinError
from gatetwin.plant.model import ArxPlant

__all__ = ["DT_RTOL", "arx_polynomials", "transfer_function", "zoh_fopdt"]

#: Relative tolerance for "dt is the ARX model's own sample period".
DT_RTOL = 1e-9


def zoh_fopdt(gain: float, tau_s: float, delay_s: float, dt_s: float
              ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Numerator and denominator in ``z`` of the exact ZOH equivalent of an FOPDT.

    With ``L = d·dt + θ`` (``0 <= θ < dt``) and ``a = exp(-dt/T)``, an input held over each
    sample gives ``x(k+1) = a x(k) + b0 u(k-d) + b1 u(k-d-1)`` with
    ``b0 = K (1 - exp(-(dt-θ)/T))`` and ``b1 = K (exp(-(dt-θ)/T) - a)``, that is
    ``G(z) = (b0 z + b1) / (z^(d+1) (z - a))``; with ``θ = 0`` (``b1 = 0``) the common
    factor ``z`` is cancelled: ``G(z) = b0 / (z^d (z - a))``.
    """
    whole = math.floor(delay_s / dt_s + 1e-12)
    theta = max(delay_s - whole * dt_s, 0.0)
    a = math.exp(-dt_s / tau_s)
    if theta <= 1e-12 * dt_s:
        return np.array([gain * (1.0 - a)]), np.polymul(np.r_[1.0, np.zeros(whole)], [1.0, -a])
    rest = math.exp(-(dt_s - theta) / tau_s)
    num = np.array([gain * (1.0 - rest), gain * (rest - a)])
    den = np.polymul(np.r_[1.0, np.zeros(whole + 1)], [1.0, -a])
    return num, den


def arx_polynomials(plant: ArxPlant, flow_m3h: float) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator in ``z`` of the ARX model at ``flow_m3h``.

    ``x(k) = Σ a_i x(k-i) + Σ b_j u(k-nk-j+1)`` gives
    ``X/U = Σ b_j z^-(nk+j-1) / (1 - Σ a_i z^-i)``, multiplied through by ``z^N``.
    """
    a, b = plant.coefficients(flow_m3h)
    order = max(plant.na, plant.nk + plant.nb - 1)
    den = np.zeros(order + 1)
    den[0] = 1.0
    den[1 : plant.na + 1] = -a
    num = np.zeros(order + 1)
    num[plant.nk : plant.nk + plant.nb] = b
    return num, den


def transfer_function(model: Any, flow_m3h: float, opening_mm: float, pade_order: int,
                      dt: float | None) -> Any:  # fmt: skip
    """The python-control TransferFunction of ``model`` at (Q, e); see the module doc."""
    import control

    names = {"inputs": "opening_mm", "outputs": f"level_{model.gauge}_mm", "name": model.name}
    plant = model.plant
    if dt is not None and not (math.isfinite(dt) and dt > 0):
        raise GatetwinError(f"dt = {dt!r}: expected a sample period > 0 in s, or None")
    if isinstance(plant, ArxPlant):
        ts = plant.sample_period_s
        if dt is not None and not math.isclose(dt, ts, rel_tol=DT_RTOL):
            raise GatetwinError(f"{model.name} is an ARX model sampled at {ts:g} s; dt = {dt:g} "
                                "s would need resampling, which is not offered")  # fmt: skip
        num, den = arx_polynomials(plant, flow_m3h)
        return control.tf(num, den, ts, **names)
    point = model.at(flow_m3h, opening_mm)
    k, tau, delay = point.gain_mm_per_mm, point.time_constant_s, point.dead_time_s
    if dt is not None:
        num, den = zoh_fopdt(k, tau, delay, dt)
        return control.tf(num, den, dt, **names)
    if not (isinstance(pade_order, int) and pade_order >= 1):
        raise GatetwinError(f"pade_order = {pade_order!r}: expected an integer >= 1")
    num, den = np.array([k]), np.array([tau, 1.0])
    if delay > 0:
        p_num, p_den = control.pade(delay, pade_order)
        num, den = np.polymul(num, p_num), np.polymul(den, p_den)
    return control.tf(num, den, **names)
