"""The loop an SSP package describes, run by the Python closed loop: the reference its
master's run must equal.

:func:`python_loop` takes the package's own plant FMU and drives it with the Python
controller the controller FMU was generated from (:func:`gatetwin.mpc.demo.pi_controller`),
through :func:`gatetwin.mpc.loop.run_closed_loop`, noise-free and without actuator rounding,
as the package's system has neither.
"""

from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.loop import ClosedLoopRun, Scenario
    from gatetwin.plant.model import Plant


def python_loop(
    package: str | Path, plant: Plant, scenario: Scenario, settings: DemoSettings
) -> ClosedLoopRun:
    """The Python PI against ``package``'s plant FMU over ``scenario`` (the package's)."""
    from gatetwin.mpc.demo import pi_controller
    from gatetwin.mpc.loop import run_closed_loop
    from gatetwin.mpc.plants import FmuCore, LoopPlant
    from gatetwin.ssp.write import PLANT_SOURCE

    with tempfile.TemporaryDirectory(prefix="gatetwin-loop-") as tmp:
        fmu = Path(tmp) / "plant.fmu"
        with zipfile.ZipFile(package) as zf:
            fmu.write_bytes(zf.read(PLANT_SOURCE))
        core = FmuCore(fmu, settings.pi.sample_period_s)
        try:
            return run_closed_loop(LoopPlant(core, noise=None, actuator_resolution_mm=0.0),
                                   pi_controller(plant, settings), scenario,
                                   level_band_mm=None, max_move_mm=settings.mpc.max_move_mm,
                                   opening_range_mm=settings.pi.opening_range_mm,
                                   sample_period_s=settings.pi.sample_period_s)  # fmt: skip
        finally:
            core.cleanup()
