"""The value of a tabulated signal at a time, written once.

Standard library only and no gatetwin imports: the scenario FMU of an SSP
(:mod:`gatetwin.fmu.signal_source`) computes its outputs with ``signal_law.c``, generated
from this module's syntax tree (:mod:`gatetwin.plant.ast_render`), and
:meth:`gatetwin.mpc.loop.Scenario.schedules` switches its set-points and discharges by the
same rule (:func:`in_force`). Keep to the subset ``ast_render`` translates.
"""

from __future__ import annotations

import math

__all__ = ["RENDERED_C", "TIME_TOL_S", "in_force", "signal_value"]

#: The functions rendered into the scenario FMU's generated ``signal_law.c`` (prefix ``gt_``).
RENDERED_C = ("in_force", "signal_value")
#: A knot at ``time_s[k]`` is in force from the first time ``t`` with ``time_s[k] <= t +
#: TIME_TOL_S * max(1, |t|)``: relative, so a knot scheduled on a communication point is
#: reached whether the point is formed as ``k h`` or as a running sum of ``h`` (which lags
#: ``k h`` by a few ulps per step: ~1e-11 relative after 10^5 steps).
TIME_TOL_S = 1e-9


def in_force(knot_s: float, time_s: float, tolerance_s: float) -> float:
    """1.0 if a knot at ``knot_s`` is in force at ``time_s`` (the module's rule), else 0.0."""
    if knot_s <= time_s + tolerance_s * max(1.0, math.fabs(time_s)):
        return 1.0
    return 0.0


def signal_value(
    time_s: float,
    times_s: list[float],
    values: list[float],
    count: int,
    linear: float,
    tolerance_s: float,
) -> float:
    """The signal of ``count`` knots ``(times_s[k], values[k])`` (times increasing strictly)
    at ``time_s``.

    Piecewise constant (``linear`` = 0): ``values[k]`` from its knot on (:func:`in_force`).
    Linear (``linear`` = 1): interpolated between neighbouring knots, each knot's value from
    the knot on. Before the first knot the first value, after the last the last.
    """
    value = values[0]
    for k in range(count - 1):
        if in_force(times_s[k + 1], time_s, tolerance_s) > 0.0:
            value = values[k + 1]
        elif linear > 0.0 and times_s[k] <= time_s:
            fraction = (time_s - times_s[k]) / (times_s[k + 1] - times_s[k])
            value = values[k] + (values[k + 1] - values[k]) * fraction
    return value
