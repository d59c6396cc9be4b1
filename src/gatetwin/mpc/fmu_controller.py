"""A controller FMU in the closed loop: the same ``reset``/``step`` as the Python controllers.

:class:`FmuController` drives a controller FMU — the PI (:mod:`gatetwin.fmu.controller`,
FMI 2.0 or 3.0) or the MPC (:mod:`gatetwin.fmu.mpc_controller`): inputs
``level_<gauge>_mm``, ``flow_m3h``, ``setpoint_mm``, output ``opening_mm`` — through fmpy,
so :func:`gatetwin.mpc.loop.run_closed_loop` runs it exactly as it runs
:class:`~gatetwin.mpc.pi.PiController`. ``reset`` instantiates the FMU at rest
(``start_opening_mm`` = the start opening, the level and discharge measured at the start);
``step`` sets the inputs, takes one communication step of one sample period and returns the
opening of that sample. This module drives an FMU; it computes nothing of the controller's.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path
from typing import Any

from gatetwin.errors import ControlError
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S

#: Outputs a controller FMU may have, read after every step (``diagnostics``): the command,
#: and the MPC's predicted level, active constraints, solver status and iterations.
OUTPUTS = (
    "opening_mm",
    "predicted_level_mm",
    "active_constraints",
    "solver_status",
    "solver_iterations",
)
_LEVEL = re.compile(r"level_.+_mm")


class FmuController:
    """A controller FMU through fmpy (co-simulation), one sample per ``step``.

    Parameters
    ----------
    fmu_path : path
        The controller FMU.
    sample_period_s : float, optional
        Communication step; default the FMU's ``sample_period_s`` parameter, else its
        default experiment's step size, else the
        controllers' sample period.
    name : str, optional
        Name in the loop's results (default ``"mpc_fmu"`` for an FMU with a solver status,
        else ``"pi_fmu"``).

    Attributes
    ----------
    last_solve_s : float
        Wall time of the last ``doStep`` (the whole controller step), s.
    diagnostics : dict[str, float]
        The outputs of :data:`OUTPUTS` the FMU has, after the last step.
    failures : int
        Steps whose ``solver_status`` was not 0 (the MPC held the opening).
    statuses : list[float]
        ``solver_status`` of every step since the last :meth:`reset` (MPC).
    """

    def __init__(self, fmu_path: str | Path, sample_period_s: float | None = None,
                 name: str | None = None) -> None:  # fmt: skip
        from gatetwin.fmi_host import UnpackedFmu

        self.path = Path(fmu_path)
        self._fmu = UnpackedFmu(self.path, error=ControlError)
        md, variables, self._vr = self._fmu.description, self._fmu.variables, self._fmu.vr
        levels = [n for n, v in variables.items() if v.causality == "input" and _LEVEL.fullmatch(n)]
        needed = {"flow_m3h", "setpoint_mm", "opening_mm", "start_opening_mm"}
        if len(levels) != 1 or not needed <= set(self._vr):
            self._fmu.cleanup()
            raise ControlError(
                f"{self.path.name}: not a controller FMU (expected inputs "
                "level_<gauge>_mm, flow_m3h, setpoint_mm, output opening_mm)"
            )
        self._inputs = [self._vr[levels[0]], self._vr["flow_m3h"], self._vr["setpoint_mm"]]
        self._outputs = [n for n in OUTPUTS if n in self._vr]
        own = variables.get("sample_period_s")
        default = float(own.start) if own is not None and own.start is not None else None
        experiment = md.defaultExperiment
        step = experiment.stepSize if experiment is not None else None
        self.sample_period_s = sample_period_s or default or (step and float(step)) \
            or SAMPLE_PERIOD_S  # fmt: skip
        self.name = name or ("mpc_fmu" if "solver_status" in self._vr else "pi_fmu")
        self.time_s = 0.0
        self.last_solve_s = 0.0
        self.failures = 0
        self.statuses: list[float] = []
        self.diagnostics: dict[str, float] = {}

    @property
    def _slave(self) -> Any:
        """The open instance (``None`` before the first start or after a refused one)."""
        return self._fmu.instance

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        """Instantiate at rest at ``opening_mm`` with the set-point at ``level_mm``."""
        from fmpy.fmi1 import FMICallException

        slave = self._fmu.open("gatetwin_controller")
        self.time_s = 0.0
        self.failures = 0
        self.statuses = []
        try:
            slave.initialise(0.0, ([self._vr["start_opening_mm"]], [opening_mm]),
                             (self._inputs, [level_mm, flow_m3h, level_mm]))  # fmt: skip
        except FMICallException as exc:
            raise ControlError(f"{self.path.name}: reset refused ({exc}){_logged(slave)}") from None

    def _set(self, vrs: list[int], values: list[float]) -> None:
        self._slave.setReal(vrs, values)

    def _get(self, vrs: list[int]) -> list[float]:
        return [float(v) for v in self._slave.getReal(vrs)]

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
            values = self._get([self._vr[n] for n in self._outputs])
        except FMICallException as exc:
            raise ControlError(
                f"{self.path.name}: step at t = {self.time_s} s refused ({exc})"
                + _logged(self._slave)
            ) from None
        self.last_solve_s = time.perf_counter() - start
        self.time_s += self.sample_period_s
        self.diagnostics = dict(zip(self._outputs, values, strict=True))
        if "solver_status" in self.diagnostics:
            self.statuses.append(self.diagnostics["solver_status"])
            self.failures += self.diagnostics["solver_status"] != 0.0
        opening = self.diagnostics["opening_mm"]
        if not math.isfinite(opening):
            raise ControlError(f"{self.path.name}: opening {opening} is not finite")
        return opening

    def close(self) -> None:
        """Free the instance (terminated first unless a refused call left it in error)."""
        self._fmu.close()

    def cleanup(self) -> None:
        """Close the instance and delete the extracted FMU."""
        self._fmu.cleanup()


def _logged(slave: Any) -> str:
    """``; FMU log: …`` with the FMU's last warning or error, or ""."""
    detail = slave.last_problem()
    return f"; FMU log: {detail[:300]}" if detail else ""


__all__ = ["OUTPUTS", "FmuController"]
