"""Exception classes of gatetwin.

Every error a user can cause by bad input derives from :class:`GatetwinError`, so the
command line can turn it into one clear line and a non-zero exit. Programming errors are
left to propagate as ordinary Python exceptions.
"""

from __future__ import annotations

__all__ = [
    "ControlError",
    "ExportError",
    "FlumeError",
    "GatetwinError",
    "IdentificationError",
    "ModelFileError",
    "NoWindowError",
    "NotSteadyError",
    "OnsetError",
    "OutputError",
    "PipelineError",
    "PlantError",
    "RecordError",
    "ReportError",
    "SimulationError",
    "SspError",
    "ValidationError",
]


class GatetwinError(Exception):
    """Base class of all errors gatetwin reports to a user."""


class RecordError(GatetwinError, ValueError):
    """A record (CSV + optional JSON sidecar) breaks the data-format contract.

    The message names the file and the row or column at fault.
    """


class FlumeError(GatetwinError, ValueError):
    """A virtual-flume scenario or configuration is invalid or physically impossible."""


class IdentificationError(GatetwinError, ValueError):
    """A record cannot support the requested identification method."""


class NoWindowError(IdentificationError):
    """A routine operation history without any informative window (no model from it)."""


class ModelFileError(GatetwinError, ValueError):
    """A model file does not follow the model-file schema."""


class ExportError(GatetwinError, RuntimeError):
    """An FMU could not be built (no compiler, build failure, bad model)."""


class OutputError(GatetwinError, OSError):
    """An output cannot be written (read-only destination, disk full, ...).

    Also an :class:`OSError`, so code catching write failures keeps doing so.
    """


class PipelineError(GatetwinError, RuntimeError):
    """The ``gatetwin run`` pipeline cannot run or cannot write its output directory."""


class SspError(GatetwinError, ValueError):
    """A System Structure package (``.ssp``) cannot be read or simulated; the message names
    the file and the element at fault."""


class PlantError(GatetwinError, ValueError):
    """A plant model (an EPA SWMM ``.inp`` and the names in it) cannot be driven, or a
    needed optional extra is missing; the message names the file and the item at fault."""


class NotSteadyError(PlantError):
    """A plant's spin-up found no steady state; ``low_mm`` is the output gauge's lowest level
    over its last window."""

    def __init__(self, message: str, low_mm: float) -> None:
        super().__init__(message)
        self.low_mm = low_mm

    def __reduce__(self) -> tuple[type, tuple[str, float]]:
        return type(self), (str(self), self.low_mm)


class ValidationError(GatetwinError, ValueError):
    """An FMU, a record or a request that cannot be validated.

    Raised for a file that is not an FMU (not a zip, no ``modelDescription.xml``), an FMU
    without a binary for this platform or without the expected inputs and outputs, an
    FMU that refuses or fails an FMI call during the simulation (the message names the
    call, its status and the FMU's last log line), a record without the gauge the FMU
    computes, and a malformed threshold. It is *not* raised when an FMU simulates but
    misses a threshold: that is a finding, reported in the results.
    """


class ControlError(GatetwinError, ValueError):
    """A controller, model rendering or closed-loop scenario cannot be set up as asked."""


class SimulationError(GatetwinError, ValueError):
    """An input or communication step the plant cannot honour."""


class OnsetError(GatetwinError, ValueError):
    """An effect, parameter or onset that cannot be injected."""


class ReportError(GatetwinError, ValueError):
    """A report part that cannot be rendered (not a PNG, ragged table, unwritable file)."""
