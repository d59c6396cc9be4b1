"""The ``physical`` family: pool storage drained by the gate law, behind a loaded actuator.

:class:`PhysicalPlant` is the data (the kernel's parameters, the gauge, the validity range);
:class:`PhysicalSimulator` steps it with the two verbs every plant has (``initialize``,
``do_step``) by calling :mod:`gatetwin.plant.physical_kernel`, where the equations are.

Semantics shared by every rendering (this simulator, the C FMU, the pythonfmu FMU):

* inputs: the commanded opening (mm) and the inflow (m³/h), held over each communication
  step; the actuator moves the gate towards the command at its loaded speed;
* a communication step of ``h`` seconds is ``n = max(1, ceil(h / max_substep_s))`` equal
  sub-steps (:func:`~gatetwin.plant.physical_kernel.substep`); a step that would need more
  than :data:`MAX_SUBSTEPS` is refused;
* initial state: the gate at the command, the depth at which the gate passes the inflow
  into the tail pool (if any) at its steady depth for the inflow
  (:func:`~gatetwin.plant.physical_kernel.held_steady_depth_m`);
* output: the kernel's gauge level at the current depth, gate position and the inflow in
  force over the last step, plus the schedule's ``level_ref_mm`` (a datum correction, 0 as
  identified; scheduled on Q so that the FMU's discharge knots mark the validity range);
* with a ``seiche`` effect block, the pool's oscillation: driven over each sub-step by the
  gate position at its start (:func:`~gatetwin.plant.blocks.seiche_advance`), at rest for
  the commanded opening at initialisation, and added to the output.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

from gatetwin.plant import blocks
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.inputs import SimulationError, check_inputs
from gatetwin.plant.model import PhysicalPlant, steady_depth_m

__all__ = ["MAX_SUBSTEPS", "PhysicalSimulator"]

#: Most sub-steps one communication step may take.
MAX_SUBSTEPS = 100_000


@dataclass
class PhysicalSimulator:
    """Stepwise simulation of a :class:`PhysicalPlant` (same verbs as ``PlantSimulator``)."""

    plant: PhysicalPlant
    time_s: float = 0.0
    depth_m: float = 0.0
    tail_m: float = 0.0
    gate_mm: float = 0.0
    flow_m3h: float = 0.0
    warned_range: bool = False
    p: list[float] = field(default_factory=list)
    seiche: Any = None
    seiche_x1: float = 0.0
    seiche_x2: float = 0.0

    def initialize(self, opening_mm: float, flow_m3h: float, time_s: float = 0.0) -> None:
        check_inputs(opening_mm, flow_m3h)
        self.p = self.plant.vector
        self.time_s, self.flow_m3h = time_s, flow_m3h
        self.gate_mm = kernel.actuator_target_mm(opening_mm, self.p)
        self.depth_m = steady_depth_m(self.gate_mm, flow_m3h, self.p)
        self.tail_m = kernel.tail_steady_m(flow_m3h, self.p)
        self.seiche = seiche = self.plant.effect_set.seiche
        self.seiche_x1 = self.seiche_x2 = 0.0
        if seiche:
            self.seiche_x1 = blocks.seiche_equilibrium(
                opening_mm - self.plant.opening_ref_mm, seiche.period_s, seiche.decay_time_s
            )
        self._check_range(flow_m3h)

    @property
    def level_mm(self) -> float:
        level = kernel.level_mm(self.depth_m, self.gate_mm, self.flow_m3h, self.p)
        level += self.plant.schedule.at("level_ref_mm", self.flow_m3h)
        seiche = self.seiche
        if seiche:
            level += blocks.seiche_output(self.seiche_x2, seiche.period_s,
                                          seiche.amplitude_mm_per_mm)  # fmt: skip
        return level

    process_level_mm = level_mm

    def do_step(self, h: float, opening_mm: float, flow_m3h: float) -> float:
        """Advance by ``h`` seconds with inputs held; return the level at the new time."""
        check_inputs(opening_mm, flow_m3h)
        if not 0 < h < math.inf:
            raise SimulationError(f"communication step {h} s must be > 0 and finite")
        n = kernel.substep_count(h, self.p)
        if n > MAX_SUBSTEPS:
            raise SimulationError(
                f"communication step {h} s needs {n:.0f} sub-steps of at most "
                f"{self.plant.parameters['max_substep_s']} s; the limit is {MAX_SUBSTEPS}"
            )
        target = kernel.actuator_target_mm(opening_mm, self.p)
        seiche = self.seiche
        dt = h / n
        for _ in range(int(n)):
            gate = self.gate_mm
            self.depth_m, self.tail_m, self.gate_mm = kernel.substep(
                self.depth_m, self.tail_m, self.gate_mm, target, flow_m3h, dt, self.p
            )
            if seiche:
                self.seiche_x1, self.seiche_x2 = blocks.seiche_advance(
                    self.seiche_x1,
                    self.seiche_x2,
                    gate - self.plant.opening_ref_mm,
                    dt,
                    seiche.period_s,
                    seiche.decay_time_s,
                )
        self._check_range(flow_m3h)
        self.flow_m3h = flow_m3h
        self.time_s += h
        return self.level_mm

    def _check_range(self, flow_m3h: float) -> None:
        lo, hi = self.plant.schedule.flow_range_m3h
        if not lo <= flow_m3h <= hi and not self.warned_range:
            self.warned_range = True
            warnings.warn(
                f"flow_m3h = {flow_m3h} outside the model's validity range [{lo}, {hi}]",
                RuntimeWarning,
                stacklevel=3,
            )
