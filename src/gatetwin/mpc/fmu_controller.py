"""A controller FMU (:mod:`gatetwin.fmu.mpc_controller`) in the closed loop, through fmpy.

:class:`FmuController` has the loop's controller interface
(:class:`gatetwin.mpc.loop.Controller`): ``reset`` instantiates and initialises the FMU at
rest (``start_opening_mm``, the level and discharge measured at the start), ``step`` sets the
inputs, calls ``doStep`` over one sample and returns ``opening_mm``. This module drives an
FMU; it computes nothing of the controller's.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import time
from pathlib import Path

from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.errors import ControlError

#: The controller FMU's outputs, read after every step (``diagnostics``).
OUTPUTS = (
    "opening_mm",
    "predicted_level_mm",
    "active_constraints",
    "solver_status",
    "solver_iterations",
)


class FmuController:
    """The MPC controller FMU as a loop controller (``u = controller.step(y)``).

    Attributes
    ----------
    name : str
        ``"mpc_fmu"``.
    last_solve_s : float
        Wall time of the last ``doStep`` (the whole controller step), s.
    diagnostics : dict[str, float]
        The outputs after the last step (:data:`OUTPUTS`).
    failures : int
        Steps whose ``solver_status`` was 1 (the opening held).
    statuses : list[float]
        ``solver_status`` of every step since the last :meth:`reset`.
    """

    name = "mpc_fmu"

    def __init__(self, fmu_path: str | Path, sample_period_s: float = SAMPLE_PERIOD_S) -> None:
        from fmpy import extract, read_model_description

        self.path = Path(fmu_path)
        self.sample_period_s = sample_period_s
        self._unzipped = extract(str(self.path))
        self._md = read_model_description(self._unzipped)
        self._vr = {v.name: v.valueReference for v in self._md.modelVariables}
        inputs = [v.name for v in self._md.modelVariables if v.causality == "input"]
        levels = [n for n in inputs if n.startswith("level_")]
        if len(levels) != 1 or not set(OUTPUTS) <= set(self._vr):
            raise ControlError(f"{self.path.name}: not an MPC controller FMU")
        self._level = self._vr[levels[0]]
        self._slave = None
        self.time_s = 0.0
        self.last_solve_s = 0.0
        self.failures = 0
        self.statuses: list[float] = []
        self.diagnostics: dict[str, float] = {}

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        """Instantiate and initialise at rest at ``opening_mm``, ``level_mm``, ``flow_m3h``."""
        from fmpy.fmi2 import FMU2Slave

        self.close()
        slave = FMU2Slave(
            guid=self._md.guid,
            unzipDirectory=self._unzipped,
            modelIdentifier=self._md.coSimulation.modelIdentifier,
            instanceName="gatetwin_mpc_controller",
        )
        slave.instantiate(loggingOn=False)
        self._slave = slave
        self.time_s = 0.0
        self.failures = 0
        self.statuses = []
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal([self._vr["start_opening_mm"]], [float(opening_mm)])
        self._set(level_mm, flow_m3h, level_mm)
        slave.exitInitializationMode()

    def _set(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> None:
        vrs = [self._level, self._vr["flow_m3h"], self._vr["setpoint_mm"]]
        self._slave.setReal(vrs, [float(level_mm), float(flow_m3h), float(setpoint_mm)])

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> float:
        """Opening (mm) to hold over the next sample."""
        if self._slave is None:
            raise ControlError("controller fmu: reset() before step()")
        from fmpy.fmi1 import FMICallException

        start = time.perf_counter()
        try:
            self._set(level_mm, flow_m3h, setpoint_mm)
            self._slave.doStep(
                currentCommunicationPoint=self.time_s, communicationStepSize=self.sample_period_s
            )
        except FMICallException as exc:
            raise ControlError(
                f"controller fmu {self.path.name}: step at t = {self.time_s} s refused ({exc})"
            ) from None
        values = self._slave.getReal([self._vr[n] for n in OUTPUTS])
        self.last_solve_s = time.perf_counter() - start
        self.time_s += self.sample_period_s
        self.diagnostics = dict(zip(OUTPUTS, values, strict=True))
        self.statuses.append(self.diagnostics["solver_status"])
        if self.diagnostics["solver_status"] != 0.0:
            self.failures += 1
        opening = float(self.diagnostics["opening_mm"])
        if not math.isfinite(opening):
            raise ControlError(f"controller fmu {self.path.name}: opening {opening} not finite")
        return opening

    def close(self) -> None:
        from fmpy.fmi1 import FMICallException

        if self._slave is not None:
            with contextlib.suppress(FMICallException):  # an instance in error: just free it
                self._slave.terminate()
            self._slave.freeInstance()
            self._slave = None

    def cleanup(self) -> None:
        """Close the instance and delete the extracted FMU."""
        self.close()
        shutil.rmtree(self._unzipped, ignore_errors=True)


__all__ = ["OUTPUTS", "FmuController"]
