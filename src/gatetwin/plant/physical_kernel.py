"""Arithmetic of the ``physical`` family, written once for every rendering.

The pool upstream of the gate is one storage area fed by the measured inflow and drained by
the gate law, behind an actuator that moves at a speed falling with the water load:

    A(h) dh/dt = Q_in/3600 − Q_g(h, h_t, e, Q_in)               (h: depth at the gate, m)
    Q_g = min(Cd(e/h, Q_in) · b · e · √(2 g (h − t)),  b · √g · (2h/3)^1.5)    (m³/s; e in m)
    Cd  = c∞ + (c₀ − c∞) / (1 + exp((ln r − m)/w))^ν             (r = e/h; c₀, c∞, m, ln w
                                                                   linear in (Q − Q_c)/Q_s)
    A(h) = max(A₀ + A₁ (h − 0.2 m), 0.05 m²)
    level at the gauge = 1000 h − o₀ − o₂ (3600 Q_g / Q_s)²      (mm; Q_g in units of Q_s)
    with a floor:  ½ (L + F + √((L − F)² + 4 s²)),  F = F_c + F₁ (Q_in − Q_c)/Q_s

The tailwater ``t`` is 0 (free underflow) unless the model has a pool below the gate
(``tail_area_m2 > 0``): then the gate discharges into it, ``t = max(h_t, e/2)`` (the orifice's
centre while the jet is free), and the pool's depth ``h_t`` above the sill follows

    A_t dh_t/dt = Q_g − Q_c/3600 · ((h_t − z) / (h_c − z))^β     (0 below its datum z)

whose steady depth at the discharge Q is ``z + (h_c − z) (Q/Q_c)^(1/β)``: ``h_c`` the tail
depth at the discharge centre, ``β`` the exponent of the outlet below (½ an orifice, 1.5 a weir,
about 5/3 a long channel at normal depth). A submerged gate answers with the tail pool's
slower mode too. The steady functions (depth, level, time constant) see the tail pool at its
steady depth for the inflow.

The discharge's centre ``Q_c`` and scale ``Q_s`` (m³/h) are parameters fixed at
identification from the data's own discharge range (see :mod:`gatetwin.identification.physical`),
so the coefficients are of order one at any gate size. The steady depth is found by Newton's
method on the gate law with its own slope, from the orifice law's depth, inside the bracket
``[DEPTH_LOW_M, depth_max_m]`` (the upper end a parameter too: a lab flume and a canal pool
differ by an order of magnitude in depth), which a step halves where Newton's would leave it
or stall (:func:`held_steady_depth_m`).

The discharge coefficient falls from its small-opening value c₀ towards c∞ as the opening
grows relative to the depth, with a logistic in ln r; the critical-flow cap is the gate lifted
clear of the water. The offset carries the gauge's datum and bed slope (o₀) and the friction
and velocity-head difference between gauge and gate, which grows with the square of the
discharge passing the gate (o₂). A gauge far up the pool has a floor too (``floor_smooth_mm >
0``): when the gate draws the pool down at a low inflow, the water there stops following the
gate and runs at about its channel's own depth for the inflow, F (linear in the discharge over
the data's range), and the level passes from the pool's to the floor over a few ``s``.

The actuator moves the gate towards the command (rounded to its resolution) at
``v₀ · max(0.05, 1 − (h/h_stall)²)`` mm/s. One sub-step of ``dt`` seconds moves the gate
linearly in time (explicit in the speed), and integrates the storage equation with one
classical Runge–Kutta step that sees the gate moving.

Every function here is plain scalar arithmetic on the helpers below, with the standard library
only and no gatetwin imports. Renderings derive from this source, none restate it:

* the Python simulator (:mod:`gatetwin.plant.physical`) calls it as it is;
* the pythonfmu slave embeds this file verbatim at export;
* :mod:`gatetwin.plant.kernel_render` rebinds the helpers to numba (identification) and a C
  emitter that writes the C FMU's ``physical_kernel.c``.

Parameters are one flat sequence ``p`` in the order of :data:`PARAMETERS`.
"""

from __future__ import annotations

import math

__all__ = [
    "AREA_DEPTH_REF_M",
    "AREA_MIN_M2",
    "BISECTION_STEPS",
    "DEPTH_DIFFERENCE_M",
    "DEPTH_LOW_M",
    "DEPTH_MAX_INDEX",
    "DEPTH_MIN_M",
    "G",
    "INDEX",
    "N_PARAMETERS",
    "PARAMETERS",
    "RATIO_MIN",
    "RENDERED",
    "SLOPE_MIN_M2S",
    "SPEED_FLOOR",
    "STEADY_MAX_STEPS",
    "TAIL_EXPONENT_MIN",
    "CdLaw",
    "actuator_speed_mm_s",
    "actuator_target_mm",
    "cd_law",
    "depth_rates",
    "exp",
    "floor",
    "fmax",
    "fmin",
    "gate_flow_m3s",
    "gate_flow_slopes",
    "has_floor",
    "has_tail",
    "held_steady_depth_m",
    "law_gate_flow_m3s",
    "law_gate_flow_slopes",
    "law_gate_terms",
    "law_newton_step",
    "law_terms_slopes",
    "less",
    "level_mm",
    "log",
    "operating_room_m2",
    "pool_depth_m",
    "pool_time_constant_s",
    "secant_time_constant_s",
    "select",
    "sqrt",
    "steady_depth_m",
    "steady_depth_start_m",
    "storage_area_m2",
    "storage_room_m2",
    "substep",
    "substep_count",
    "tail_outflow_m3s",
    "tail_outflow_slope_m2s",
    "tail_pool_piece",
    "tail_secant_time_constant_s",
    "tail_steady_m",
    "time_constant_s",
]

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
    ("depth_max_m", "m", "Upper end of the steady-depth bracket"),
    ("tail_area_m2", "m2", "Storage area of the pool below the gate, A_t; 0: free underflow"),
    ("tail_depth_m", "m", "Steady depth of the pool below the gate at Q = flow_centre_m3h, h_c"),
    ("tail_datum_m", "m", "Depth of the pool below the gate at which its outflow stops, z"),
    ("tail_exponent", "1", "Exponent of the outflow of the pool below the gate in its depth"),
    (
        "floor_mm",
        "mm",
        "Level the gauge stays above at Q = flow_centre_m3h (the channel's own "
        "depth for the discharge, where the gate's pool no longer reaches), F",
    ),
    ("floor_per_q_mm", "mm", "change of F per flow_scale_m3h"),
    ("floor_smooth_mm", "mm", "Level above F where the pool meets the floor, s; 0: no floor"),
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
#: Lower end of the steady depth's bracket (the upper end is the parameter ``depth_max_m``),
#: and the halvings that bring the bracket to the solve's tolerance (its width / 2^44:
#: 2 m / 2^44 = 1.1e-13 m, 32 m / 2^44 = 1.8e-12 m).
DEPTH_LOW_M = 1e-4
BISECTION_STEPS = 44
#: Most steps of the steady-depth solve: a Newton step is taken only where it lands inside
#: the bracket and at most half as long as the step before it, else the bracket is halved,
#: so the steps shrink to the tolerance within about twice the halvings whatever the law.
STEADY_MAX_STEPS = 2 * BISECTION_STEPS
#: Index of the bracket's upper end in ``p``.
DEPTH_MAX_INDEX = 20
#: Smallest exponent of the tail pool's outflow (keeps its steady depth defined).
TAIL_EXPONENT_MIN = 0.05
#: Depth gap below which the envelope's secant is the tangent (the gap is not resolved), m.
DEPTH_DIFFERENCE_M = 1e-6
#: Smallest slope of a discharge in a depth the time constants divide by, m²/s (a closed gate
#: passes nothing at any depth; the floor keeps the division defined).
SLOPE_MIN_M2S = 5e-10


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
#: Cd's curve over the opening ratio at one discharge (:func:`cd_law`).
CdLaw = tuple[float, float, float, float, float]


def cd_law(flow_m3h: float, p: list[float]) -> CdLaw:
    """What Cd's curve over the opening ratio is at the discharge ``flow_m3h``: its small- and
    large-opening values, the middle and width of the transition, its shape (a solve at one
    discharge computes them once)."""
    # written as Q/Q_s − Q_c/Q_s: with Q_s a power of ten the same arithmetic at any scale
    qq = flow_m3h / p[19] - p[18] / p[19]
    c_small = p[0] + p[1] * qq
    c_large = p[2] + p[3] * qq
    middle = p[4] + p[5] * qq
    return c_small, c_large, middle, exp(p[6] + p[7] * qq), exp(p[8])


def has_tail(p: list[float]) -> bool:
    """Whether the gate discharges into a pool of its own (else free underflow)."""
    return less(0.0, p[21])


def tail_steady_m(flow_m3h: float, p: list[float]) -> float:
    """Steady depth of the pool below the gate at the discharge ``flow_m3h``, m (0: none)."""
    ratio = fmax(flow_m3h, 0.0) / p[18]
    power = exp(log(fmax(ratio, RATIO_MIN)) / fmax(p[24], TAIL_EXPONENT_MIN))
    return select(has_tail(p), p[23] + (p[22] - p[23]) * power, 0.0)


def tail_outflow_m3s(tail_m: float, p: list[float]) -> float:
    """Outflow of the pool below the gate, m³/s."""
    fraction = fmax(tail_m - p[23], 0.0) / fmax(p[22] - p[23], DEPTH_MIN_M)
    power = exp(fmax(p[24], TAIL_EXPONENT_MIN) * log(fmax(fraction, RATIO_MIN)))
    return select(less(RATIO_MIN, fraction), p[18] / 3600.0 * power, 0.0)


def tail_outflow_slope_m2s(tail_m: float, p: list[float]) -> float:
    """∂Q_t/∂h_t of :func:`tail_outflow_m3s`, m²/s."""
    span = fmax(p[22] - p[23], DEPTH_MIN_M)
    fraction = fmax(tail_m - p[23], 0.0) / span
    beta = fmax(p[24], TAIL_EXPONENT_MIN)
    power = exp(beta * log(fmax(fraction, RATIO_MIN)))
    slope = p[18] / 3600.0 * beta * power / fmax(fraction, RATIO_MIN) / span
    return select(less(RATIO_MIN, fraction), slope, 0.0)


def gate_flow_m3s(depth_m: float, tail_m: float, opening_mm: float, flow_m3h: float,
                  p: list[float]) -> float:  # fmt: skip
    """Discharge under the gate, m³/s (underflow against the tailwater, capped at critical)."""
    return law_gate_flow_m3s(depth_m, tail_m, opening_mm, cd_law(flow_m3h, p), p)


def law_gate_terms(depth_m: float, tail_m: float, opening_mm: float, law: CdLaw,
                   p: list[float]) -> tuple[float, float, float, float, float, float, float,
                                            float, float, float]:  # fmt: skip
    """The gate law's terms at a depth, with Cd's curve at the discharge given
    (:func:`cd_law`): the depth and opening it sees (m), Cd's logistic argument ``z``, its
    ``exp(z)`` and the logistic's share, Cd, the tailwater (m), ``√(2 g head)``, the free
    underflow and the critical-flow cap (m³/s). :func:`law_gate_flow_m3s` and
    :func:`law_gate_flow_slopes` are written on them."""
    c_small, c_large, middle, width, shape = law
    h = fmax(depth_m, DEPTH_MIN_M)
    e = fmax(opening_mm, 0.0) / 1000.0
    z = (log(fmax(e / h, RATIO_MIN)) - middle) / width
    grow = exp(z)
    share = exp(-shape * log(1.0 + grow))
    cd = c_large + (c_small - c_large) * share
    tailwater = select(has_tail(p), fmax(tail_m, 0.5 * e), 0.0)
    root = sqrt(2.0 * G * fmax(h - tailwater, 0.0))
    free = cd * p[9] * e * root
    critical = p[9] * sqrt(G) * 0.5443310539518174 * h * sqrt(h)  # (2/3)^1.5 h^1.5
    return h, e, z, grow, share, cd, tailwater, root, free, critical


def law_gate_flow_m3s(depth_m: float, tail_m: float, opening_mm: float,
                      law: CdLaw,
                      p: list[float]) -> float:  # fmt: skip
    """:func:`gate_flow_m3s` with Cd's curve at the discharge given (:func:`cd_law`)."""
    free, critical = law_gate_terms(depth_m, tail_m, opening_mm, law, p)[8:]
    return fmin(free, critical)


def gate_flow_slopes(depth_m: float, tail_m: float, opening_mm: float, flow_m3h: float,
                     p: list[float]) -> tuple[float, float]:  # fmt: skip
    """∂Q_g/∂h and ∂Q_g/∂h_t of :func:`gate_flow_m3s`, m²/s: its derivatives, written from the
    same law (where a bound of the law holds, the derivative of the bounded branch)."""
    return law_gate_flow_slopes(depth_m, tail_m, opening_mm, cd_law(flow_m3h, p), p)


def law_gate_flow_slopes(depth_m: float, tail_m: float, opening_mm: float, law: CdLaw,
                         p: list[float]) -> tuple[float, float]:  # fmt: skip
    """:func:`gate_flow_slopes` with Cd's curve at the discharge given (:func:`cd_law`)."""
    terms = law_gate_terms(depth_m, tail_m, opening_mm, law, p)
    return law_terms_slopes(terms, depth_m, tail_m, law, p)


def law_terms_slopes(terms: tuple[float, float, float, float, float, float, float, float,
                                  float, float],
                     depth_m: float, tail_m: float, law: CdLaw,
                     p: list[float]) -> tuple[float, float]:  # fmt: skip
    """:func:`law_gate_flow_slopes` from the law's terms at the depth
    (:func:`law_gate_terms`), which the caller has."""
    c_small, c_large, _, width, shape = law
    h, e, z, grow, share, cd, tailwater, root, free, critical = terms
    above = select(less(DEPTH_MIN_M, depth_m), 1.0, 0.0)  # d h / d depth
    # dCd/dh: through the logistic in ln r, r = e/h; grow / (1 + grow) written so that
    # neither arm overflows (exp(z) is inf for a large z in C and numba)
    lift = select(less(z, 0.0), grow / (1.0 + grow), 1.0 / (1.0 + exp(-fmax(z, 0.0))))
    dcd_dz = -(c_small - c_large) * shape * share * lift
    dcd_dh = select(less(RATIO_MIN, e / h), dcd_dz / width * (-1.0 / h), 0.0) * above
    # d tailwater / d h_t: 1 where the tail pool's depth is the tailwater
    drowning = select(has_tail(p), select(less(0.5 * e, tail_m), 1.0, 0.0), 0.0)
    # d sqrt(2 g head) / d head, 0 where the head is gone
    droot = select(less(0.0, h - tailwater), G / fmax(root, 1e-300), 0.0)
    free_h = p[9] * e * (dcd_dh * root + cd * droot * above)
    free_t = -p[9] * e * cd * droot * drowning
    critical_h = p[9] * sqrt(G) * 0.5443310539518174 * 1.5 * sqrt(h) * above
    below = less(free, critical)  # fmin(free, critical) is the free underflow
    return select(below, free_h, critical_h), select(below, free_t, 0.0)


def storage_area_m2(depth_m: float, p: list[float]) -> float:
    return fmax(p[12] + p[13] * (depth_m - AREA_DEPTH_REF_M), AREA_MIN_M2)


def pool_depth_m(level_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Depth at the gate of a steady pool whose gauge reads ``level_mm`` at ``flow_m3h`` (the
    pool term of :func:`level_mm` solved for the depth, the gate passing the inflow; the floor
    left out: at a floored gauge the pool may be lower), m."""
    passing = flow_m3h / p[19]
    return (level_mm + p[10] + p[11] * passing * passing) / 1000.0


def operating_room_m2(level_mm: float, flow_m3h: float, p: list[float]) -> float:
    """How far the linear storage area rises above its floor (``AREA_MIN_M2``) at the steady
    pool of :func:`pool_depth_m`, m²: where a model runs, this is positive, or the kernel runs
    on the floor instead of the fitted pool. The area is linear in depth and the depth in the
    level, so a level range's ends at a discharge range's ends bound it."""
    return p[12] + p[13] * (pool_depth_m(level_mm, flow_m3h, p) - AREA_DEPTH_REF_M) - AREA_MIN_M2


def storage_room_m2(p: list[float]) -> float:
    """How far the linear storage area ``A0 + A1 (h − 0.2 m)`` rises above its floor at the
    better end of the depths the model spans (``DEPTH_LOW_M`` .. ``depth_max_m``), m²: a model
    whose pool has no storage anywhere (this is not positive) is no model of a pool."""
    low = p[12] + p[13] * (DEPTH_LOW_M - AREA_DEPTH_REF_M)
    high = p[12] + p[13] * (p[20] - AREA_DEPTH_REF_M)
    return fmax(low, high) - AREA_MIN_M2


def depth_rates(depth_m: float, tail_m: float, opening_mm: float, flow_m3h: float,
                p: list[float]) -> tuple[float, float]:  # fmt: skip
    """dh/dt and dh_t/dt, m/s."""
    passing = gate_flow_m3s(depth_m, tail_m, opening_mm, flow_m3h, p)
    net = flow_m3h / 3600.0 - passing
    tail = (passing - tail_outflow_m3s(tail_m, p)) / fmax(p[21], AREA_MIN_M2)
    return net / storage_area_m2(depth_m, p), select(has_tail(p), tail, 0.0)


def actuator_target_mm(command_mm: float, p: list[float]) -> float:
    """The command rounded to the actuator's resolution."""
    return p[16] * floor(command_mm / p[16] + 0.5)


def actuator_speed_mm_s(depth_m: float, p: list[float]) -> float:
    load = depth_m / p[15]
    return p[14] * fmax(SPEED_FLOOR, 1.0 - load * load)


def substep(
    depth_m: float, tail_m: float, gate_mm: float, target_mm: float, flow_m3h: float,
    dt_s: float, p: list[float],
) -> tuple[float, float, float]:  # fmt: skip
    """Depth, tail depth and gate position after ``dt_s`` with the target and inflow held."""
    travel = actuator_speed_mm_s(depth_m, p) * dt_s
    gate_end = gate_mm + fmax(-travel, fmin(travel, target_mm - gate_mm))
    gate_mid = 0.5 * (gate_mm + gate_end)
    k1, l1 = depth_rates(depth_m, tail_m, gate_mm, flow_m3h, p)
    k2, l2 = depth_rates(depth_m + 0.5 * dt_s * k1, tail_m + 0.5 * dt_s * l1, gate_mid,
                         flow_m3h, p)  # fmt: skip
    k3, l3 = depth_rates(depth_m + 0.5 * dt_s * k2, tail_m + 0.5 * dt_s * l2, gate_mid,
                         flow_m3h, p)  # fmt: skip
    k4, l4 = depth_rates(depth_m + dt_s * k3, tail_m + dt_s * l3, gate_end, flow_m3h, p)
    depth_end = depth_m + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    tail_end = tail_m + dt_s / 6.0 * (l1 + 2.0 * l2 + 2.0 * l3 + l4)
    return depth_end, tail_end, gate_end


def law_newton_step(
    low_m: float, high_m: float, depth_m: float, step_m: float, tail_m: float,
    opening_mm: float, flow_m3h: float, c_small: float, c_large: float, middle: float,
    width: float, shape: float, p: list[float],
) -> tuple[float, float, float, float]:  # fmt: skip
    """One step of the solve for the depth at which the gate passes the inflow into the tail
    pool held at ``tail_m`` (Cd's curve at the discharge as :func:`cd_law` returns it): the
    bracket ``[low_m, high_m]`` narrowed by the side ``depth_m`` lies on, and the next depth:
    Newton's (the law's own slope, :func:`law_gate_flow_slopes`) where it lands inside the
    bracket and is at most half as long as the step before (``step_m``), else the narrowed
    bracket's middle. Returns the bracket, the next depth and the step to it."""
    law = (c_small, c_large, middle, width, shape)
    terms = law_gate_terms(depth_m, tail_m, opening_mm, law, p)
    excess = fmin(terms[8], terms[9]) - flow_m3h / 3600.0
    below = less(excess, 0.0)
    low = select(below, depth_m, low_m)
    high = select(below, high_m, depth_m)
    newton = -excess / fmax(law_terms_slopes(terms, depth_m, tail_m, law, p)[0], SLOPE_MIN_M2S)
    target = depth_m + newton
    short = select(less(2.0 * fmax(newton, -newton), fmax(step_m, -step_m)), 1.0, 0.0)
    # on an end of the bracket only where the law passes the inflow exactly there (a last
    # Newton step under half an ulp lands on the depth it starts from, the bracket's end)
    take = select(less(target, low), 0.0, select(less(high, target), 0.0, short))
    following = select(take, target, 0.5 * (low + high))
    return low, high, following, following - depth_m


def steady_depth_start_m(tail_m: float, opening_mm: float, flow_m3h: float, c_small: float,
                         p: list[float]) -> float:  # fmt: skip
    """Where the steady-depth solve starts: the depth at which the gate would pass the
    inflow as an orifice with Cd at small openings (c₀), or under the critical-flow cap,
    whichever is deeper (the law passes the lesser of the two), inside the bracket."""
    e = fmax(opening_mm, 0.0) / 1000.0
    q = flow_m3h / 3600.0
    tailwater = select(has_tail(p), fmax(tail_m, 0.5 * e), 0.0)
    velocity = q / fmax(c_small * p[9] * e, 1e-12)  # √(2 g head)
    orifice = tailwater + velocity * velocity / (2.0 * G)
    critical = 1.5 * exp(log(fmax(q / (p[9] * sqrt(G)), 1e-300)) * (2.0 / 3.0))
    return fmin(fmax(fmax(orifice, critical), DEPTH_LOW_M), p[DEPTH_MAX_INDEX])


def has_floor(p: list[float]) -> bool:
    """Whether the gauge has a floor of its own (a far gauge that the pool leaves at low
    levels: its channel's flow depth takes over)."""
    return less(0.0, p[27])


def steady_depth_m(opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Depth at the gate at which it passes ``flow_m3h`` with the tail pool at its steady
    depth (:func:`held_steady_depth_m`), m."""
    return held_steady_depth_m(tail_steady_m(flow_m3h, p), opening_mm, flow_m3h, p)


def held_steady_depth_m(tail_m: float, opening_mm: float, flow_m3h: float,
                        p: list[float]) -> float:  # fmt: skip
    """:func:`steady_depth_m` with the tail pool held at ``tail_m``, m: :func:`law_newton_step`
    from :func:`steady_depth_start_m` on ``[DEPTH_LOW_M, depth_max_m]`` until a step is no
    longer than the bracket's width / 2^:data:`BISECTION_STEPS` (or is NaN), at most
    :data:`STEADY_MAX_STEPS` steps (as ``kernel_point.c`` runs it; Cd's curve at the
    discharge computed once). A law that passes the inflow at no depth in the bracket ends
    at its nearer end."""
    c_small, c_large, middle, width, shape = cd_law(flow_m3h, p)
    low, high = DEPTH_LOW_M, p[DEPTH_MAX_INDEX]
    tolerance = (high - low) * 2.0**-BISECTION_STEPS
    depth, step = steady_depth_start_m(tail_m, opening_mm, flow_m3h, c_small, p), high - low
    for _ in range(STEADY_MAX_STEPS):
        low, high, depth, step = law_newton_step(low, high, depth, step, tail_m, opening_mm,
                                                 flow_m3h, c_small, c_large, middle, width,
                                                 shape, p)  # fmt: skip
        if not (step > tolerance or -step > tolerance):
            break
    return depth


def level_mm(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Level at the gauge, mm, for a depth at the gate and the gate's position (the offset's
    discharge is the gate's with the tail pool at its steady depth for ``flow_m3h``); with a
    floor, the smooth maximum of that level and the floor."""
    tail = tail_steady_m(flow_m3h, p)
    passing = gate_flow_m3s(depth_m, tail, opening_mm, flow_m3h, p) * (3600.0 / p[19])
    pool = 1000.0 * depth_m - p[10] - p[11] * passing * passing
    floor_level = p[25] + p[26] * (flow_m3h / p[19] - p[18] / p[19])
    gap = pool - floor_level
    smooth = 0.5 * (pool + floor_level + sqrt(gap * gap + 4.0 * p[27] * p[27]))
    return select(has_floor(p), smooth, pool)


def time_constant_s(depth_m: float, opening_mm: float, flow_m3h: float, p: list[float]) -> float:
    """Time constant of the level's answer to the gate at a steady point, s.

    The small-signal T of :func:`~gatetwin.plant.model.local_fopdt` (the MPC's and the
    controllers' linearisation); the envelope FOPDT of a free gate relaxes with it (one with
    a tail pool carries the pool as a state, :func:`tail_pool_piece`). A free gate:
    the storage equation linearised at (h, e, Q), A / (∂Q_g/∂h). Behind a tail pool the level
    answers with two modes; this is the first moment of that answer to a gate step (the
    single time constant whose first-order answer encloses the same area),
    A (1 + b/c) / (∂Q_g/∂h), with b = −∂Q_g/∂h_t the tailwater's hold on the gate and
    c = ∂Q_t/∂h_t the tail pool's outlet (:func:`gate_flow_slopes`,
    :func:`tail_outflow_slope_m2s`).
    """
    tail = tail_steady_m(flow_m3h, p)
    drowned = -gate_flow_slopes(depth_m, tail, opening_mm, flow_m3h, p)[1]
    outlet = tail_outflow_slope_m2s(tail, p)
    factor = 1.0 + select(has_tail(p), drowned / fmax(outlet, SLOPE_MIN_M2S), 0.0)
    return pool_time_constant_s(depth_m, tail, opening_mm, flow_m3h, p) * factor


def pool_time_constant_s(depth_m: float, tail_m: float, opening_mm: float, flow_m3h: float,
                         p: list[float]) -> float:  # fmt: skip
    """The upstream pool's own time constant at depth ``depth_m`` with the tail pool held at
    ``tail_m``: A / (∂Q_g/∂h), s."""
    slope = gate_flow_slopes(depth_m, tail_m, opening_mm, flow_m3h, p)[0]
    # a closed gate passes nothing at any depth: no finite time constant (the floor keeps the
    # division defined; the level then barely moves)
    return storage_area_m2(depth_m, p) / fmax(slope, SLOPE_MIN_M2S)


def secant_time_constant_s(
    level_mm: float,
    target_mm: float,
    steady_m: float,
    tangent_s: float,
    opening_mm: float,
    flow_m3h: float,
    p: list[float],
) -> float:
    """Time constant with which the envelope FOPDT leaves ``level_mm`` for the steady level
    ``target_mm`` (depth ``steady_m`` at the gate, tangent time constant ``tangent_s``), s.

    The tangent at the target is right near the target only: after a large inflow or gate
    change the level first moves at the storage's rate ``(Q_in − Q_g(h)) / A``, which a
    tangent taken where the level ends misjudges. This is the secant through the current
    depth ``h`` and the steady depth ``h_s``:

        T = T_tangent · (A(h̄) / A(h_s)) · (∂Q_g/∂h · (h_s − h)) / (Q_in − Q_g(h))

    with ``h̄`` the mid-depth (the mean storage area over the gap, A linear in depth), so that
    ``(target − level) / T`` is the storage equation's rate at ``h`` and the first-order
    answer keeps the tangent's two-pool factor. The depth is the steady depth less the
    level's gap (exact when the offset does not grow with discharge, ``o₂ = 0``, and the gauge
    has no floor; at a floor the level's gap understates the pool's, and the secant so
    reckoned followed SWMM's far gauges better than the pool's gap did). Within one
    ``DEPTH_DIFFERENCE_M`` of the target, or where the gate law does not grow with the depth
    (a closed gate, the critical-flow cap), the tangent itself.
    """
    tail = tail_steady_m(flow_m3h, p)
    return tail_secant_time_constant_s(level_mm, target_mm, steady_m, tangent_s, tail, opening_mm,
                                       flow_m3h, p)  # fmt: skip


def tail_secant_time_constant_s(
    level_mm: float,
    target_mm: float,
    steady_m: float,
    tangent_s: float,
    tail_m: float,
    opening_mm: float,
    flow_m3h: float,
    p: list[float],
) -> float:
    """:func:`secant_time_constant_s` with the tail pool held at ``tail_m``."""
    d = DEPTH_DIFFERENCE_M
    tail = tail_m
    depth = fmax(steady_m - (target_mm - level_mm) / 1000.0, DEPTH_LOW_M)
    gap = steady_m - depth
    slope = gate_flow_slopes(steady_m, tail, opening_mm, flow_m3h, p)[0]
    imbalance = flow_m3h / 3600.0 - gate_flow_m3s(depth, tail, opening_mm, flow_m3h, p)
    # the secant holds where the gap is resolved and the gate law grows with the depth
    # across it (imbalance and gap of one sign); elsewhere the tangent
    resolved = less(d, fmax(gap, -gap))
    growing = less(0.0, slope * gap * imbalance)
    ratio = (storage_area_m2(0.5 * (depth + steady_m), p) / storage_area_m2(steady_m, p)
             * slope * gap / select(growing, imbalance, 1.0))  # fmt: skip
    return select(resolved, select(growing, tangent_s * ratio, tangent_s), tangent_s)


def tail_pool_piece(
    x_mm: float, tail_m: float, steady_m: float, opening_mm: float, flow_m3h: float,
    dt_s: float, p: list[float],
) -> tuple[float, float]:  # fmt: skip
    """The envelope FOPDT of a gate that discharges into a pool of its own, over ``dt_s``
    with the inputs held: the level ``x_mm`` and the tail pool's depth after it.

    The level relaxes towards the steady level of the gate law with the tail pool held at
    ``tail_m`` (``steady_m``: that steady depth at the gate), with the storage's secant time
    constant (:func:`tail_secant_time_constant_s`, from the tangent of the upstream pool
    alone); the tail pool fills with the gate's discharge at the level's depth and drains
    through its outlet, integrated exactly for its local time constant
    ``A_t / (∂Q_t/∂h_t − ∂Q_g/∂h_t)``. A single time constant cannot carry both pools: after
    an inflow change the tail pool, slower than the upstream one, holds the gate back for as
    long as it takes to fill or drain.
    """
    target = level_mm(steady_m, opening_mm, flow_m3h, p)
    tangent = pool_time_constant_s(steady_m, tail_m, opening_mm, flow_m3h, p)
    tau = tail_secant_time_constant_s(x_mm, target, steady_m, tangent, tail_m, opening_mm,
                                      flow_m3h, p)  # fmt: skip
    depth = fmax(steady_m - (target - x_mm) / 1000.0, DEPTH_LOW_M)
    passing = gate_flow_m3s(depth, tail_m, opening_mm, flow_m3h, p)
    drowned = -gate_flow_slopes(depth, tail_m, opening_mm, flow_m3h, p)[1]
    outlet = tail_outflow_slope_m2s(tail_m, p)
    area = fmax(p[21], AREA_MIN_M2)
    rate = fmax((drowned + outlet) / area, 1e-12)
    filled = (passing - tail_outflow_m3s(tail_m, p)) / area * (1.0 - exp(-rate * dt_s)) / rate
    return target + (x_mm - target) * exp(-dt_s / tau), tail_m + filled


def substep_count(step_s: float, p: list[float]) -> float:
    """Sub-steps of one communication step: the fewest of at most ``max_substep_s``."""
    return fmax(1.0, -floor(-step_s / p[17]))


#: The functions rendered into C, with their argument names (``p`` last) and output count.
RENDERED = (
    ("substep", ("depth_m", "tail_m", "gate_mm", "target_mm", "flow_m3h", "dt_s"), 3),
    ("tail_steady_m", ("flow_m3h",), 1),
    ("cd_law", ("flow_m3h",), 5),
    (
        "law_newton_step",
        (
            "low_m",
            "high_m",
            "depth_m",
            "step_m",
            "tail_m",
            "opening_mm",
            "flow_m3h",
            "c_small",
            "c_large",
            "middle",
            "width",
            "shape",
        ),
        4,
    ),  # fmt: skip
    ("steady_depth_start_m", ("tail_m", "opening_mm", "flow_m3h", "c_small"), 1),
    ("has_tail", (), 1),
    ("storage_room_m2", (), 1),
    ("operating_room_m2", ("level_mm", "flow_m3h"), 1),
    ("level_mm", ("depth_m", "opening_mm", "flow_m3h"), 1),
    ("actuator_target_mm", ("command_mm",), 1),
    ("substep_count", ("step_s",), 1),
    ("time_constant_s", ("depth_m", "opening_mm", "flow_m3h"), 1),
    (
        "secant_time_constant_s",
        ("level_mm", "target_mm", "steady_m", "tangent_s", "opening_mm", "flow_m3h"),
        1,
    ),
    (
        "tail_pool_piece",
        ("x_mm", "tail_m", "steady_m", "opening_mm", "flow_m3h", "dt_s"),
        2,
    ),
)
