"""Arithmetic of the ``physical`` family, written once for every rendering.

The pool upstream of the gate is one storage area fed by the measured inflow and drained by
the gate law, behind an actuator that moves at a speed falling with the water load:

    A(h) dh/dt = Q_in/3600 − Q_g(h, e, Q_in)                    (h: depth at the gate, m)
    Q_g = min(Cd(e/h, Q_in) · b · e · √(2 g h),  b · √g · (2h/3)^1.5)    (m³/s; e in m)
    Cd  = c∞ + (c₀ − c∞) / (1 + exp((ln r − m)/w))^ν             (r = e/h; c₀, c∞, m, ln w
                                                                   linear in (Q − Q_c)/Q_s)
    A(h) = max(A₀ + A₁ (h − 0.2 m), 0.05 m²)
    level at the gauge = 1000 h − o₀ − o₂ (3600 Q_g / Q_s)²      (mm; Q_g in units of Q_s)

The discharge's centre ``Q_c`` and scale ``Q_s`` (m³/h) are parameters fixed at
identification from the data's own discharge range (see :mod:`gatetwin.identify.physical`),
so the coefficients are of order one at any gate size. The steady depth is found by bisection
on ``[DEPTH_LOW_M, depth_max_m]``, the upper end a parameter too (a lab flume and a canal pool
differ by an order of magnitude in depth).

The discharge coefficient falls from its small-opening value c₀ towards c∞ as the opening
grows relative to the depth, with a logistic in ln r; the critical-flow cap is the gate lifted
clear of the water. The offset carries the gauge's datum and bed slope (o₀) and the friction
and velocity-head difference between gauge and gate, which grows with the square of the
discharge passing the gate (o₂).

The actuator moves the gate towards the command (rounded to its resolution) at
``v₀ · max(0.05, 1 − (h/h_stall)²)`` mm/s. One sub-step of ``dt`` seconds moves the gate
linearly in time (explicit in the speed), and integrates the storage equation with one
classical Runge–Kutta step that sees the gate moving.

Every function here is plain scalar arithmetic on the helpers below, with the standard library
only and no gatetwin imports. Renderings derive from this source, none restate it:

* the Python simulator (:mod:`gatetwin.plant.physical`) calls it as it is;
* the pythonfmu slave embeds this file verbatim at export;
* :mod:`gatetwin.plant.kernel_render` rebinds the helpers to numba (identification), CasADi
  (the MPC's symbolic model) and a C emitter that writes the C FMU's ``physical_kernel.c``.

Parameters are one flat sequence ``p`` in the order of :data:`PARAMETERS`.
"""

from __future__ import annotations

import math

#: The parameter vector, in order: (name, unit, description).
PARAMETERS = (
    ("cd_small", "1", "Cd at small openings (c0) at Q = flow_centre_m3h"),
    ("cd_small_per_q", "1", "change of c0 per flow_scale_m3h"),
    ("cd_large", "1", "Cd at large openings (c_inf) at Q = flow_centre_m3h"),
    ("cd_large_per_q", "1", "change of c_inf per flow_scale_m3h"),
    ("cd_mid_log_ratio", "1", "ln(e/h) at the middle of the Cd transition (m) at Q_c"),
    ("cd_mid_per_q", "1", "change of m per flow_scale_m3h"),
    ("cd_log_width", "1", "ln of the transition width w in ln(e/h), at Q = flow_centre_m3h"),
    ("cd_log_width_per_q", "1", "change of ln w per flow_scale_m3h"),
    ("cd_log_shape", "1", "ln of the transition's asymmetry exponent nu"),
    ("width_m", "m", "Channel width at the gate, b"),
    ("offset_mm", "mm", "Depth at the gate minus level at the gauge at zero discharge, o0"),
    ("offset_per_flow2_mm", "mm", "Offset growth with (gate discharge / flow_scale_m3h)^2, o2"),
    ("area_m2", "m2", "Effective storage area of the pool at 0.2 m depth, A0"),
    ("area_per_depth_m", "m", "Change of the storage area per metre of depth, A1 (m2/m)"),
    ("speed_mm_s", "mm/s", "Actuator speed without water load, v0"),
    ("stall_depth_m", "m", "Depth at the gate at which the actuator would stall, h_stall"),
    ("resolution_mm", "mm", "Actuator position resolution: the command is rounded to it"),
    ("max_substep_s", "s", "Longest integration sub-step"),
    ("flow_centre_m3h", "m3/h", "Discharge at which the Cd coefficients hold, Q_c"),
    ("flow_scale_m3h", "m3/h", "Discharge unit of the Cd slopes and of o2, Q_s"),
    ("depth_max_m", "m", "Upper end of the steady-depth bisection bracket"),
)
N_PARAMETERS = len(PARAMETERS)
#: Index of each parameter in ``p``.
INDEX = {name: i for i, (name, _, _) in enumerate(PARAMETERS)}

G = 9.81
#: Depth about which the storage area is linear, m.
AREA_DEPTH_REF_M = 0.2
#: Smallest storage area, m² (keeps the equation well posed for any parameter).
AREA_MIN_M2 = 0.05
#: Smallest depth the gate law sees, m, and smallest opening ratio.
DEPTH_MIN_M = 1e-4
RATIO_MIN = 1e-6
#: The actuator never slows below this fraction of its no-load speed.
SPEED_FLOOR = 0.05
#: Lower end and iteration count of the steady-depth bisection (the upper end is the
#: parameter ``depth_max_m``; 2 m / 2^44 = 1.1e-13 m, 32 m / 2^44 = 1.8e-12 m).
DEPTH_LOW_M = 1e-4
BISECTION_STEPS = 44
#: Index of the bracket's upper end in ``p``.
DEPTH_MAX_INDEX = 20
#: Half-width of the central difference of the gate law in the depth, m.
DEPTH_DIFFERENCE_M = 1e-6


# -- helpers every rendering rebinds -------------------------------------------------------------
def fmin(a: float, b: float) -> float:
    return a if a < b else b


def fmax(a: float, b: float) -> float:
    return a if a > b else b


def less(a: float, b: float) -> bool:
    return a < b


def select(condition: bool, if_true: float, if_false: float) -> float:
    return if_true if condition else if_false


sqrt = math.sqrt
exp = math.exp
log = math.log
floor = math.floor


# -- the model -----------------------------------------------------------------------------------
def discharge_coefficient(ratio: float, flow_m3h: float, p: list[float]) -> float:
    """Cd at opening ratio ``e/h`` and discharge ``flow_m3h``."""
    # written as Q/Q_s − Q_c/Q_s: with Q_s a power of ten the same arithmetic at any scale
    qq = flow_m3h / p[19] - p[18] / p[19]
    c_small = p[0] + p[1] * qq
    c_large = p[2] + p[3] * qq
    middle = p[4] + p[5] * qq
    width = exp(p[6] + p[7] * qq)
    shape = exp(p[8])
    z = (log(fmax(ratio, RATIO_MIN)) - middle) / width
    return c_large + (c_small - c_large) * exp(-shape * log(1.0 + exp(z)))


def gate_flow_m3s(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Discharge under the gate, m³/s (free underflow, capped at critical flow)."""
    h = fmax(depth_m, DEPTH_MIN_M)
    e = fmax(opening_mm, 0.0) / 1000.0
    cd = discharge_coefficient(e / h, flow_m3h, p)
    free = cd * p[9] * e * sqrt(2.0 * G * h)
    critical = p[9] * sqrt(G) * 0.5443310539518174 * h * sqrt(h)  # (2/3)^1.5 h^1.5
    return fmin(free, critical)


def storage_area_m2(depth_m: float, p: list[float]) -> float:
    return fmax(p[12] + p[13] * (depth_m - AREA_DEPTH_REF_M), AREA_MIN_M2)


def depth_rate(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """dh/dt, m/s."""
    net = flow_m3h / 3600.0 - gate_flow_m3s(depth_m, opening_mm, flow_m3h, p)
    return net / storage_area_m2(depth_m, p)


def actuator_target_mm(command_mm: float, p: list[float]) -> float:
    """The command rounded to the actuator's resolution."""
    return p[16] * floor(command_mm / p[16] + 0.5)


def actuator_speed_mm_s(depth_m: float, p: list[float]) -> float:
    load = depth_m / p[15]
    return p[14] * fmax(SPEED_FLOOR, 1.0 - load * load)


def substep(
    depth_m: float, gate_mm: float, target_mm: float, flow_m3h: float, dt_s: float,
    p: list[float],
) -> tuple[float, float]:  # fmt: skip
    """Depth and gate position after ``dt_s`` with the target and the inflow held."""
    travel = actuator_speed_mm_s(depth_m, p) * dt_s
    gate_end = gate_mm + fmax(-travel, fmin(travel, target_mm - gate_mm))
    gate_mid = 0.5 * (gate_mm + gate_end)
    k1 = depth_rate(depth_m, gate_mm, flow_m3h, p)
    k2 = depth_rate(depth_m + 0.5 * dt_s * k1, gate_mid, flow_m3h, p)
    k3 = depth_rate(depth_m + 0.5 * dt_s * k2, gate_mid, flow_m3h, p)
    k4 = depth_rate(depth_m + dt_s * k3, gate_end, flow_m3h, p)
    depth_end = depth_m + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return depth_end, gate_end


def bisection_step(
    low_m: float, high_m: float, opening_mm: float, flow_m3h: float, p: list[float]
) -> tuple[float, float]:
    """One halving of the bracket of the steady depth (the gate passes the inflow)."""
    middle = 0.5 * (low_m + high_m)
    below = less(gate_flow_m3s(middle, opening_mm, flow_m3h, p), flow_m3h / 3600.0)
    return select(below, middle, low_m), select(below, high_m, middle)


def level_mm(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Level at the gauge, mm, for a depth at the gate and the gate's position."""
    passing = gate_flow_m3s(depth_m, opening_mm, flow_m3h, p) * (3600.0 / p[19])
    return 1000.0 * depth_m - p[10] - p[11] * passing * passing


def time_constant_s(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Small-signal time constant at a steady point: storage area over ∂Q_g/∂h, s.

    The envelope FOPDT relaxes towards the steady level with this time constant; it is the
    storage equation linearised at (h, e, Q) (∂Q_g/∂h by a central difference).
    """
    d = DEPTH_DIFFERENCE_M
    upper = gate_flow_m3s(depth_m + d, opening_mm, flow_m3h, p)
    lower = gate_flow_m3s(depth_m - d, opening_mm, flow_m3h, p)
    # a closed gate passes nothing at any depth: no finite time constant (the floor keeps the
    # division defined; the level then barely moves)
    return storage_area_m2(depth_m, p) * (2.0 * d) / fmax(upper - lower, 1e-15)


def substep_count(step_s: float, p: list[float]) -> float:
    """Sub-steps of one communication step: the fewest of at most ``max_substep_s``."""
    return fmax(1.0, -floor(-step_s / p[17]))


#: The functions rendered into C, with their argument names (``p`` last) and output count.
RENDERED = (
    ("substep", ("depth_m", "gate_mm", "target_mm", "flow_m3h", "dt_s"), 2),
    ("bisection_step", ("low_m", "high_m", "opening_mm", "flow_m3h"), 2),
    ("level_mm", ("depth_m", "opening_mm", "flow_m3h"), 1),
    ("actuator_target_mm", ("command_mm",), 1),
    ("substep_count", ("step_s",), 1),
    ("time_constant_s", ("depth_m", "opening_mm", "flow_m3h"), 1),
)
