"""The value of a tabulated signal at a time, written once.

Standard library only and no gatetwin imports: the scenario FMU of an SSP
(:mod:`gatetwin.fmu.signal_source`) computes its outputs with ``signal_value.c``, generated
from this module's syntax tree (:mod:`gatetwin.plant.ast_render`), and the tests' reference
reads the same tables with :func:`signal_value` itself. Keep to the subset ``ast_render``
translates.
"""

from __future__ import annotations

#: The functions rendered into the scenario FMU's generated ``signal_value.c`` (prefix
#: ``gt_``).
RENDERED_C = ("signal_value",)
#: A knot at ``time_s[k]`` is in force from the first time not before ``time_s[k] -
#: TIME_TOL_S`` (the rule of :meth:`gatetwin.mpc.loop.Scenario.schedules`: a change scheduled
#: at a communication point computed as a running sum still lands on that point).
TIME_TOL_S = 1e-9


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

    Piecewise constant (``linear`` = 0): ``values[k]`` from ``times_s[k] - tolerance_s`` on.
    Linear (``linear`` = 1): interpolated between neighbouring knots, the knot's value from
    ``times_s[k] - tolerance_s`` on. Before the first knot the first value, after the last
    the last.
    """
    value = values[0]
    for k in range(count - 1):
        if times_s[k + 1] <= time_s + tolerance_s:
            value = values[k + 1]
        elif linear > 0.0 and times_s[k] <= time_s:
            fraction = (time_s - times_s[k]) / (times_s[k + 1] - times_s[k])
            value = values[k] + (values[k + 1] - values[k]) * fraction
    return value
