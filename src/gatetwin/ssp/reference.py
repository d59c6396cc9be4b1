"""The loop an SSP package describes, run by the Python closed loop: the reference its
master's run must equal.

:func:`python_loop` takes the package's own plant FMU and drives it with the Python
controller the controller FMU was generated from (the PI of
:func:`gatetwin.mpc.demo.pi_controller`, or the :class:`~gatetwin.mpc.MpcController` with
``linearisation="schedule"``: both solve the same strictly convex QP to its unique
solution, the FMU with its own dense active-set solver, Python with DAQP), through
:func:`gatetwin.mpc.loop.run_closed_loop`, noise-free and without actuator rounding, as the
package's system has neither.
"""

from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.loop import ClosedLoopRun, Scenario
    from gatetwin.plant.model import Plant

__all__ = ["python_loop"]


def python_loop(
    package: str | Path, plant: Plant, scenario: Scenario, settings: DemoSettings,
    controller: str = "pi",
) -> ClosedLoopRun:  # fmt: skip
    """The Python controller (``"pi"`` or ``"mpc"``, built from ``plant``: for the MPC, the
    FOPDT the package's MPC FMU was built on) against ``package``'s plant FMU over
    ``scenario`` (the package's)."""
    from gatetwin.mpc.loop import run_closed_loop
    from gatetwin.mpc.plants import FmuCore, LoopPlant
    from gatetwin.ssp.write import PLANT_SOURCE

    law, limits = _controller(plant, settings, controller)
    with tempfile.TemporaryDirectory(prefix="gatetwin-loop-") as tmp:
        fmu = Path(tmp) / "plant.fmu"
        with zipfile.ZipFile(package) as zf:
            fmu.write_bytes(zf.read(PLANT_SOURCE))
        core = FmuCore(fmu, limits["sample_period_s"])
        try:
            return run_closed_loop(LoopPlant(core, noise=None, actuator_resolution_mm=0.0),
                                   law, scenario, **limits)  # fmt: skip
        finally:
            core.cleanup()


def _controller(plant: Plant, settings: DemoSettings, kind: str) -> tuple[Any, dict[str, Any]]:
    """The Python controller and the loop's limits (as the demo scores each controller)."""
    from gatetwin.fmu.controller import check_controller_kind
    from gatetwin.mpc.controller import MpcController
    from gatetwin.mpc.demo import pi_controller

    check_controller_kind(kind)
    if kind == "pi":
        return pi_controller(plant, settings), {
            "level_band_mm": None, "max_move_mm": settings.mpc.max_move_mm,
            "opening_range_mm": settings.pi.opening_range_mm,
            "sample_period_s": settings.pi.sample_period_s,
        }  # fmt: skip
    s = settings.mpc
    return MpcController(plant, s, linearisation="schedule"), {
        "level_band_mm": s.level_band_mm, "max_move_mm": s.max_move_mm,
        "opening_range_mm": s.opening_range_mm, "sample_period_s": s.sample_period_s,
    }  # fmt: skip
