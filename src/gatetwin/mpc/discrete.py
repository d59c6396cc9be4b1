"""Exact discrete-time state-space rendering of a plant at one discharge, for the MPC.

A :class:`~gatetwin.plant.model.Plant` evaluated at a discharge ``Q`` becomes

    z(k+1) = A z(k) + B u(k) + B_d d,      level(k) = level_ref_mm(Q) + C z(k),

with ``u = opening − opening_ref_mm`` held over ``[k Ts, (k+1) Ts)`` (zero-order hold) and
``d`` an input disturbance (mm of opening) that the observer estimates.

FOPDT ``T dx/dt = K u(t − L) − x``: the dead time is represented exactly, not by a Padé
approximation. With ``L = n Ts + θ`` (``n`` whole samples, ``0 <= θ < Ts``) the modified
z-transform splits the delayed input over two samples,

    x(k+1) = a x(k) + b1 u(k − n) + b2 u(k − n − 1),
    a = exp(−Ts/T),  b1 = K (1 − exp(−(Ts − θ)/T)),  b2 = K exp(−(Ts − θ)/T) (1 − exp(−θ/T)),

and the past moves ``u(k − 1) … u(k − m)`` are a shift register in the state. ``m`` is set
by the largest dead time in the schedule, so the state has the same size at every ``Q``
and the MPC can re-evaluate ``K, T, L`` at each step's measured discharge.

ARX ``x(k) = Σ a_i x(k − i) + Σ b_j u(k − nk − j + 1)`` (the paper's convention, ``u(k)``
being the input in force over the step that ends at sample ``k``) is already discrete;
its state holds ``na`` past outputs and the register of past inputs.

This module renders models; it does not simulate plants (:mod:`gatetwin.plant.simulate`)
or pose optimisation problems (:mod:`gatetwin.mpc.qp`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gatetwin.mpc.errors import ControlError
from gatetwin.plant.model import ArxPlant, FopdtPlant, Plant

#: Control period of the demo and of the paper's logger, s.
SAMPLE_PERIOD_S = 1.2
#: Relative slack when splitting ``L / Ts`` into whole samples (2.4 / 1.2 must give 2).
DELAY_SPLIT_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """``z(k+1) = A z + B u + B_d d``, ``level = level_ref_mm + C z`` at one discharge.

    Attributes
    ----------
    a, b, c, b_dist : ndarray
        ``A`` (nz × nz), ``B``, ``C`` and ``B_d`` (nz each). ``u`` and ``d`` in mm of
        opening, ``z`` in mm (levels) and mm (past openings).
    level_ref_mm : float
        Level of the plant at ``opening_ref_mm`` and this discharge, mm.
    opening_ref_mm : float
        Reference opening, mm: ``u = opening − opening_ref_mm``.
    flow_m3h : float
        Discharge the parameters were evaluated at, m³/h.
    sample_period_s : float
        ``Ts``, s.
    n_dynamic : int
        The first ``n_dynamic`` states are level deviations (``x`` and, for ARX, its past
        values); the rest is the register of past inputs, known exactly.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    b_dist: np.ndarray
    level_ref_mm: float
    opening_ref_mm: float
    flow_m3h: float
    sample_period_s: float
    n_dynamic: int

    @property
    def n_states(self) -> int:
        return int(self.b.size)

    def step(self, z: np.ndarray, opening_mm: float, disturbance_mm: float = 0.0) -> np.ndarray:
        """State one sample later with ``opening_mm`` held over the sample."""
        u = opening_mm - self.opening_ref_mm
        return self.a @ z + self.b * u + self.b_dist * disturbance_mm

    def level_mm(self, z: np.ndarray) -> float:
        return float(self.level_ref_mm + self.c @ z)

    def steady_state(self, opening_mm: float, disturbance_mm: float = 0.0) -> np.ndarray:
        """Equilibrium state for a constant opening (the plants' initial state)."""
        u = opening_mm - self.opening_ref_mm
        rhs = self.b * u + self.b_dist * disturbance_mm
        return np.linalg.solve(np.eye(self.n_states) - self.a, rhs)

    def dc_gain_mm_per_mm(self) -> float:
        """Steady level change per mm of opening."""
        return float(self.c @ np.linalg.solve(np.eye(self.n_states) - self.a, self.b))


def fopdt_split(
    gain_mm_per_mm: float, time_constant_s: float, dead_time_s: float, sample_period_s: float
) -> tuple[float, int, float, float]:
    """ZOH discretisation of ``K e^{−Ls}/(Ts+1)`` by the modified z-transform.

    Returns
    -------
    a : float
        Pole ``exp(−Ts/T)``.
    n_whole : int
        Whole samples of dead time, ``n = floor(L / Ts)``.
    b1, b2 : float
        Weights of ``u(k − n)`` and ``u(k − n − 1)``; ``b1 + b2 = K (1 − a)``.
    """
    if not (time_constant_s > 0 and dead_time_s >= 0 and sample_period_s > 0):
        raise ControlError(
            f"fopdt: need T > 0, L >= 0, Ts > 0 (got T = {time_constant_s}, "
            f"L = {dead_time_s}, Ts = {sample_period_s})"
        )
    ratio = dead_time_s / sample_period_s
    n_whole = math.floor(ratio + DELAY_SPLIT_RTOL * max(1.0, ratio))
    theta = max(0.0, dead_time_s - n_whole * sample_period_s)
    a = math.exp(-sample_period_s / time_constant_s)
    late = math.exp(-(sample_period_s - theta) / time_constant_s)
    b1 = gain_mm_per_mm * (1.0 - late)
    b2 = gain_mm_per_mm * late * (1.0 - math.exp(-theta / time_constant_s))
    return a, n_whole, b1, b2


def register_length(plant: Plant, sample_period_s: float = SAMPLE_PERIOD_S) -> int:
    """Past inputs the state must hold for every discharge in the plant's schedule."""
    if isinstance(plant, FopdtPlant):
        _, n_max, _, _ = fopdt_split(1.0, 1.0, plant.max_dead_time_s, sample_period_s)
        return n_max + 1
    return plant.nk + plant.nb - 2


def discretise(
    plant: Plant, flow_m3h: float, sample_period_s: float = SAMPLE_PERIOD_S
) -> DiscreteModel:
    """The plant's exact discrete model at ``flow_m3h`` (parameters clamped outside knots).

    Raises
    ------
    ControlError
        Non-finite discharge, or an ARX plant whose sample period is not ``sample_period_s``.
    """
    if not math.isfinite(flow_m3h):
        raise ControlError(f"discharge {flow_m3h} m³/h is not finite")
    if isinstance(plant, FopdtPlant):
        return _fopdt_model(plant, flow_m3h, sample_period_s)
    if isinstance(plant, ArxPlant):
        return _arx_model(plant, flow_m3h, sample_period_s)
    raise ControlError(f"cannot render {type(plant).__name__}: expected FopdtPlant or ArxPlant")


def _fopdt_model(plant: FopdtPlant, q: float, ts: float) -> DiscreteModel:
    sched = plant.schedule
    gain = sched.at("gain_mm_per_mm", q)
    a, n, b1, b2 = fopdt_split(gain, sched.at("time_constant_s", q), sched.at("dead_time_s", q), ts)
    m = register_length(plant, ts)
    nz = 1 + m
    a_mat = np.zeros((nz, nz))
    b_vec = np.zeros(nz)
    a_mat[0, 0] = a
    # u(k - j) is state 1 + (j - 1) for j >= 1; u(k) itself enters through B
    for lag, weight in ((n, b1), (n + 1, b2)):
        if lag == 0:
            b_vec[0] += weight
        else:
            a_mat[0, lag] += weight
    _shift_register(a_mat, b_vec, first=1, length=m)
    c_vec = np.zeros(nz)
    c_vec[0] = 1.0
    b_dist = np.zeros(nz)
    b_dist[0] = b1 + b2
    return DiscreteModel(
        a_mat, b_vec, c_vec, b_dist, sched.at("level_ref_mm", q), plant.opening_ref_mm, q, ts, 1
    )


def _arx_model(plant: ArxPlant, q: float, ts: float) -> DiscreteModel:
    if abs(plant.sample_period_s - ts) > DELAY_SPLIT_RTOL * ts:
        raise ControlError(
            f"arx: sample period {plant.sample_period_s} s differs from the control period "
            f"{ts} s; re-identify or resample the model"
        )
    a_coef, b_coef = plant.coefficients(q)
    na, m = plant.na, register_length(plant, ts)
    nz = na + m
    a_mat = np.zeros((nz, nz))
    b_vec = np.zeros(nz)
    a_mat[0, :na] = a_coef
    for i in range(1, na):  # x(k - i) moves down the output history
        a_mat[i, i - 1] = 1.0
    for j, bj in enumerate(b_coef):
        lag = plant.nk - 1 + j  # b_{j+1} multiplies u(k - lag)
        if lag == 0:
            b_vec[0] += bj
        else:
            a_mat[0, na + lag - 1] += bj
    _shift_register(a_mat, b_vec, first=na, length=m)
    c_vec = np.zeros(nz)
    c_vec[0] = 1.0
    b_dist = np.zeros(nz)
    b_dist[0] = float(np.sum(b_coef))
    return DiscreteModel(
        a_mat,
        b_vec,
        c_vec,
        b_dist,
        plant.schedule.at("level_ref_mm", q),
        plant.opening_ref_mm,
        q,
        ts,
        na,
    )


def _shift_register(a_mat: np.ndarray, b_vec: np.ndarray, *, first: int, length: int) -> None:
    """States ``first … first+length−1`` hold ``u(k−1) … u(k−length)``."""
    if length == 0:
        return
    b_vec[first] = 1.0
    for i in range(1, length):
        a_mat[first + i, first + i - 1] = 1.0


__all__ = [
    "SAMPLE_PERIOD_S",
    "ControlError",
    "DiscreteModel",
    "discretise",
    "fopdt_split",
    "register_length",
]
