"""A controller FMU in the closed loop: the same ``reset``/``step`` as the Python controllers.

:class:`FmuController` drives a controller FMU, FMI 2.0 or 3.0 (:mod:`gatetwin.fmu.controller`:
inputs ``level_<gauge>_mm``, ``flow_m3h``, ``setpoint_mm``, output ``opening_mm``) through fmpy, so
:func:`gatetwin.mpc.loop.run_closed_loop` runs it exactly as it runs
:class:`~gatetwin.mpc.pi.PiController`. ``reset`` instantiates the FMU at rest
(``start_opening_mm`` = the start opening); ``step`` sets the inputs, takes one
communication step of one sample period and returns the opening of that sample.
"""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path
from typing import Any

from gatetwin.mpc.errors import ControlError

_LEVEL = re.compile(r"level_.+_mm")


class FmuController:
    """A controller FMU through fmpy (co-simulation), one sample per ``step``.

    Parameters
    ----------
    fmu_path : path
        The controller FMU.
    name : str
        Name in the loop's results (default ``"pi_fmu"``).
    """

    def __init__(self, fmu_path: str | Path, name: str = "pi_fmu") -> None:
        from fmpy import extract, read_model_description

        self.path = Path(fmu_path)
        self.name = name
        self.last_solve_s = 0.0
        self._unzipped = extract(str(self.path))
        md = read_model_description(self._unzipped)
        self._md = md
        variables = {v.name: v for v in md.modelVariables}
        self._vr = {n: v.valueReference for n, v in variables.items()}
        levels = [n for n, v in variables.items() if v.causality == "input" and _LEVEL.fullmatch(n)]
        needed = {"flow_m3h", "setpoint_mm", "opening_mm", "start_opening_mm", "sample_period_s"}
        if len(levels) != 1 or not needed <= set(self._vr):
            shutil.rmtree(self._unzipped, ignore_errors=True)
            raise ControlError(
                f"{self.path.name}: not a controller FMU (expected inputs "
                "level_<gauge>_mm, flow_m3h, setpoint_mm, output opening_mm)"
            )
        self._inputs = [self._vr[levels[0]], self._vr["flow_m3h"], self._vr["setpoint_mm"]]
        self.sample_period_s = float(variables["sample_period_s"].start)
        self._fmi3 = md.fmiVersion.startswith("3.")
        self._slave: Any = None
        self.time_s = 0.0

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        """Instantiate at rest at ``opening_mm`` with the set-point at ``level_mm``."""
        from fmpy.fmi1 import FMICallException
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        self.close()
        slave = (FMU3Slave if self._fmi3 else FMU2Slave)(
            guid=self._md.guid,
            unzipDirectory=self._unzipped,
            modelIdentifier=self._md.coSimulation.modelIdentifier,
            instanceName="gatetwin_controller",
        )
        slave.instantiate(loggingOn=False)
        self._slave = slave
        self.time_s = 0.0
        try:
            if self._fmi3:
                slave.enterInitializationMode(startTime=0.0)
            else:
                slave.setupExperiment(startTime=0.0)
                slave.enterInitializationMode()
            self._set([self._vr["start_opening_mm"]], [float(opening_mm)])
            self._set(self._inputs, [float(level_mm), float(flow_m3h), float(level_mm)])
            slave.exitInitializationMode()
        except FMICallException as exc:
            raise ControlError(f"{self.path.name}: reset refused ({exc})") from None

    def _set(self, vrs: list[int], values: list[float]) -> None:
        if self._fmi3:
            self._slave.setFloat64(vrs, values)
        else:
            self._slave.setReal(vrs, values)

    def _get(self, vr: int) -> float:
        get = self._slave.getFloat64 if self._fmi3 else self._slave.getReal
        return float(get([vr])[0])

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> float:
        """Opening (mm) the FMU computes from these inputs, held over the next sample."""
        if self._slave is None:
            raise ControlError(f"{self.path.name}: reset() before step()")
        from fmpy.fmi1 import FMICallException

        start = time.perf_counter()
        try:
            self._set(self._inputs, [float(level_mm), float(flow_m3h), float(setpoint_mm)])
            self._slave.doStep(currentCommunicationPoint=self.time_s,
                               communicationStepSize=self.sample_period_s)  # fmt: skip
            opening = self._get(self._vr["opening_mm"])
        except FMICallException as exc:
            raise ControlError(
                f"{self.path.name}: step at t = {self.time_s} s refused ({exc})"
            ) from None
        self.time_s += self.sample_period_s
        self.last_solve_s = time.perf_counter() - start
        return opening

    def close(self) -> None:
        """Free the instance (terminated first unless a refused call left it in error)."""
        from fmpy.fmi1 import FMICallException

        if self._slave is not None:
            try:
                self._slave.terminate()
            except FMICallException:
                pass  # the instance is in the error state; freeing it is all that is left
            self._slave.freeInstance()
            self._slave = None

    def cleanup(self) -> None:
        """Close and delete the extracted FMU."""
        self.close()
        shutil.rmtree(self._unzipped, ignore_errors=True)


__all__ = ["FmuController"]
