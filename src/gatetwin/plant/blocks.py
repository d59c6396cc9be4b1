"""Arithmetic kernels of the effect blocks, shared by the reference simulator and the FMUs.

Standard library only (``math``), no gatetwin imports: the pythonfmu slave embeds this module's
source verbatim at export (:mod:`gatetwin.fmu.python_build`), the diagnosis' fast simulator
compiles these functions with numba (:mod:`gatetwin.diagnosis.grid_sim`), and the C FMU's
``blocks.c`` is generated from their syntax tree (:mod:`gatetwin.plant.ast_render`), so the
Python reference (:mod:`gatetwin.plant.simulate`), both FMUs and the fast simulator run the very
same operations (the C FMU with the C library's ``exp``, ``log``, ``sin``, ...: on one platform
the very functions Python's ``math`` calls). Keep to the subset
``ast_render`` translates (scalar arithmetic, ``math`` functions, ``if``/``while``, early
returns, ``for i in range(n)`` over arrays passed in: ``list[float]`` arguments, written in
place, with ``int`` counts; calls of the other rendered functions of numbers).

What the blocks mean (inputs, outputs, parameters, state) is documented in
:mod:`gatetwin.plant.effects`; this module only advances them. The ARX family's sample
(:func:`arx_sample`, :func:`arx_equilibrium`, and for the envelope form
:func:`arx_envelope_coefficients`) lives here too, for the same renderings.
"""

from __future__ import annotations

import math

__all__ = [
    "RENDERED_C",
    "arx_envelope_coefficients",
    "arx_equilibrium",
    "arx_gain_rescaled",
    "arx_pole_scaled",
    "arx_sample",
    "first_order",
    "first_order_decay",
    "flow_scaled",
    "gain_map",
    "gain_map_inverse",
    "grid_index_at_or_after",
    "lag_interval",
    "move_toward",
    "play",
    "relax",
    "seiche_advance",
    "seiche_equilibrium",
    "seiche_output",
]

#: The functions rendered into the C FMU's generated ``blocks.c`` (prefix ``gt_``).
RENDERED_C = ("move_toward", "play", "gain_map", "gain_map_inverse", "flow_scaled",
              "first_order_decay", "relax", "first_order", "seiche_advance",
              "seiche_equilibrium", "seiche_output", "lag_interval",
              "grid_index_at_or_after", "arx_pole_scaled", "arx_gain_rescaled",
              "arx_envelope_coefficients", "arx_sample", "arx_equilibrium")  # fmt: skip


def move_toward(position_mm: float, command_mm: float, max_travel_mm: float) -> float:
    """Rate-limited actuator: move at most ``max_travel_mm`` toward ``command_mm``."""
    diff = command_mm - position_mm
    if diff > max_travel_mm:
        return position_mm + max_travel_mm
    if diff < -max_travel_mm:
        return position_mm - max_travel_mm
    return command_mm


def play(gate_mm: float, actuator_mm: float, deadband_mm: float) -> float:
    """Backlash (play operator) for an actuator that moved monotonically to ``actuator_mm``.

    The gate stays put while the actuator is inside the band ``gate ± deadband/2`` and is
    dragged along at the band's edge once it leaves it.
    """
    half = 0.5 * deadband_mm
    if actuator_mm - gate_mm > half:
        return actuator_mm - half
    if actuator_mm - gate_mm < -half:
        return actuator_mm + half
    return gate_mm


def gain_map(deviation_mm: float, slope_per_mm: float) -> float:
    """Opening nonlinearity: ``expm1(s v) / s`` (``v`` for ``s = 0``), local gain ``exp(s v)``."""
    if slope_per_mm == 0.0:
        return deviation_mm
    return math.expm1(slope_per_mm * deviation_mm) / slope_per_mm


def gain_map_inverse(effective_mm: float, slope_per_mm: float) -> float:
    """Inverse of :func:`gain_map` (``log1p(s u) / s``); NaN outside the map's range."""
    if slope_per_mm == 0.0:
        return effective_mm
    arg = slope_per_mm * effective_mm
    if not arg > -1.0:
        return math.nan
    return math.log1p(arg) / slope_per_mm


def flow_scaled(value: float, slope_per_m3h: float, flow_m3h: float, flow_ref_m3h: float
                ) -> float:  # fmt: skip
    """Flow-dependent gain block: ``value * exp(slope * (Q - Q_ref))``."""
    return value * math.exp(slope_per_m3h * (flow_m3h - flow_ref_m3h))


def arx_pole_scaled(a1: float, time_constant_ref_s: float, time_constant_s: float) -> float:
    """An envelope ARX's pole where the pool's time constant is ``time_constant_s``: the pole
    ``a1`` identified where it was ``time_constant_ref_s``, with time stretched by their
    ratio (``a1 = exp(-Ts/tau)`` keeps its ``tau / T`` across the envelope).

    The ratio's time constants are the kernel's analytic ones (no difference magnifies an ulp
    into them); binaries whose C libraries round ``pow`` differently stay within the 1e-9 mm
    of ``tests/fmu/test_fmu_platforms.py``."""
    return math.pow(a1, time_constant_ref_s / time_constant_s)


def arx_gain_rescaled(b: float, a1: float, a1_scaled: float) -> float:
    """An envelope ARX's input coefficient at the scaled pole: unit steady gain is kept, so
    the steady level stays the gate law's."""
    return b * (1.0 - a1_scaled) / (1.0 - a1)


def arx_envelope_coefficients(
    a: list[float], b: list[float], a_now: list[float], b_now: list[float], nb: int,
    time_constant_ref_s: float, time_constant_s: float,
) -> float:  # fmt: skip
    """An envelope ARX's coefficients where the pool's time constant is ``time_constant_s``:
    ``a_now[0]`` the pole ``a[0]`` scaled (:func:`arx_pole_scaled`), ``b_now[j]`` the ``b[j]``
    rescaled to it (:func:`arx_gain_rescaled`). Returns the scaled pole. (Calls the two
    blocks, so numba compiles it only with them compiled.)"""
    a_now[0] = arx_pole_scaled(a[0], time_constant_ref_s, time_constant_s)
    for j in range(nb):
        b_now[j] = arx_gain_rescaled(b[j], a[0], a_now[0])
    return a_now[0]


def arx_sample(
    x_hist: list[float], u_hist: list[float], a: list[float], b: list[float], u: float,
    na: int, nb: int, nk: int,
) -> float:  # fmt: skip
    """One sample of ARX(na, nb, nk), paper's sign convention:
    ``x(k) = sum_i a_i x(k-i) + sum_j b_j u(k-nk-j+1)`` (``i``, ``j`` from 1).

    ``u`` is ``u(k-1)``, the input held over the sample. On entry ``x_hist[i]`` holds
    ``x(k-1-i)`` (``na`` values) and ``u_hist[m]`` holds ``u(k-2-m)`` (``nk + nb - 1``
    values); both are shifted in place by one sample (``x_hist[0] = x(k)``,
    ``u_hist[0] = u``). Returns ``x(k)``; the sums run left to right from 0.
    """
    for m in range(nk + nb - 2):
        u_hist[nk + nb - 2 - m] = u_hist[nk + nb - 3 - m]
    u_hist[0] = u
    x = 0.0
    for i in range(na):
        x += a[i] * x_hist[i]
    for j in range(nb):
        x += b[j] * u_hist[nk - 1 + j]
    for i in range(na - 1):
        x_hist[na - 1 - i] = x_hist[na - 2 - i]
    x_hist[0] = x
    return x


def arx_equilibrium(a: list[float], b: list[float], u: float, na: int, nb: int
                    ) -> tuple[float, float]:  # fmt: skip
    """The sum of the ``a`` coefficients, and the state at rest under the held input ``u``:
    ``sum(b) / (1 - sum(a)) * u`` (NaN where ``sum(a)`` is 1: no rest state). Sums run left
    to right from 0."""
    sum_a = 0.0
    for i in range(na):
        sum_a += a[i]
    sum_b = 0.0
    for j in range(nb):
        sum_b += b[j]
    if sum_a == 1.0:
        return sum_a, math.nan
    return sum_a, sum_b / (1.0 - sum_a) * u


def first_order_decay(duration_s: float, time_constant_s: float) -> float:
    """The fraction of a first-order deviation left after ``duration_s``; it depends on the
    duration and the time constant alone, so a caller whose steps repeat may keep it."""
    return math.exp(-duration_s / time_constant_s)


def relax(state: float, target: float, decay: float) -> float:
    """A first-order state relaxed toward a constant ``target``, ``decay`` of its deviation
    left (:func:`first_order_decay`)."""
    return target + (state - target) * decay


def first_order(state: float, target: float, duration_s: float, time_constant_s: float) -> float:
    """Exact first-order relaxation toward a constant ``target`` over ``duration_s``. (Calls
    two blocks, so numba compiles it only with them compiled.)"""
    return relax(state, target, first_order_decay(duration_s, time_constant_s))


def seiche_advance(
    x1: float, x2: float, drive_mm: float, duration_s: float, period_s: float, decay_time_s: float
) -> tuple[float, float]:
    """Exact advance of ``x1' = x2, x2' = -w0^2 x1 - 2 sigma x2 + v`` with ``v`` held.

    ``w = 2 pi / period``, ``sigma = 1 / decay_time``, ``w0^2 = sigma^2 + w^2``; the block's
    output is ``amplitude * w * x2`` (:func:`seiche_output`).
    """
    w = 2.0 * math.pi / period_s
    sigma = 1.0 / decay_time_s
    w0_sq = sigma * sigma + w * w
    p = x1 - drive_mm / w0_sq
    envelope = math.exp(-sigma * duration_s)
    c = math.cos(w * duration_s)
    s = math.sin(w * duration_s) / w
    p_new = envelope * ((c + sigma * s) * p + s * x2)
    q_new = envelope * (-w0_sq * s * p + (c - sigma * s) * x2)
    return p_new + drive_mm / w0_sq, q_new


def seiche_equilibrium(drive_mm: float, period_s: float, decay_time_s: float) -> float:
    """``x1`` at rest for a held drive ``v`` (``x2 = 0``, output 0)."""
    w = 2.0 * math.pi / period_s
    sigma = 1.0 / decay_time_s
    return drive_mm / (sigma * sigma + w * w)


def seiche_output(x2: float, period_s: float, amplitude_mm_per_mm: float) -> float:
    """Seiche contribution to the level, mm."""
    return amplitude_mm_per_mm * (2.0 * math.pi / period_s) * x2


def lag_interval(
    sensed_mm: float,
    level_target_mm: float,
    level_excess_mm: float,
    duration_s: float,
    level_time_constant_s: float,
    lag_s: float,
) -> float:
    """Exact sensor lag ``z' = (w - z) / lag`` over an interval where the level is
    ``w(s) = level_target + level_excess * exp(-s / level_time_constant)``.

    ``z(d) = A + (z0 - A) e^(-d/lag) + B phi(d)`` with ``A`` the target, ``B`` the excess and
    ``phi(d) = beta (e^(-alpha d) - e^(-beta d)) / (beta - alpha)``, ``alpha = 1/T``,
    ``beta = 1/lag``, evaluated without cancellation.
    """
    alpha = 1.0 / level_time_constant_s
    beta = 1.0 / lag_s
    lo = alpha if alpha < beta else beta
    gap = (beta - alpha) if beta > alpha else (alpha - beta)
    if gap == 0.0:
        phi = beta * duration_s * math.exp(-lo * duration_s)
    else:
        phi = beta * math.exp(-lo * duration_s) * (-math.expm1(-gap * duration_s)) / gap
    decay = math.exp(-beta * duration_s)
    return level_target_mm + (sensed_mm - level_target_mm) * decay + level_excess_mm * phi


def grid_index_at_or_after(time_s: float, origin_s: float, step_s: float) -> int:
    """Index ``k`` of the first grid point ``origin + k * step`` that is ``>= time_s``."""
    k = max(math.ceil((time_s - origin_s) / step_s), 0)
    while k > 0 and origin_s + (k - 1) * step_s >= time_s:
        k -= 1
    while origin_s + k * step_s < time_s:
        k += 1
    return k
