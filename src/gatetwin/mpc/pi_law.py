"""The PI controller's arithmetic for one sample, written once.

Standard library only and no gatetwin imports: :class:`gatetwin.mpc.pi.PiController` calls
:func:`pi_step`, and the C controller FMU's ``pi_law.c`` is generated from this module's
syntax tree (:mod:`gatetwin.plant.ast_render`), so the Python loop and the FMU perform the
same operations in the same order. Keep to the subset ``ast_render`` translates (scalar
arithmetic, ``max``/``min`` of two values, ``if``, early returns).

What the law means (positional PI on the level error, rate and range limits on the opening,
back-calculation anti-windup) is documented in :mod:`gatetwin.mpc.pi`; this module only
advances it.
"""

from __future__ import annotations

__all__ = ["RENDERED_C", "pi_step"]

#: The functions rendered into the C controller FMU's generated ``pi_law.c`` (prefix ``gt_``).
RENDERED_C = ("pi_step",)


def pi_step(
    level_mm: float,
    setpoint_mm: float,
    integral_mm: float,
    previous_opening_mm: float,
    filtered_mm: float,
    gain_mm_per_mm: float,
    integral_time_s: float,
    tracking_time_s: float,
    opening_min_mm: float,
    opening_max_mm: float,
    opening_rate_mm_s: float,
    sample_period_s: float,
    filter_time_s: float,
) -> tuple[float, float, float]:
    """One sample of the PI: ``(opening_mm, integral_mm, filtered_mm)`` after it.

    The level is first filtered, ``y += Ts / (Tf + Ts) · (level − y)`` (the backward-Euler
    first-order filter of time constant ``Tf``; ``Tf = 0``: the level itself). Then ``wanted
    = Kc e + I`` with ``e = setpoint − y``; the opening is ``wanted`` clipped to ``previous ±
    rate · Ts``, then to ``[opening_min, opening_max]``; the integral moves by ``Kc Ts / Ti ·
    e + Ts / Tt · (opening − wanted)`` (back-calculation). Units: mm, s, mm/s, mm/mm.
    """
    filtered = level_mm
    if filter_time_s > 0.0:
        filtered = filtered_mm + sample_period_s / (filter_time_s + sample_period_s) * (
            level_mm - filtered_mm
        )
    error = setpoint_mm - filtered
    wanted = gain_mm_per_mm * error + integral_mm
    travel = opening_rate_mm_s * sample_period_s
    opening = min(max(wanted, previous_opening_mm - travel), previous_opening_mm + travel)
    opening = min(max(opening, opening_min_mm), opening_max_mm)
    integral = integral_mm + (
        gain_mm_per_mm * sample_period_s / integral_time_s * error
        + sample_period_s / tracking_time_s * (opening - wanted)
    )
    return opening, integral, filtered
