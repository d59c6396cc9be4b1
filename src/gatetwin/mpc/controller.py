"""The level MPC: plant rendering at the measured discharge, observer, and QP per sample.

The loop follows do-mpc's shape, ``u = controller.step(y); y = plant.step(u)``: each
:meth:`MpcController.step` takes the level measured now (and the discharge and set-point)
and returns the opening to hold over the next sample. Inside it the observer corrects its
estimate, the plant (FOPDT or ARX, the object the FMUs are exported from) is re-rendered
at the measured discharge (``K``, ``T``, ``L`` re-evaluated; same state size at every
``Q``), the problem goes to the QP backend (or the Opti + IPOPT reference), and the
observer predicts ahead with the chosen opening. Openings are not rounded here: the
actuator's 1 mm resolution belongs to the plant.

A plant with effect blocks is controlled with all of them: the output blocks are states of
the model (:mod:`gatetwin.mpc.augment`), the input blocks shape the command
(:class:`~gatetwin.mpc.actuation.CommandShaper`: a rate limit narrows the move bound, an
opening nonlinearity is planned through, a backlash is compensated), and the cost is on
the water level, not on what a lagging or drifting gauge reads.
"""

from __future__ import annotations

import math

import numpy as np

from gatetwin.mpc.actuation import CommandShaper
from gatetwin.mpc.discrete import DiscreteModel, discretise
from gatetwin.mpc.errors import ControlError
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.opti import OptiBackend
from gatetwin.mpc.qp import MpcProblem, MpcSolution, QpBackend
from gatetwin.mpc.settings import MpcSettings
from gatetwin.plant.model import Plant

BACKENDS = ("qp", "ipopt")


class MpcController:
    """Offset-free, scheduled MPC of one gauge's level with the gate opening.

    Parameters
    ----------
    plant : FopdtPlant or ArxPlant
        The plant model (the same object the FMUs are exported from).
    settings : MpcSettings, optional
        Horizon, constraints, weights, QP solver, observer tuning.
    backend : {"qp", "ipopt"}
        ``"qp"``: condensed dense QP through casadi's conic plugin (the controller);
        ``"ipopt"``: the ``casadi.Opti`` + IPOPT reference formulation.

    Attributes
    ----------
    last_solution : MpcSolution or None
        The last plan (model openings, predicted levels, solver time and status).
    shaper : CommandShaper
        The plant's input blocks on the controller's side.
    previous_opening_mm : float
        Model opening of the last sample (the gate opening unless the plant has an opening
        nonlinearity), mm.
    previous_gate_mm : float
        Gate opening at the last sample as the controller knows it, mm (the command differs
        by a backlash compensation).
    failures : int
        Samples at which the solver reported failure (the previous opening is then held).
    """

    name = "mpc"

    def __init__(
        self, plant: Plant, settings: MpcSettings | None = None, *, backend: str = "qp"
    ) -> None:
        if backend not in BACKENDS:
            raise ControlError(
                f"mpc backend must be one of {', '.join(BACKENDS)} (got {backend!r})"
            )
        self.plant = plant
        self.settings = settings or MpcSettings()
        self.backend = QpBackend(self.settings) if backend == "qp" else OptiBackend(self.settings)
        self.observer = DisturbanceObserver(self.settings.observer)
        self.shaper = CommandShaper(
            plant.effect_set,
            plant.opening_ref_mm,
            self.settings.max_move_mm,
            self.settings.sample_period_s,
            self.settings.backlash_hold_mm,
        )
        self.previous_opening_mm = math.nan
        self.previous_gate_mm = math.nan
        self.last_solution: MpcSolution | None = None
        self.failures = 0
        self._model: DiscreteModel | None = None

    def model_at(self, flow_m3h: float) -> DiscreteModel:
        """The plant rendered at ``flow_m3h`` (the same object while the discharge holds)."""
        if self._model is None or self._model.flow_m3h != flow_m3h:
            self._model = discretise(self.plant, flow_m3h, self.settings.sample_period_s)
        return self._model

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        """Start at rest: ``opening_mm`` held, ``level_mm`` measured at ``flow_m3h``."""
        lo, hi = self.settings.opening_range_mm
        if not lo <= opening_mm <= hi:
            raise ControlError(f"mpc: start opening {opening_mm} mm outside [{lo}, {hi}] mm")
        if not math.isfinite(level_mm):
            raise ControlError(f"mpc: start level {level_mm} mm is not finite")
        model_opening = self.shaper.to_model(float(opening_mm))
        self.observer.reset(self.model_at(flow_m3h), model_opening, level_mm)
        self.shaper.reset(opening_mm)
        self.previous_opening_mm = model_opening
        self.previous_gate_mm = float(opening_mm)
        # one solve at rest sets the solver up (qpOASES' first call is a cold start that
        # costs ~20x a hot one); from here on every step is hot-started
        self.backend.solve(self.problem(flow_m3h, level_mm))
        self.last_solution = None
        self.failures = 0

    @property
    def last_solve_s(self) -> float:
        return self.last_solution.solve_s if self.last_solution is not None else 0.0

    def problem(self, flow_m3h: float, setpoint_mm: float) -> MpcProblem:
        """The decision to take now, from the observer's current estimate."""
        return MpcProblem(
            model=self.model_at(flow_m3h),
            state=self.observer.state.copy(),
            disturbance_mm=self.observer.disturbance_mm,
            setpoint_mm=float(setpoint_mm),
            previous_opening_mm=self.previous_opening_mm,
            settings=self.settings,
            max_move_mm=self.shaper.model_move_mm(self.previous_gate_mm),
            opening_range_mm=self.shaper.model_range_mm(self.settings.opening_range_mm),
        )

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> float:
        """Opening (mm) to command over the next sample, given the level measured now.

        ``flow_m3h`` is the discharge measured now (held over the horizon) and
        ``setpoint_mm`` the level set-point (no preview). The command is the wanted gate
        opening, compensated for a backlash if the plant has one.
        """
        if math.isnan(self.previous_opening_mm) or self._model is None:
            raise ControlError("mpc: call reset() before step()")
        if not (math.isfinite(level_mm) and math.isfinite(flow_m3h) and math.isfinite(setpoint_mm)):
            raise ControlError("mpc: level, discharge and set-point must be finite")
        self.observer.correct(self._model, level_mm)
        problem = self.problem(flow_m3h, setpoint_mm)
        solution = self.backend.solve(problem)
        self.last_solution = solution
        gate = self.shaper.to_gate(solution.first_move_mm)
        if not solution.success or not math.isfinite(gate):
            self.failures += 1
            gate = self.previous_gate_mm
        command = self.shaper.command(float(np.clip(gate, *self.settings.opening_range_mm)))
        # where the gate goes: the plan, or within backlash_hold_mm of it under a backlash
        gate = self.shaper.gate_mm
        opening = self.shaper.to_model(gate)
        self.observer.predict(problem.model, opening)
        self.previous_opening_mm, self.previous_gate_mm = opening, gate
        return command


__all__ = ["BACKENDS", "MpcController"]
