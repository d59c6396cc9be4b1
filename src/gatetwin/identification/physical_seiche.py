"""The pool's seiche in the ``physical`` family (stage 6 of
:mod:`gatetwin.identification.physical`).

The periods the sampling and the pool can show, where the period's search starts (the
simulation error's spectrum) and the fit of period, decay time and amplitude with the
hydraulics held, kept by an F-test. The seiche's arithmetic is not here: it is the plant's
``seiche`` effect block (:mod:`gatetwin.plant.blocks`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from gatetwin.identification import physical_start as start
from gatetwin.identification.physical_residuals import (
    NO_SEICHE,
    SEICHE,
    SEICHE_SIGNIFICANCE,
    SteadyPoints,
    _Drive,
    _dynamic_residuals,
    _f_test_p,
    _standard_errors,
)
from gatetwin.plant import physical_kernel as kernel
from gatetwin.records import Record

__all__ = ["SEICHE_AMPLITUDE_MAX", "SEICHE_AMPLITUDE_START", "seiche_periods_s"]

#: Amplitude start of the seiche fit, mm of level per mm of gate move.
SEICHE_AMPLITUDE_START = 0.3
#: Largest |amplitude| of the seiche, mm per mm of gate move.
SEICHE_AMPLITUDE_MAX = 5.0


def seiche_periods_s(records: dict[str, Record], p: np.ndarray, points: SteadyPoints
                     ) -> tuple[float, float]:  # fmt: skip
    """The seiche periods the data can show, s: from two sample periods (a faster oscillation
    aliases) to the quarter-wave period of the longest pool the storage allows, 4 L / sqrt(g h)
    with L = area / gate width (the channel is at least as wide as the gate) at the steady
    points' median depth."""
    depth_m = max(float(np.median(points.level_mm + p[kernel.INDEX["offset_mm"]])) / 1000.0,
                  kernel.DEPTH_MIN_M)  # fmt: skip
    length_m = kernel.storage_area_m2(depth_m, list(p)) / p[kernel.INDEX["width_m"]]
    return 2.0 * start.sample_period_s(records), 4.0 * length_m / math.sqrt(kernel.G * depth_m)


def _seiche_start(
    residuals: Sequence[np.ndarray], drives: Sequence[_Drive], periods_s: tuple[float, float]
) -> float:
    """The period of the strongest oscillation left in the simulation error within
    ``periods_s`` (the records' power spectra summed on one grid of periods), s."""
    grid = np.geomspace(periods_s[0], periods_s[1], 64)
    power = np.zeros(grid.size)
    for r, d in zip(residuals, drives, strict=True):
        dt = float(np.median(np.diff(d.time_s)))
        freq = np.fft.rfftfreq(r.size, dt)
        spectrum = np.abs(np.fft.rfft(r - r.mean())) ** 2
        power += np.interp(1.0 / grid, freq, spectrum)
    return float(grid[int(np.argmax(power))])


def _fit_seiche(drives: Sequence[_Drive], p: np.ndarray, weights: list[float],
                periods_s: tuple[float, float]) -> tuple[np.ndarray, dict[str, Any]]:  # fmt: skip
    """The pool's seiche from the simulation error left by the hydraulics (held fixed): its
    period (within ``periods_s``, started at the residuals' spectral peak), decay time (one
    sample period to ten of the longest periods) and amplitude per mm of gate move, with an
    F-test against none; not kept when the period or the decay time ends on its bound
    (``at_bound`` in the report)."""

    def weighted(res: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([r / w for r, w in zip(res, weights, strict=True)])

    def residual(x: np.ndarray) -> np.ndarray:
        return weighted(_dynamic_residuals(drives, p, np.asarray(x, float)))

    plain = _dynamic_residuals(drives, p)
    without = weighted(plain)
    if periods_s[1] <= periods_s[0]:
        reason = (
            f"no seiche the sampling can show: the longest pool's quarter-wave period "
            f"{periods_s[1]:.3g} s is under two sample periods ({periods_s[0]:.3g} s)"
        )
        return NO_SEICHE.copy(), {"kept": False, "reason": reason}
    period = _seiche_start(plain, drives, periods_s)
    lower = (periods_s[0], periods_s[0] / 2.0, -SEICHE_AMPLITUDE_MAX)
    upper = (periods_s[1], 10.0 * periods_s[1], SEICHE_AMPLITUDE_MAX)
    result = least_squares(residual, (period, period, SEICHE_AMPLITUDE_START),
                           bounds=(lower, upper), x_scale="jac")  # fmt: skip
    n, k = without.size, len(SEICHE)
    rss0, rss1 = float(without @ without), 2.0 * float(result.cost)
    p_value = _f_test_p(rss0, rss1, k, max(1, n - k))
    # a period or decay time at its bound is not an oscillation the sampling resolves (a
    # decay of one sample period is a transient the hydraulics miss), and the F-test's
    # reference distribution does not hold on a bound
    bounded = [name for name, active in zip(SEICHE[:2], result.active_mask[:2], strict=True)
               if active != 0]  # fmt: skip
    report = {
        "kept": bool(result.success and p_value < SEICHE_SIGNIFICANCE and result.x[2] != 0.0
                     and not bounded),  # fmt: skip
        "at_bound": bounded,
        "parameters": dict(zip(SEICHE, (float(v) for v in result.x), strict=True)),
        "standard_errors": _standard_errors(result, SEICHE),
        "f_test_p_value": p_value,
        "weighted_rss_without": rss0, "weighted_rss_with": rss1,
        "period_bounds_s": [float(v) for v in periods_s], "period_start_s": period,
    }  # fmt: skip
    return np.asarray(result.x, float), report
