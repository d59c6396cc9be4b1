"""The output effect blocks in the MPC's discrete model: extra states after the register.

:func:`append_output_blocks` takes the rendering of the level dynamics
(:func:`gatetwin.mpc.discrete.discretise`) and appends, for the blocks the plant carries,
each block's exact discrete state-space at the control period
(:meth:`gatetwin.plant.effects.EffectBlock.state_space`):

* ``seiche`` — two states driven by the model input ``u`` (the gate's deviation from the
  reference opening) held over the sample; its output adds to the level and the reading.
  With an ``opening_nonlinearity`` as well, ``u`` is the effective input, which agrees with
  the gate's deviation to first order (the map's slope is 1 at the reference opening).
* ``inflow_disturbance`` — one state driven by the measured ``Q − Q_ref`` as a known input
  (the model's affine term ``f``; the discharge is held over the horizon as for the
  schedule); adds to the level and the reading.
* ``sensor_drift`` — offset and rate, started at ``(0, rate)`` and never corrected by the
  observer; adds to the reading only, so the MPC controls the water level and not the
  drifting gauge.

``flow_dependent_gain`` and ``sensor_lag`` change the level dynamics themselves and are
rendered in :mod:`gatetwin.mpc.discrete`; the input blocks in :mod:`gatetwin.mpc.actuation`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from gatetwin.mpc.statespace import DiscreteModel
from gatetwin.plant.effects import EffectSet


def _block_diagonal(model: DiscreteModel, size: int) -> dict[str, np.ndarray]:
    """The model's arrays grown by ``size`` zero states at the end."""
    nz = model.n_states
    a = np.zeros((nz + size, nz + size))
    a[:nz, :nz] = model.a

    def grow(v: np.ndarray) -> np.ndarray:
        return np.concatenate([v, np.zeros(size)])

    return {
        "a": a,
        "b": grow(model.b),
        "c": grow(model.c),
        "b_dist": grow(model.b_dist),
        "affine": grow(model.affine),
        "c_level": grow(model.c_level),
    }


def _append(
    model: DiscreteModel,
    ss: tuple[np.ndarray, ...],
    *,
    driven_by_input: bool,
    known_drive: float = 0.0,
    in_level: bool = True,
    fixed_values: tuple[float, ...] = (),
    uncertain: bool = False,
) -> DiscreteModel:
    """Append one block ``(A, B, C, D)``; its input is ``u``, a known constant or none."""
    a_blk, b_blk, c_blk, _ = ss
    nz, size = model.n_states, a_blk.shape[0]
    arrays = _block_diagonal(model, size)
    new = slice(nz, nz + size)
    arrays["a"][new, new] = a_blk
    if driven_by_input:
        arrays["b"][new] = b_blk[:, 0]
    elif b_blk.shape[1]:
        arrays["affine"][new] = b_blk[:, 0] * known_drive
    arrays["c"][new] = c_blk[0]
    if in_level:
        arrays["c_level"][new] = c_blk[0]
    fixed = tuple(range(nz, nz + len(fixed_values)))
    uncertain_states = tuple(range(nz, nz + size)) if uncertain else ()
    return replace(
        model,
        **arrays,
        fixed_states=(*model.fixed_states, *fixed),
        fixed_values=(*model.fixed_values, *fixed_values),
        uncertain_states=(*model.uncertain_states, *uncertain_states),
    )


def append_output_blocks(model: DiscreteModel, fx: EffectSet, flow_m3h: float) -> DiscreteModel:
    """``model`` with the seiche, inflow and drift blocks of ``fx`` appended (in that order)."""
    ts = model.sample_period_s
    if fx.seiche:
        # the seiche is a fitted sinusoid of the pool's wave reflections: the observer
        # corrects it from the readings (see DiscreteModel.uncertain_states)
        model = _append(model, fx.seiche.state_space(ts), driven_by_input=True, uncertain=True)
    if fx.inflow:
        model = _append(
            model,
            fx.inflow.state_space(ts),
            driven_by_input=False,
            known_drive=flow_m3h - fx.inflow.flow_ref_m3h,
        )
    if fx.drift:
        model = _append(
            model,
            fx.drift.state_space(ts),
            driven_by_input=False,
            in_level=False,
            fixed_values=(0.0, fx.drift.rate_mm_per_s),
        )
    return model


__all__ = ["append_output_blocks"]
