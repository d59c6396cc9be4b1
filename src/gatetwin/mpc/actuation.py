"""The plant's input blocks on the MPC's side: what the controller commands, and how.

The discrete model (:mod:`gatetwin.mpc.discrete`) is linear in its input ``u``; the input
blocks are not linear, so the controller handles them around the model, as each block's
``mpc`` text says (:mod:`gatetwin.plant.effects`):

* ``actuator_rate_limit`` — a move bound: the plan's gate moves are at most
  ``min(settings' max move, rate · Ts)`` per sample, so the gate reaches every command
  within the sample. The model then sees a step where the gate makes a ramp of at most
  one sample; that is the one approximation left.
* ``opening_nonlinearity`` — the plan is made in the effective input
  ``u = map(e − e_ref)`` (the model's input, as a "model opening" ``e_ref + u``) and
  the gate opening is ``e_ref + inverse(u)``. The opening range maps exactly (the map is
  increasing); the move bound of the first move maps exactly too (``map(v + m) − map(v)
  = exp(s v) map(m)``), later moves of the plan use the slope at the current opening.
* ``actuator_backlash`` — the command is the wanted gate opening plus half the dead band
  in the direction of the move (:meth:`ActuatorBacklash.compensate_mm`). The shaper runs
  the block's play operator on its own commands, so it knows where the gate is; a
  reversal commands a jump of one dead band, and a reversal smaller than ``hold_mm`` is
  not made at all (the gate stays within ``hold_mm`` of the plan), so that round-off in
  the plan cannot make the actuator cross the band back and forth. The controller plans
  from where the gate really is. Limit: the linear plan does not know that a reversal
  costs a crossing, and near a set-point it reverses every 15–20 samples by tiny amounts,
  each time moving the actuator across the band (34 reversals in 12 min of two
  set-point steps on the test plant with a 2 mm band, noise-free); a plan that prices
  reversals needs a mixed-integer or split-move QP, not built. With a rate limit as
  well, the actuator needs extra samples to cross the band.

This module is for the controller; the blocks' simulation is in :mod:`gatetwin.plant`.
"""

from __future__ import annotations

import math

from gatetwin.plant import blocks
from gatetwin.plant.effects import EffectSet


class CommandShaper:
    """Maps between gate openings, model inputs and actuator commands for one plant.

    Parameters
    ----------
    effects : EffectSet
        The plant's checked blocks.
    opening_ref_mm : float
        The plant's reference opening, mm.
    max_move_mm : float
        The settings' largest gate move per sample, mm.
    sample_period_s : float
        Control period, s.
    hold_mm : float
        Smallest gate move against the last direction worth crossing a backlash for, mm.

    Attributes
    ----------
    actuator_mm, gate_mm : float
        Last command and where it put the gate (the play operator's state), mm.
    direction : float
        Direction of the last move: +1 opening, -1 closing, 0 none yet.
    """

    def __init__(
        self,
        effects: EffectSet,
        opening_ref_mm: float,
        max_move_mm: float,
        sample_period_s: float,
        hold_mm: float = 0.0,
    ) -> None:
        self.opening_ref_mm = opening_ref_mm
        self.nonlinearity = effects.nonlinearity
        self.backlash = effects.backlash
        self.hold_mm = hold_mm
        self.gate_move_mm = max_move_mm
        if effects.rate_limit:
            limit = effects.rate_limit.rate_constraint_mm(sample_period_s)
            self.gate_move_mm = min(max_move_mm, limit)
        self.direction = 0.0
        self.actuator_mm = self.gate_mm = math.nan

    def reset(self, opening_mm: float) -> None:
        """The gate rests at ``opening_mm`` in the middle of any dead band."""
        self.direction = 0.0
        self.actuator_mm = self.gate_mm = float(opening_mm)

    def to_model(self, gate_mm: float) -> float:
        """Model opening ``e_ref + map(gate − e_ref)`` (the gate itself without a map)."""
        if not self.nonlinearity:
            return gate_mm
        return self.opening_ref_mm + self.nonlinearity.forward_mm(gate_mm - self.opening_ref_mm)

    def to_gate(self, model_opening_mm: float) -> float:
        """Inverse of :meth:`to_model`."""
        if not self.nonlinearity:
            return model_opening_mm
        effective = model_opening_mm - self.opening_ref_mm
        return self.opening_ref_mm + self.nonlinearity.inverse_mm(effective)

    def model_range_mm(self, opening_range_mm: tuple[float, float]) -> tuple[float, float]:
        """The gate's opening range in model openings (the map is increasing)."""
        lo, hi = opening_range_mm
        return self.to_model(lo), self.to_model(hi)

    def model_move_mm(self, gate_mm: float) -> float:
        """Largest model move from ``gate_mm`` keeping the gate's move within its bound."""
        m = self.gate_move_mm
        if not self.nonlinearity:
            return m
        up = self.to_model(gate_mm + m) - self.to_model(gate_mm)
        down = self.to_model(gate_mm) - self.to_model(gate_mm - m)
        return min(up, down)

    def command(self, gate_mm: float) -> float:
        """Actuator command that puts the gate at ``gate_mm`` (backlash compensated)."""
        if not self.backlash:
            self.actuator_mm = self.gate_mm = gate_mm
            return gate_mm
        move = gate_mm - self.gate_mm
        reversal = move * self.direction < 0
        if move == 0.0 or (reversal and abs(move) <= self.hold_mm):
            return self.actuator_mm
        self.direction = math.copysign(1.0, move)
        self.actuator_mm = self.backlash.compensate_mm(gate_mm, self.direction)
        self.gate_mm = blocks.play(self.gate_mm, self.actuator_mm, self.backlash.deadband_mm)
        return self.actuator_mm


__all__ = ["CommandShaper"]
