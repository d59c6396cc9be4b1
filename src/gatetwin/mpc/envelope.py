"""The envelope rendering of a plant for the MPC: the tangent model at the measured (Q, e).

An envelope FOPDT (``fopdt`` with ``plant.envelope``) or a ``physical`` plant holds across
the gate's whole range: its steady level ``H_ss(Q, e)`` is the gate law's, and its gain
``K = ∂H_ss/∂e`` changes by an order of magnitude between a wide and a nearly closed gate
(−3 mm/mm at 50 mm and −28 mm/mm at 20 mm, both at 50 m³/h, for gauge 3F).
:func:`linearised_model` renders it at one point ``(Q, e₀)`` as an FOPDT about that point,

    T(Q, e₀) dy/dt = H_ss(Q, e₀) + K(Q, e₀) (e(t − L) − e₀) − y,

with ``K``, ``T``, ``L`` and ``H_ss`` from :func:`gatetwin.plant.model.local_fopdt` and the
same exact ZOH discretisation and dead-time register as the scheduled FOPDT
(:func:`gatetwin.mpc.discrete.fopdt_split`). Unlike that rendering, the state is the
absolute level (``level_ref_mm`` = 0) and the linearisation point enters as a known drive
(the model's affine term), with the input measured from the plant's fixed
``opening_ref_mm``. So the state, the register and the observer's estimate mean the same
at every point, and the MPC re-renders the model at each sample without mapping its state.

:func:`steady_opening_mm` inverts the steady level (the opening that holds a level at a
discharge); the controller starts from it when it is not told the gate's opening.

This module renders models; it does not pose or solve the MPC problem.
"""

from __future__ import annotations

import math
from typing import Any

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S, fopdt_split
from gatetwin.mpc.statespace import DiscreteModel
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.model import FopdtPlant, PhysicalPlant, Plant, envelope_point, local_fopdt

#: Bisection steps of :func:`steady_opening_mm` (100 mm / 2^30 ≈ 1e-7 mm).
INVERSE_STEPS = 30


def envelope_parameters(plant: Plant) -> list[float]:
    """The kernel's parameter vector of an envelope FOPDT or a physical plant."""
    _require_envelope(plant)
    return plant.vector if isinstance(plant, PhysicalPlant) else list(plant.envelope.values())


def has_envelope(plant: Plant) -> bool:
    """Whether ``plant`` holds across the gate's range (envelope FOPDT or physical)."""
    return isinstance(plant, PhysicalPlant) or (
        isinstance(plant, FopdtPlant) and plant.envelope is not None
    )


def _require_envelope(plant: Plant) -> None:
    if not has_envelope(plant):
        raise ControlError(
            f"envelope mpc needs an envelope FOPDT or a physical plant; got a {plant.kind} "
            "plant without an envelope"
        )


def _datum_mm(plant: Plant, flow_m3h: Any) -> Any:
    """What the plant's output adds to the gate law's level: the physical family's datum
    correction (``level_ref_mm``); nothing for an envelope FOPDT. A symbolic discharge gets
    the same interpolation on symbols."""
    if not isinstance(plant, PhysicalPlant):
        return 0.0
    if sym.is_symbolic(flow_m3h):
        from gatetwin.mpc.codegen import interp_clamped_symbolic

        s = plant.schedule
        return interp_clamped_symbolic(s.flow_m3h, s.values["level_ref_mm"], flow_m3h)
    return plant.schedule.at("level_ref_mm", flow_m3h)


def steady_level_mm(plant: Plant, flow_m3h: float, opening_mm: float) -> float:
    """The plant's steady level at (Q, e), mm (the physical family's datum included); an
    FOPDT without an envelope holds its schedule's tangent, ``level_ref(Q) + K(Q) (e -
    opening_ref)``."""
    if isinstance(plant, FopdtPlant) and plant.envelope is None:
        s = plant.schedule
        return s.at("level_ref_mm", flow_m3h) + s.at("gain_mm_per_mm", flow_m3h) * (
            opening_mm - plant.opening_ref_mm)  # fmt: skip
    _require_envelope(plant)
    p = plant.vector if isinstance(plant, PhysicalPlant) else list(plant.envelope.values())
    return envelope_point(opening_mm, flow_m3h, p)[0] + _datum_mm(plant, flow_m3h)


def envelope_register_length(plant: Plant, sample_period_s: float = SAMPLE_PERIOD_S) -> int:
    """Past inputs the state holds: the schedule's largest dead time (none for physical)."""
    delay = plant.max_dead_time_s if isinstance(plant, FopdtPlant) else 0.0
    _, n_max, _, _ = fopdt_split(1.0, 1.0, delay, sample_period_s)
    return n_max + 1


def on_grid(value: float, grid_rel: float) -> float:
    """``value`` rounded to the nearest point of a geometric grid of ratio ``1 + grid_rel``
    (0 and ``grid_rel`` = 0 leave it as it is)."""
    if grid_rel == 0.0 or value == 0.0:
        return value
    step = math.log1p(grid_rel)
    return math.copysign(math.exp(round(math.log(abs(value)) / step) * step), value)


def gate_position_mm(plant: Plant, command_mm: float) -> float:
    """Where the gate settles for ``command_mm``: rounded to the actuator's resolution
    (the envelope's ``resolution_mm``), as the gate law's plant does it."""
    _require_envelope(plant)
    p = plant.vector if isinstance(plant, PhysicalPlant) else list(plant.envelope.values())
    return kernel.actuator_target_mm(command_mm, p)


def linearised_model(
    plant: Plant,
    flow_m3h: float,
    opening_mm: float,
    sample_period_s: float = SAMPLE_PERIOD_S,
    *,
    grid_rel: float = 0.0,
) -> DiscreteModel:
    """The plant's tangent FOPDT at (``flow_m3h``, ``opening_mm``), sampled exactly.

    The plant's effect blocks are not in it: the seiche the envelope models carry has no
    steady gain, and the MPC's disturbance observer absorbs what it leaves.

    Parameters
    ----------
    plant : FopdtPlant or PhysicalPlant
        An envelope FOPDT or a physical plant.
    flow_m3h : float
        Discharge of the linearisation point, m³/h.
    opening_mm : float
        Opening of the linearisation point, mm.
    sample_period_s : float
        Control period, s.
    grid_rel : float
        ``K`` and ``T`` are rounded to a geometric grid of this relative step (0: exact
        tangent). Models whose ``K``, ``T`` and ``L`` fall on the same grid point share
        ``A`` and ``B``, so the MPC rebuilds its QP matrices only when the tangent has
        moved by about this much; the steady level at ``opening_mm`` stays exact.

    Returns
    -------
    DiscreteModel
        State ``[level (mm), u(k−1) … u(k−m)]`` with ``u = e − opening_ref_mm`` (mm) and
        ``level_ref_mm`` = 0; its steady level at ``opening_mm`` is ``H_ss(Q, e₀)``.

    Raises
    ------
    ControlError
        A plant without an envelope, or a non-finite point.
    """
    _require_envelope(plant)
    if not (math.isfinite(flow_m3h) and math.isfinite(opening_mm)):
        raise ControlError(f"envelope mpc: point (Q {flow_m3h}, e {opening_mm}) is not finite")
    point = local_fopdt(plant, flow_m3h, opening_mm)  # type: ignore[arg-type]
    datum = _datum_mm(plant, flow_m3h)
    return tangent_model(plant, point, datum, flow_m3h, opening_mm, sample_period_s, grid_rel)


def tangent_model(
    plant: Plant,
    point: dict[str, Any],
    datum_mm: Any,
    flow_m3h: Any,
    opening_mm: Any,
    sample_period_s: float = SAMPLE_PERIOD_S,
    grid_rel: float = 0.0,
) -> DiscreteModel:
    """:func:`linearised_model` from the tangent ``point`` (:func:`gatetwin.plant.model.
    local_fopdt`'s dict) and the datum at ``flow_m3h``; numbers or casadi symbols (a symbolic
    point needs a numeric dead time, which places the input in the register)."""
    gain = on_grid(point["gain_mm_per_mm"], grid_rel)
    level = point["level_mm"] + datum_mm
    tau = on_grid(point["time_constant_s"], grid_rel)
    a, n_whole, b1, b2 = fopdt_split(gain, tau, point["dead_time_s"], sample_period_s)
    m = envelope_register_length(plant, sample_period_s)
    nz = 1 + m
    a_mat = sym.zeros((nz, nz), a, b1, b2)
    b_vec, b_dist, affine, c_vec = (sym.zeros(nz, a, b1, b2, level) for _ in range(4))
    a_mat[0, 0] = a
    for lag_samples, weight in ((n_whole, b1), (n_whole + 1, b2)):
        if lag_samples == 0:
            b_vec[0] += weight
        else:  # u(k − j) is state j
            a_mat[0, lag_samples] += weight
    b_vec[1] = 1.0  # the register: u(k) becomes u(k − 1), and so on down
    for i in range(2, nz):
        a_mat[i, i - 1] = 1.0
    b_dist[0] = b1 + b2
    # steady level H + K (e − e0) written with u = e − e_ref: the drive is (1 − a) times
    # the level the tangent gives at u = 0
    affine[0] = (1.0 - a) * (level - gain * (opening_mm - plant.opening_ref_mm))
    c_vec[0] = 1.0
    return DiscreteModel(
        a_mat, b_vec, c_vec, b_dist, 0.0, plant.opening_ref_mm, sym.scalar(flow_m3h),
        sample_period_s, 1, affine=affine,
    )  # fmt: skip


def steady_opening_mm(
    plant: Plant, flow_m3h: float, level_mm: float, opening_range_mm: tuple[float, float]
) -> float:
    """The opening in ``opening_range_mm`` whose steady level at ``flow_m3h`` is ``level_mm``.

    The steady level falls as the gate opens; a level out of reach gives the nearer end of
    the range.
    """
    lo, hi = opening_range_mm
    for _ in range(INVERSE_STEPS):
        middle = 0.5 * (lo + hi)
        if steady_level_mm(plant, flow_m3h, middle) > level_mm:
            lo = middle
        else:
            hi = middle
    return 0.5 * (lo + hi)


__all__ = [
    "envelope_parameters",
    "envelope_register_length",
    "gate_position_mm",
    "has_envelope",
    "linearised_model",
    "on_grid",
    "tangent_model",
    "steady_level_mm",
    "steady_opening_mm",
]
