"""The level MPC: plant rendering at the measured discharge, observer, and QP per sample.

The loop follows do-mpc's shape, ``u = controller.step(y); y = plant.step(u)``: each
:meth:`MpcController.step` takes the level measured now (and the discharge and set-point)
and returns the opening to hold over the next sample. Inside it the observer corrects its
estimate, the plant (FOPDT or ARX, the object the FMUs are exported from) is re-rendered
at the measured discharge (``K``, ``T``, ``L`` re-evaluated; same state size at every
``Q``), the problem goes to the QP backend (or the Opti + IPOPT reference), and the
observer predicts ahead with the chosen opening. Openings are not rounded here: the
actuator's 1 mm resolution belongs to the plant.

A plant with an envelope (envelope FOPDT, physical family) is re-linearised instead at
every sample at the measured discharge and the gate's position
(:mod:`gatetwin.mpc.envelope`): the tangent's ``K``, ``T``, ``L`` and the steady level
``H_ss(Q, e)`` as the linearisation point. Three things keep that consistent from one
sample to the next: the state is the absolute level, so it needs no mapping between
points; the observer's input disturbance is rescaled when ``K`` changes, so it keeps its
effect on the level; and the observer predicts with the opening at the actuator's
resolution (the envelope's ``resolution_mm``), so it does not integrate the rounding into
a limit cycle. Where ``|K|`` exceeds the gain the move weight was tuned for, the weight
grows with ``K²`` (:attr:`MpcSettings.move_weight_gain_mm_per_mm`).

Why a re-linearised QP and not a nonlinear MPC on the physical kernel: the tangent at the
measured point is exact to first order, the condensed QP keeps DAQP's warm-started ~0.2 ms
solve, and a rebuild of its matrices
(only when the tangent has moved by a 1 % grid step) costs a few ms; IPOPT on the same
horizon takes ~19 ms median and ~64 ms p99 a solve on the linear model alone
(``benchmarks/bench_mpc.py``, N = 100), more with the kernel's nested steady-depth solve inside,
and gives up the QP's solution in a bounded number of active-set steps.

A plant with effect blocks is controlled with all of them: the output blocks are states of
the model (:mod:`gatetwin.mpc.augment`), the input blocks shape the command
(:class:`~gatetwin.mpc.actuation.CommandShaper`: a rate limit narrows the move bound, an
opening nonlinearity is planned through, a backlash is compensated), and the cost is on
the water level, not on what a lagging or drifting gauge reads.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc.actuation import CommandShaper
from gatetwin.mpc.discrete import DiscreteModel, discretise
from gatetwin.mpc.envelope import (
    gate_position_mm,
    has_envelope,
    linearised_model,
    on_grid,
    steady_opening_mm,
)
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.opti import OptiBackend
from gatetwin.mpc.qp import MpcProblem, MpcSolution, QpBackend
from gatetwin.mpc.settings import MpcSettings
from gatetwin.plant.effects import EffectSet
from gatetwin.plant.model import PhysicalPlant, Plant

BACKENDS = ("qp", "ipopt")
LINEARISATIONS = ("auto", "envelope", "schedule")


class MpcController:
    """Offset-free MPC of one gauge's level with the gate opening, one call per sample.

    Parameters
    ----------
    plant : FopdtPlant, ArxPlant, PhysicalPlant, str or Path
        The plant model (the object the FMUs are exported from), or the path of a model
        file holding one.
    settings : MpcSettings, optional
        Horizon, constraints, weights, QP solver, observer tuning.
    backend : {"qp", "ipopt"}
        ``"qp"``: condensed dense QP through casadi's conic plugin (the controller);
        ``"ipopt"``: the ``casadi.Opti`` + IPOPT reference formulation.
    linearisation : {"auto", "envelope", "schedule"}
        ``"envelope"``: at every sample the model is the plant's tangent at the measured
        discharge and the gate's present opening (:mod:`gatetwin.mpc.envelope`; envelope
        FOPDT or physical plants). ``"schedule"``: the schedule's ``K``, ``T``, ``L`` and
        ``level_ref_mm`` at the measured discharge, i.e. the model linearised once, at
        ``opening_ref_mm`` (FOPDT and ARX). ``"auto"``: the envelope when the plant has one.
    setpoint_mm : float, optional
        Level set-point, mm, used by :meth:`step` when it is not given one; by default the
        level measured at the start (hold the level).

    Attributes
    ----------
    name : str
        ``"mpc"``, or ``"mpc_envelope"`` with the envelope linearisation (the closed-loop
        runs are labelled with it).
    setpoint_mm : float or None
        The set-point :meth:`step` uses when called without one, mm (may be reassigned).
    linearisation : str
        ``"envelope"`` or ``"schedule"`` (``"auto"`` resolved).
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

    Examples
    --------
    A controller for a scheduled FOPDT (gain −13.6 mm/mm, 62 s, 2 s dead time at
    40 m³/h); it starts at rest at the first level it measures, with the gate where the
    model holds that level, and closes the gate to raise the level to the set-point:

    >>> from gatetwin.mpc import MpcController
    >>> from gatetwin.plant.model import FopdtPlant, Schedule
    >>> plant = FopdtPlant("3F", 25.0, Schedule((40.0,), {
    ...     "gain_mm_per_mm": (-13.6,), "time_constant_s": (62.0,),
    ...     "dead_time_s": (2.0,), "level_ref_mm": (190.0,)}))
    >>> mpc = MpcController(plant, setpoint_mm=200.0)
    >>> opening = mpc.step(190.0, 40.0)
    >>> round(mpc.previous_gate_mm - opening, 6) == 0 and 24.0 < opening < 25.0
    True
    >>> mpc.reset()  # forget the state: the next step starts at rest again
    """

    def __init__(
        self,
        plant: Plant | str | Path,
        settings: MpcSettings | None = None,
        *,
        backend: str = "qp",
        linearisation: str = "auto",
        setpoint_mm: float | None = None,
    ) -> None:
        if backend not in BACKENDS:
            raise ControlError(
                f"mpc backend must be one of {', '.join(BACKENDS)} (got {backend!r})"
            )
        if isinstance(plant, (str, Path)):
            from gatetwin.modelfile import read_model_file

            plant = read_model_file(plant).plant
        self.plant = plant
        self.linearisation = _resolve_linearisation(plant, linearisation)
        self.name = "mpc_envelope" if self.linearisation == "envelope" else "mpc"
        self.settings = settings or MpcSettings()
        self.backend = QpBackend(self.settings) if backend == "qp" else OptiBackend(self.settings)
        self.observer = DisturbanceObserver(self.settings.observer)
        effect_set = EffectSet() if isinstance(plant, PhysicalPlant) else plant.effect_set
        self.shaper = CommandShaper(
            effect_set,
            plant.opening_ref_mm,
            self.settings.max_move_mm,
            self.settings.sample_period_s,
            self.settings.backlash_hold_mm,
        )
        self.setpoint_mm = setpoint_mm
        self.previous_opening_mm = math.nan
        self.previous_gate_mm = math.nan
        self.last_solution: MpcSolution | None = None
        self.failures = 0
        self._model: DiscreteModel | None = None
        self._start_opening_mm: float | None = None
        self._point_mm = math.nan

    def model_at(self, flow_m3h: float) -> DiscreteModel:
        """The plant rendered at ``flow_m3h`` (the same object while the point holds).

        With the envelope linearisation the point is (``flow_m3h``, the gate's present
        opening); the observer's disturbance keeps its effect on the level when the
        tangent's gain changes (it is rescaled by the ratio of the gains).
        """
        if self.linearisation == "schedule":
            if self._model is None or self._model.flow_m3h != flow_m3h:
                self._model = discretise(self.plant, flow_m3h, self.settings.sample_period_s)
            return self._model
        # the point: the gate's position, i.e. the last opening at the actuator's resolution
        opening = gate_position_mm(self.plant, self.previous_opening_mm)
        old = self._model
        if old is None or old.flow_m3h != flow_m3h or self._point_mm != opening:
            self._model = linearised_model(
                self.plant, flow_m3h, opening, self.settings.sample_period_s,
                grid_rel=self.settings.tangent_grid_rel,
            )  # fmt: skip
            self._point_mm = opening
            if old is not None and self.observer.state.size:
                self.observer.rescale_disturbance(
                    old.dc_gain_mm_per_mm(), self._model.dc_gain_mm_per_mm()
                )
        return self._model

    def reset(
        self,
        opening_mm: float | None = None,
        level_mm: float | None = None,
        flow_m3h: float | None = None,
    ) -> None:
        """Start at rest: ``opening_mm`` held, ``level_mm`` measured at ``flow_m3h``.

        Without ``level_mm`` and ``flow_m3h`` the controller forgets its state and the next
        :meth:`step` starts at rest at what it measures, with the gate at ``opening_mm``
        or, without it, at the opening that holds the measured level in the model.
        """
        self._model = None
        self.previous_opening_mm = self.previous_gate_mm = math.nan
        self.last_solution = None
        self.failures = 0
        if level_mm is None or flow_m3h is None:
            self._start_opening_mm = opening_mm
            return
        if not (math.isfinite(level_mm) and math.isfinite(flow_m3h)):
            raise ControlError("mpc: start level and discharge must be finite")
        if opening_mm is None:
            opening_mm = self._holding_opening_mm(level_mm, flow_m3h)
        self._start(float(opening_mm), float(level_mm), float(flow_m3h))

    def _start(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        lo, hi = self.settings.opening_range_mm
        if not lo <= opening_mm <= hi:
            raise ControlError(f"mpc: start opening {opening_mm} mm outside [{lo}, {hi}] mm")
        if not math.isfinite(level_mm):
            raise ControlError(f"mpc: start level {level_mm} mm is not finite")
        model_opening = self.shaper.to_model(float(opening_mm))
        self.previous_opening_mm = model_opening
        self.previous_gate_mm = float(opening_mm)
        self.observer.reset(self.model_at(flow_m3h), model_opening, level_mm)
        self.shaper.reset(opening_mm)
        # one solve at rest sets the solver up (its first call factors the Hessian and starts
        # cold, ~20x a warm one); from here on every step is warm-started
        self.backend.solve(self.problem(flow_m3h, level_mm))
        self.last_solution = None
        self.failures = 0

    def _applied_mm(self, opening_mm: float) -> float:
        """The opening the plant will hold for a planned one: with the envelope, the gate's
        position at the actuator's resolution (so the observer does not read the rounding
        as a disturbance and integrate it into a limit cycle); else the plan itself."""
        if self.linearisation == "envelope":
            return gate_position_mm(self.plant, opening_mm)
        return opening_mm

    def _holding_opening_mm(self, level_mm: float, flow_m3h: float) -> float:
        """The opening at which the model's steady level at ``flow_m3h`` is ``level_mm``."""
        rng = self.settings.opening_range_mm
        if self.linearisation == "envelope":  # where the gate can stand: its resolution
            opening = gate_position_mm(
                self.plant, steady_opening_mm(self.plant, flow_m3h, level_mm, rng)
            )
            return float(np.clip(opening, *rng))
        model = discretise(self.plant, flow_m3h, self.settings.sample_period_s)
        gain = model.dc_gain_mm_per_mm()
        if gain == 0.0:
            return float(np.clip(self.plant.opening_ref_mm, *rng))
        opening = self.plant.opening_ref_mm + (level_mm - model.level_ref_mm) / gain
        return float(np.clip(opening, *rng))

    @property
    def last_solve_s(self) -> float:
        return self.last_solution.solve_s if self.last_solution is not None else 0.0

    def _settings_for(self, model: DiscreteModel) -> MpcSettings:
        """The settings of this sample's problem: with the envelope, the move weight is
        held in level terms where the tangent's gain exceeds the one it was tuned for."""
        s = self.settings
        if self.linearisation != "envelope":
            return s
        ratio = (model.dc_gain_mm_per_mm() / s.move_weight_gain_mm_per_mm) ** 2
        if ratio <= 1.0:
            return s
        # on a 5 % grid, so that the QP's matrices are shared between nearby samples
        return replace(s, move_weight=on_grid(s.move_weight * ratio, 0.05))

    def problem(self, flow_m3h: float, setpoint_mm: float) -> MpcProblem:
        """The decision to take now, from the observer's current estimate."""
        model = self.model_at(flow_m3h)
        settings = self._settings_for(model)
        return MpcProblem(
            model=model,
            state=self.observer.state.copy(),
            disturbance_mm=self.observer.disturbance_mm,
            setpoint_mm=float(setpoint_mm),
            previous_opening_mm=self.previous_opening_mm,
            settings=settings,
            max_move_mm=self.shaper.model_move_mm(self.previous_gate_mm),
            opening_range_mm=self.shaper.model_range_mm(self.settings.opening_range_mm),
        )

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float | None = None) -> float:
        """Opening (mm) to command over the next sample, given the level measured now.

        ``flow_m3h`` is the discharge measured now (held over the horizon) and
        ``setpoint_mm`` the level set-point (no preview; default :attr:`setpoint_mm`, or
        the level measured at the start). The command is the wanted gate opening,
        compensated for a backlash if the plant has one.
        """
        if not (math.isfinite(level_mm) and math.isfinite(flow_m3h)):
            raise ControlError("mpc: level and discharge must be finite")
        if math.isnan(self.previous_opening_mm) or self._model is None:
            start = self._start_opening_mm
            if start is None:
                start = self._holding_opening_mm(level_mm, flow_m3h)
            self._start(start, level_mm, flow_m3h)
        if setpoint_mm is None:
            if self.setpoint_mm is None:
                self.setpoint_mm = float(level_mm)
            setpoint_mm = self.setpoint_mm
        if not math.isfinite(setpoint_mm):
            raise ControlError("mpc: the set-point must be finite")
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
        self.observer.predict(problem.model, self._applied_mm(opening))
        self.previous_opening_mm, self.previous_gate_mm = opening, gate
        return command


def _resolve_linearisation(plant: Plant, linearisation: str) -> str:
    if linearisation not in LINEARISATIONS:
        raise ControlError(
            f"mpc linearisation must be one of {', '.join(LINEARISATIONS)} (got {linearisation!r})"
        )
    if linearisation == "auto":
        return "envelope" if has_envelope(plant) else "schedule"
    if linearisation == "envelope" and not has_envelope(plant):
        raise ControlError(
            f"mpc: the {plant.kind} plant of gauge {plant.gauge} has no envelope; use the "
            "schedule linearisation"
        )
    if linearisation == "schedule" and isinstance(plant, PhysicalPlant):
        raise ControlError("mpc: a physical plant has no schedule of K, T, L; use the envelope")
    return linearisation


__all__ = ["BACKENDS", "LINEARISATIONS", "MpcController"]
