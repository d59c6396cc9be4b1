"""Disturbance observer of the MPC: a Kalman filter on the model state and a disturbance.

The model state ``z`` is augmented with an input disturbance ``d`` (mm of opening, a
random walk): ``z(k+1) = A z + B u + B_d d``, ``d(k+1) = d``. Process noise enters the
newest level state and ``d``; the register of past inputs is known and gets none. A
seiche's states get some too (:attr:`DiscreteModel.uncertain_states`): its prediction from
the gate's moves alone is a fitted sinusoid, and where the pool's real wave differs (the
flume's is a staircase of reflections, no rebound) an uncorrected prediction puts the
difference, every seiche period, into the level and ``d``, which the MPC then answers: a
limit cycle at about the seiche's period. The filter starts from the steady-state
covariance (``scipy.linalg.solve_discrete_are``) and then propagates its covariance with
the model of each sample, so a change of discharge (new ``K``, ``T``, ``L``) is followed
consistently.

Why an input and not an output disturbance: a gain error, or the flume's own response to
a change of inflow, acts on the level through the pool's storage — through the same lag
as the gate — so an input disturbance predicts how the level will go on moving where an
output disturbance would only shift it.

A change of discharge makes the plant object's level jump by ``Δ = level_ref(Q₁) −
level_ref(Q₀)`` at once; a real pool fills instead. The filter therefore adds ``Δ²`` to
the level state's variance at such a sample: it is unsure how much of the jump has
happened, takes the level it then measures as the truth, and lets the model (not the
disturbance) predict the rest of the rise. On a plant that does jump (the FMU) the
innovation is zero and nothing changes.

:meth:`DisturbanceObserver.start`, ``correct`` and ``predict`` also run on casadi symbols
(:mod:`gatetwin.mpc.symbolic`): the C controller FMU's observer is generated from them.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError, solve_discrete_are

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.discrete import DiscreteModel
from gatetwin.mpc.settings import ObserverSettings


def _augmented(model: DiscreteModel) -> tuple[np.ndarray, np.ndarray]:
    nz = model.n_states
    a_aug = sym.zeros((nz + 1, nz + 1), model.a, model.b_dist)
    a_aug[:nz, :nz] = model.a
    a_aug[:nz, nz] = model.b_dist
    a_aug[nz, nz] = 1.0
    return a_aug, np.append(model.c, 0.0)


def _process_noise(model: DiscreteModel, settings: ObserverSettings) -> np.ndarray:
    """Process noise of ``[z, d]``: on the level state, on ``d``, and on each uncertain
    state with an effect on the reading, sized so that its term in the reading wanders
    by ``level_sd_mm`` per sample, as the level does."""
    nz = model.n_states
    q = np.zeros((nz + 1, nz + 1))
    q[0, 0] = settings.level_sd_mm**2
    q[nz, nz] = settings.disturbance_sd_mm**2
    for i in model.uncertain_states:
        weight = float(model.c[i])
        if weight != 0.0:
            q[i, i] = (settings.level_sd_mm / weight) ** 2
    return q


def steady_prior_covariance(model: DiscreteModel, settings: ObserverSettings) -> np.ndarray:
    """Steady-state prior covariance of ``[z, d]`` for the model held constant.

    The model's ``fixed_states`` (a sensor drift: known from the start, no process noise,
    no equilibrium) keep zero covariance; the Riccati equation is solved for the rest. So
    does ``d`` where the reading cannot see it (the gate has no hold on the level at this
    point, an envelope's tangent at the critical-flow cap: ``c A^k b_d = 0`` for every
    ``k``): an integrator nothing observes has no steady covariance, and the filter then
    starts from the disturbance it has.
    """
    a_aug, c_aug = _augmented(model)
    keep = model.free_states
    if _disturbance_observable(model):
        keep = np.append(keep, model.n_states)
    sub = np.ix_(keep, keep)
    r = np.array([[settings.measurement_sd_mm**2]])
    try:
        p_sub = solve_discrete_are(
            a_aug[sub].T, c_aug[keep][:, None], _process_noise(model, settings)[sub], r
        )
    except (LinAlgError, ValueError) as exc:
        raise ControlError(f"observer: no steady-state Kalman filter ({exc})") from None
    p = np.zeros_like(a_aug)
    p[sub] = p_sub
    return p


#: Below this reach of the input disturbance on the reading, mm of level per mm of opening
#: (``max_k |c A^k b_d|``), the reading does not see it: a metre of disturbance would move
#: the level by a micrometre, far under any gauge's noise.
UNSEEN_DISTURBANCE_MM_PER_MM = 1e-9


def _disturbance_observable(model: DiscreteModel) -> bool:
    """Whether the reading sees the input disturbance: ``|c A^k b_d|`` reaches
    :data:`UNSEEN_DISTURBANCE_MM_PER_MM` for some ``k`` below the number of states."""
    a, c = np.asarray(model.a, dtype=float), np.asarray(model.c, dtype=float)
    column = np.asarray(model.b_dist, dtype=float)
    seen = 0.0
    for _ in range(model.n_states):
        seen = max(seen, abs(float(c @ column)))
        column = a @ column
    return seen >= UNSEEN_DISTURBANCE_MM_PER_MM


def kalman_gain(model: DiscreteModel, settings: ObserverSettings) -> np.ndarray:
    """Steady-state filter gain ``L`` (``nz + 1``): ``[z; d] += L (y − ŷ)``."""
    p = steady_prior_covariance(model, settings)
    c = np.append(model.c, 0.0)
    return p @ c / (c @ p @ c + settings.measurement_sd_mm**2)


class DisturbanceObserver:
    """Estimate of the model state and the input disturbance, one sample at a time.

    Use :meth:`reset` at a steady start, then per sample :meth:`correct` with the measured
    level and :meth:`predict` with the opening applied over the next sample.
    """

    def __init__(self, settings: ObserverSettings) -> None:
        self.settings = settings
        self.state = np.zeros(0)
        self.disturbance_mm = 0.0
        self.covariance = np.zeros((0, 0))
        self._level_ref_mm = np.nan

    def reset(self, model: DiscreteModel, opening_mm: float, level_mm: float) -> None:
        """Steady state at ``opening_mm``; the level's offset from the model becomes ``d``."""
        self.start(model, opening_mm, level_mm)
        self.covariance = steady_prior_covariance(model, self.settings)

    def start(self, model: DiscreteModel, opening_mm: float, level_mm: float) -> None:
        """:meth:`reset` without the covariance (which the caller sets)."""
        dc = model.dc_gain_mm_per_mm()
        steady = model.level_mm(model.steady_state(opening_mm))
        # a gain the reading cannot see (UNSEEN_DISTURBANCE_MM_PER_MM) explains no offset
        seen = dc * dc >= UNSEEN_DISTURBANCE_MM_PER_MM**2
        if sym.is_symbolic(dc, steady, level_mm):  # both branches are formed, one is taken
            self.disturbance_mm = sym.where(seen, (level_mm - steady) / dc, 0.0)
        else:
            self.disturbance_mm = (level_mm - steady) / dc if seen else 0.0
        self.state = model.steady_state(opening_mm, self.disturbance_mm)
        self._level_ref_mm = model.level_ref_mm

    def set_estimate(
        self,
        state: np.ndarray,
        disturbance_mm: float,
        covariance: np.ndarray,
        level_ref_mm: float,
    ) -> None:
        """Take an estimate as it stands (``level_ref_mm``: the last prediction model's)."""
        self.state, self.disturbance_mm, self.covariance = state, disturbance_mm, covariance
        self._level_ref_mm = level_ref_mm

    def correct(self, model: DiscreteModel, level_mm: float) -> float:
        """Update with the level measured now; ``model`` is the one of the last prediction.

        Returns the innovation (measured minus predicted level), mm.
        """
        c = np.append(model.c, 0.0)
        p = self.covariance
        pc = p @ c
        gain = pc / (c @ pc + self.settings.measurement_sd_mm**2)
        innovation = level_mm - model.level_mm(self.state)
        self.state = self.state + gain[:-1] * innovation
        self.disturbance_mm += sym.scalar(gain[-1]) * innovation
        self.covariance = p - np.outer(gain, pc)
        return sym.scalar(innovation)

    def rescale_disturbance(self, old_gain: float, new_gain: float) -> None:
        """Keep the disturbance's steady effect on the level when the model's gain changes.

        ``d`` is in mm of opening, so a re-linearised model whose gain goes from
        ``old_gain`` to ``new_gain`` (mm/mm) would read the same ``d`` as a different level
        offset; ``d`` and its covariance are scaled by ``old_gain / new_gain`` instead.
        """
        if sym.is_symbolic(old_gain, new_gain):  # both branches are formed, one is taken
            kept = sym.where(old_gain == 0.0, 1.0, sym.where(new_gain == 0.0, 1.0, 0.0))
            ratio = sym.where(kept > 0.0, 1.0, old_gain / new_gain)
        elif old_gain == 0.0 or new_gain == 0.0 or old_gain == new_gain:
            return
        else:
            ratio = old_gain / new_gain
        self.disturbance_mm *= ratio
        self.covariance[-1, :] *= ratio
        self.covariance[:, -1] *= ratio

    def predict(self, model: DiscreteModel, opening_mm: float) -> None:
        """Advance one sample with ``opening_mm`` held (the model at this sample's flow)."""
        self.state = model.step(self.state, opening_mm, self.disturbance_mm)
        a_aug, _ = _augmented(model)
        p = a_aug @ self.covariance @ a_aug.T + _process_noise(model, self.settings)
        jump = model.level_ref_mm - self._level_ref_mm
        p[0, 0] += jump * jump
        self.covariance = 0.5 * (p + p.T)
        self._level_ref_mm = model.level_ref_mm


__all__ = [
    "UNSEEN_DISTURBANCE_MM_PER_MM",
    "DisturbanceObserver",
    "kalman_gain",
    "steady_prior_covariance",
]
