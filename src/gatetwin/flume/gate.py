"""The sluice gate as a boundary: discharge-coefficient law, free and submerged underflow.

Numba-compiled scalar functions, called from the solver at every time step; the same
functions are callable from Python (for the rating relation and tests).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gatetwin.flume.config import GateLaw

__all__ = ["CONTRACTION", "G", "discharge_coefficient", "gate_law_array", "unit_discharge"]

G = 9.81
#: Contraction coefficient used only for the free/submerged transition (vena contracta).
CONTRACTION = 0.61


def gate_law_array(law: GateLaw) -> np.ndarray:
    """Pack a :class:`GateLaw` into the flat array the compiled functions read."""
    return np.array(
        [
            law.flow_m3h[0],
            law.flow_m3h[1],
            law.intercept[0],
            law.intercept[1],
            law.slope[0],
            law.slope[1],
            law.r_low,
            law.r_high,
            law.cd_large_r,
        ]
    )


@njit(cache=True)
def discharge_coefficient(r: float, flow_m3h: float, law: np.ndarray) -> float:
    """Effective Cd at opening ratio ``r = e/h`` and discharge ``flow_m3h`` (see GateLaw)."""
    w = (flow_m3h - law[0]) / (law[1] - law[0])
    w = min(1.0, max(0.0, w))
    c0 = law[2] + w * (law[3] - law[2])
    s = law[4] + w * (law[5] - law[4])
    r_low, r_high, cd_inf = law[6], law[7], law[8]
    if r <= r_low:
        return c0 + s * r_low
    if r <= r_high:
        return c0 + s * r
    cd_high = c0 + s * r_high
    span = (cd_high - cd_inf) / (-s) if s < 0.0 else 0.0
    if span <= 0.0:
        return cd_high
    return cd_high - (cd_high - cd_inf) * (1.0 - math.exp(-(r - r_high) / span))


@njit(cache=True)
def unit_discharge(
    h_up: float, opening_m: float, tailwater_m: float, flow_m3h: float, law: np.ndarray
) -> float:
    """Discharge per unit width under the gate, m²/s.

    Free underflow ``q = Cd e sqrt(2 g h)``; submerged when the tailwater exceeds the
    conjugate depth of the vena contracta, then ``q = Cd e sqrt(2 g (h - h_t))``; never more
    than critical flow over the section (gate lifted clear of the water). ``tailwater_m``
    < 0 means a free outfall.
    """
    if h_up <= 0.0 or opening_m <= 0.0:
        return 0.0
    cd = discharge_coefficient(opening_m / h_up, flow_m3h, law)
    q = cd * opening_m * math.sqrt(2.0 * G * h_up)
    if tailwater_m > 0.0:
        y2 = CONTRACTION * opening_m
        fr2 = q / (y2 * math.sqrt(G * y2))
        conjugate = 0.5 * y2 * (math.sqrt(1.0 + 8.0 * fr2 * fr2) - 1.0)
        if tailwater_m > conjugate:
            head = max(h_up - tailwater_m, 0.0)
            q = min(q, cd * opening_m * math.sqrt(2.0 * G * head))
    q_critical = math.sqrt(G) * (2.0 * h_up / 3.0) ** 1.5
    return min(q, q_critical)
