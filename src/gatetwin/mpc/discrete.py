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

The FOPDT rendering also runs on casadi symbols (:mod:`gatetwin.mpc.symbolic`), from which
the C controller FMU's arithmetic is generated (:mod:`gatetwin.mpc.codegen`).

This module renders models; it does not simulate plants (:mod:`gatetwin.plant.simulate`)
or pose optimisation problems (:mod:`gatetwin.mpc.qp`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.augment import append_output_blocks
from gatetwin.mpc.statespace import DiscreteModel
from gatetwin.plant.effects import EffectSet
from gatetwin.plant.model import ArxPlant, FopdtPlant, Plant
from gatetwin.plant.simulate import fopdt_parameters

#: Control period of the demo and of the paper's logger, s.
SAMPLE_PERIOD_S = 1.2
#: Relative slack when splitting ``L / Ts`` into whole samples (2.4 / 1.2 must give 2).
DELAY_SPLIT_RTOL = 1e-9


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
    symbolic = sym.is_symbolic(gain_mm_per_mm, time_constant_s, dead_time_s)
    if not symbolic and not (time_constant_s > 0 and dead_time_s >= 0 and sample_period_s > 0):
        raise ControlError(
            f"fopdt: need T > 0, L >= 0, Ts > 0 (got T = {time_constant_s}, "
            f"L = {dead_time_s}, Ts = {sample_period_s})"
        )
    n_whole, theta = _split_delay(dead_time_s, sample_period_s)
    a = sym.exp(-sample_period_s / time_constant_s)
    late = sym.exp(-(sample_period_s - theta) / time_constant_s)
    b1 = gain_mm_per_mm * (1.0 - late)
    b2 = gain_mm_per_mm * late * (1.0 - sym.exp(-theta / time_constant_s))
    return a, n_whole, b1, b2


def _split_delay(dead_time_s: float, sample_period_s: float) -> tuple[int, float]:
    """``L = n Ts + θ``: whole samples ``n`` and the fraction ``0 <= θ < Ts``, s."""
    ratio = dead_time_s / sample_period_s
    n_whole = sym.floor_int(ratio + DELAY_SPLIT_RTOL * sym.fmax(1.0, ratio))
    return n_whole, sym.fmax(0.0, dead_time_s - n_whole * sample_period_s)


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

    The plant's effect blocks are rendered too: the flow-dependent gain in ``K`` and
    ``T``, the sensor lag in the level dynamics, and the seiche, inflow and drift as extra
    states (:mod:`gatetwin.mpc.augment`). The input blocks (rate limit, backlash, opening
    nonlinearity) act on the command, not on the model: :mod:`gatetwin.mpc.actuation`.

    Raises
    ------
    ControlError
        Non-finite discharge, or an ARX plant whose sample period is not ``sample_period_s``.
    """
    if not math.isfinite(flow_m3h):
        raise ControlError(f"discharge {flow_m3h} m³/h is not finite")
    if not isinstance(plant, (FopdtPlant, ArxPlant)):
        raise ControlError(f"cannot render {type(plant).__name__}: expected FopdtPlant or ArxPlant")
    fx = plant.effect_set
    if isinstance(plant, FopdtPlant):
        core = _fopdt_model(plant, fx, flow_m3h, sample_period_s)
    else:
        core = _arx_model(plant, fx, flow_m3h, sample_period_s)
    return append_output_blocks(core, fx, flow_m3h)


def _fopdt_model(plant: FopdtPlant, fx: EffectSet, q: float, ts: float) -> DiscreteModel:
    gain, tau, delay = fopdt_parameters(plant, fx, q)
    level_ref = plant.schedule.at("level_ref_mm", q)
    return fopdt_model(
        gain, tau, delay, level_ref, plant.opening_ref_mm, q, ts, register_length(plant, ts), fx
    )


def fopdt_model(
    gain: float,
    tau: float,
    delay: float,
    level_ref: float,
    opening_ref_mm: float,
    q: float,
    ts: float,
    m: int,
    fx: EffectSet | None = None,
) -> DiscreteModel:
    """The FOPDT's discrete model from its parameters at ``q`` (``K``, ``T``, ``L``,
    ``level_ref_mm``), with a register of ``m`` past inputs.

    The parameters may be casadi symbols (:mod:`gatetwin.mpc.symbolic`): the whole
    samples of dead time are then a symbol too, and the delayed input's weights are
    placed in the register by comparing it with each position.
    """
    fx = fx or EffectSet()
    if fx.lag:
        core = _lagged_fopdt(gain, tau, delay, fx.lag.time_constant_s, ts)
        n = _split_delay(delay, ts)[0]
    else:
        a, n, b1, b2 = fopdt_split(gain, tau, delay, ts)
        dt = sym.dtype_of(a, b1, b2)
        core = _Core(np.array([[a]], dtype=dt), np.array([b1], dtype=dt),
                     np.array([b2], dtype=dt), np.array([b1 + b2], dtype=dt),
                     np.zeros(1))  # fmt: skip
    nc = core.phi.shape[0]
    nz = nc + m
    a_mat = sym.zeros((nz, nz), core.phi, level_ref)
    b_vec, b_dist, affine = (sym.zeros(nz, core.phi, level_ref) for _ in range(3))
    a_mat[:nc, :nc] = core.phi
    # u(k - j) is state nc + (j - 1) for j >= 1; u(k) itself enters through B
    for lag_samples, weight in ((n, core.late), (n + 1, core.early)):
        if sym.is_symbolic(lag_samples):  # a symbol: compare with every position
            b_vec[:nc] += weight * (lag_samples == 0)
            for j in range(1, m + 1):
                a_mat[:nc, nc + j - 1] += weight * (lag_samples == j)
        elif lag_samples == 0:
            b_vec[:nc] += weight
        else:
            a_mat[:nc, nc + lag_samples - 1] += weight
    _shift_register(a_mat, b_vec, first=nc, length=m)
    b_dist[:nc] = core.whole
    affine[:nc] = core.level_drive * level_ref
    c_level = np.zeros(nz)
    c_level[0] = 1.0
    c_vec = c_level
    if fx.lag:
        c_vec = np.zeros(nz)
        c_vec[1] = 1.0
    return DiscreteModel(
        a_mat, b_vec, c_vec, b_dist, level_ref, opening_ref_mm, q, ts, nc,
        affine=affine, c_level=c_level, output_offset_mm=0.0 if fx.lag else level_ref,
    )  # fmt: skip


@dataclass(frozen=True)
class _Core:
    """Sampled FOPDT core ``[x]`` or ``[x, sensed]`` over one sample.

    ``z(k+1) = phi z + late u(k − n) + early u(k − n − 1) + level_drive level_ref``;
    ``whole`` is the response to an input held over the whole sample (the disturbance's).
    """

    phi: np.ndarray
    late: np.ndarray
    early: np.ndarray
    whole: np.ndarray
    level_drive: np.ndarray


def _lagged_fopdt(gain: float, tau: float, delay: float, lag_s: float, ts: float) -> _Core:
    """FOPDT in cascade with the sensor's first-order lag, sampled exactly.

    Continuous: ``x' = (K u(t − L) − x)/T``, ``s' = (level_ref + x − s)/lag``. Within a
    sample the delayed input switches from ``u(k − n − 1)`` to ``u(k − n)`` at ``θ``, so
    ``z(k+1) = Φ(Ts) z + Φ(Ts − θ) Γ(θ) u(k−n−1) + Γ(Ts − θ) u(k−n) + Γ_ref(Ts) level_ref``.
    """
    theta = _split_delay(delay, ts)[1]
    cont = np.zeros((4, 4))
    cont[:2, :2] = [[-1.0 / tau, 0.0], [1.0 / lag_s, -1.0 / lag_s]]
    cont[0, 2] = gain / tau  # input u
    cont[1, 3] = 1.0 / lag_s  # constant level_ref

    def flow(h: float) -> np.ndarray:
        return linalg.expm(cont * h)

    full, rest, head = flow(ts), flow(ts - theta), flow(theta)
    return _Core(
        phi=full[:2, :2],
        late=rest[:2, 2],
        early=rest[:2, :2] @ head[:2, 2],
        whole=full[:2, 2],
        level_drive=full[:2, 3],
    )


def _arx_model(plant: ArxPlant, fx: EffectSet, q: float, ts: float) -> DiscreteModel:
    if plant.envelope is not None:
        raise ControlError(
            "arx: an envelope ARX's input is the gate law's steady level, not the opening; "
            "control on the envelope FOPDT (re-linearised) or a local ARX"
        )
    if abs(plant.sample_period_s - ts) > DELAY_SPLIT_RTOL * ts:
        raise ControlError(
            f"arx: sample period {plant.sample_period_s} s differs from the control period "
            f"{ts} s; re-identify or resample the model"
        )
    a_coef, b_coef = plant.coefficients(q)
    lag = fx.lag
    na, m = plant.na, register_length(plant, ts)
    nc = na + (1 if lag else 0)
    nz = nc + m
    a_mat = np.zeros((nz, nz))
    b_vec, b_dist, affine = np.zeros(nz), np.zeros(nz), np.zeros(nz)
    a_mat[0, :na] = a_coef
    for i in range(1, na):  # x(k - i) moves down the output history
        a_mat[i, i - 1] = 1.0
    for j, bj in enumerate(b_coef):
        lag_samples = plant.nk - 1 + j  # b_{j+1} multiplies u(k - lag_samples)
        if lag_samples == 0:
            b_vec[0] += bj
        else:
            a_mat[0, nc + lag_samples - 1] += bj
    _shift_register(a_mat, b_vec, first=nc, length=m)
    b_dist[0] = float(np.sum(b_coef))
    level_ref = plant.schedule.at("level_ref_mm", q)
    c_level = np.zeros(nz)
    c_level[0] = 1.0
    c_vec = c_level
    if lag:  # s(k+1) = a_l s(k) + (1 - a_l) (level_ref + x(k+1)), x(k+1) from row 0
        keep = lag.state_space(ts)[0][0, 0]
        s = na
        a_mat[s] = (1.0 - keep) * a_mat[0]
        a_mat[s, s] = keep
        b_vec[s], b_dist[s] = (1.0 - keep) * b_vec[0], (1.0 - keep) * b_dist[0]
        affine[s] = (1.0 - keep) * level_ref
        c_vec = np.zeros(nz)
        c_vec[s] = 1.0
    return DiscreteModel(
        a_mat, b_vec, c_vec, b_dist, level_ref, plant.opening_ref_mm, q, ts, nc,
        affine=affine, c_level=c_level, output_offset_mm=0.0 if lag else level_ref,
    )  # fmt: skip


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
    "fopdt_model",
    "fopdt_split",
    "register_length",
]
