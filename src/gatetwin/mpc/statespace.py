"""The MPC's discrete-time model: a state-space at one discharge with two outputs.

:class:`DiscreteModel` is what every part of the MPC works on (observer, QP, effect
blocks); :mod:`gatetwin.mpc.discrete` renders a plant into one and
:mod:`gatetwin.mpc.augment` appends the output effect blocks' states. This module holds
the object and its arithmetic only; it renders nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gatetwin.mpc import symbolic as sym


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """``z(k+1) = A z + B u + B_d d + f`` at one discharge, with two outputs.

    ``reading = output_offset_mm + C z`` is what the gauge reads (what
    :func:`gatetwin.plant.simulate` returns; the observer corrects with it) and
    ``level = level_ref_mm + C_level z`` is the water level the MPC controls. They differ
    only by the sensor blocks (``sensor_lag``, ``sensor_drift``).

    Attributes
    ----------
    a, b, c, b_dist : ndarray
        ``A`` (nz × nz), ``B``, ``C`` and ``B_d`` (nz each). ``u`` and ``d`` in mm of
        opening (``u`` is the effective input when the plant has an opening nonlinearity),
        ``z`` in mm (levels), mm (past inputs) and the effect blocks' own units.
    level_ref_mm : float
        Level of the plant at ``opening_ref_mm`` and this discharge, mm.
    opening_ref_mm : float
        Reference opening, mm: ``u = opening − opening_ref_mm``.
    flow_m3h : float
        Discharge the parameters were evaluated at, m³/h.
    sample_period_s : float
        ``Ts``, s.
    n_dynamic : int
        The first ``n_dynamic`` states are the level dynamics (``x``, for ARX its past
        values, and the sensed level of a ``sensor_lag``); then the register of past
        inputs (known exactly); then the states of the output effect blocks.
    affine : ndarray
        ``f``: the known drive of each state over one sample at this discharge (the
        inflow term's ``Q − Q_ref``, the sensor lag's ``level_ref``); zeros by default.
    c_level : ndarray
        ``C_level``; ``c`` by default.
    output_offset_mm : float
        Constant of the reading; ``level_ref_mm`` by default (0 with a sensor lag, whose
        state is the absolute sensed level).
    fixed_states, fixed_values : tuple
        States with no equilibrium, set at the start and never corrected by the observer
        (the sensor drift's offset and rate), and their start values.
    uncertain_states : tuple
        States of output blocks driven by the input whose prediction from the input alone
        is uncertain (the seiche's): the observer gives them process noise, so that it
        corrects them from the readings instead of trusting their open-loop prediction
        (:func:`gatetwin.mpc.observer.steady_prior_covariance`).
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
    affine: np.ndarray = None  # type: ignore[assignment]
    c_level: np.ndarray = None  # type: ignore[assignment]
    output_offset_mm: float = None  # type: ignore[assignment]
    fixed_states: tuple[int, ...] = ()
    fixed_values: tuple[float, ...] = ()
    uncertain_states: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if self.affine is None:
            object.__setattr__(self, "affine", np.zeros(self.b.size))
        if self.c_level is None:
            object.__setattr__(self, "c_level", self.c)
        if self.output_offset_mm is None:
            object.__setattr__(self, "output_offset_mm", self.level_ref_mm)

    @property
    def n_states(self) -> int:
        return int(self.b.size)

    @property
    def free_states(self) -> np.ndarray:
        """Indices of the states that have an equilibrium (all but ``fixed_states``)."""
        return np.setdiff1d(np.arange(self.n_states), np.asarray(self.fixed_states, dtype=int))

    def step(self, z: np.ndarray, opening_mm: float, disturbance_mm: float = 0.0) -> np.ndarray:
        """State one sample later with ``opening_mm`` held over the sample."""
        u = opening_mm - self.opening_ref_mm
        return self.a @ z + self.b * u + self.b_dist * disturbance_mm + self.affine

    def level_mm(self, z: np.ndarray) -> float:
        """What the gauge reads in state ``z``, mm."""
        return sym.scalar(self.output_offset_mm + self.c @ z)

    def process_level_mm(self, z: np.ndarray) -> float:
        """The water level in state ``z`` (without the sensor blocks), mm."""
        return sym.scalar(self.level_ref_mm + self.c_level @ z)

    def steady_state(self, opening_mm: float, disturbance_mm: float = 0.0) -> np.ndarray:
        """Equilibrium state for a constant opening (the plants' initial state); the
        ``fixed_states`` take their start values."""
        u = opening_mm - self.opening_ref_mm
        z = sym.zeros(self.n_states, self.a, opening_mm, disturbance_mm)
        fixed = np.asarray(self.fixed_states, dtype=int)
        z[fixed] = self.fixed_values
        free = self.free_states
        rhs = self.b * u + self.b_dist * disturbance_mm + self.affine + self.a @ z
        lhs = np.eye(free.size) - self.a[np.ix_(free, free)]
        z[free] = sym.solve(lhs, rhs[free])
        return z

    def dc_gain_mm_per_mm(self) -> float:
        """Steady change of the reading per mm of opening."""
        free = self.free_states
        lhs = np.eye(free.size) - self.a[np.ix_(free, free)]
        return sym.scalar(self.c[free] @ sym.solve(lhs, self.b[free]))


__all__ = ["DiscreteModel"]
