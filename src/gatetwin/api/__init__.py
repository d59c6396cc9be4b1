"""The Python API: read, identify, simulate, export, validate and diagnose in a few calls.

Everything here is re-exported by :mod:`gatetwin` (``gatetwin.identify(...)``,
``gatetwin.Model``); the work itself is done by the stage packages (:mod:`gatetwin.identification`,
:mod:`gatetwin.plant`, :mod:`gatetwin.fmu`, :mod:`gatetwin.validation`,
:mod:`gatetwin.diagnosis`). This package adds no arithmetic, only plain objects and calls.
"""

from gatetwin.api._diagnosis import Diagnosis, diagnose
from gatetwin.api._identify import identify, identify_folder
from gatetwin.api._model import Model, ModelSet, OperatingPoint, load_model
from gatetwin.api._simulation import SimulationResult
from gatetwin.api._validation import ValidationReport, validate

__all__ = [
    "Diagnosis",
    "Model",
    "ModelSet",
    "OperatingPoint",
    "SimulationResult",
    "ValidationReport",
    "diagnose",
    "identify",
    "identify_folder",
    "load_model",
    "validate",
]
