"""The one plant object and its Python reference simulation.

A :class:`Plant` holds a gauge's dynamics (FOPDT or ARX), scheduled on discharge, around an
operating point taken from the rating relation. The Python simulator here, the C FMU, the
pythonfmu FMU and the MPC model are renderings of the same object.
"""

from gatetwin.plant.model import ArxPlant, FopdtPlant, Plant, Schedule, plant_from_dict
from gatetwin.plant.simulate import PlantSimulator, simulate

__all__ = [
    "ArxPlant",
    "FopdtPlant",
    "Plant",
    "PlantSimulator",
    "Schedule",
    "plant_from_dict",
    "simulate",
]
