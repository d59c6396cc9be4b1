"""gatetwin: control-ready digital-twin models of a canal sluice gate.

From logged step and PRBS tests of a gate (opening in mm, upstream level in mm, discharge
in m³/h) gatetwin identifies FOPDT, ARX and static rating models scheduled on discharge,
exports them as FMI 2.0 co-simulation FMUs, validates them, runs an MPC demo on them and
diagnoses what they miss. A virtual flume produces reference records.

The names below are the public API (see docs/python.md). ``identify``, ``validate`` and
``diagnose`` are functions here and, by their full names, the stage packages behind them:
``from gatetwin.validate import validate_fmu`` reaches the package.
"""

import sys as _sys
import types as _types

from gatetwin.api import (  # noqa: E402
    Diagnosis,
    Model,
    ModelSet,
    OperatingPoint,
    SimulationResult,
    ValidationReport,
    diagnose,
    identify,
    identify_folder,
    load_model,
    validate,
)
from gatetwin.bundled import bundled_records_dir  # noqa: E402
from gatetwin.errors import (  # noqa: E402
    ExportError,
    FlumeError,
    GatetwinError,
    IdentificationError,
    ModelFileError,
    RecordError,
)
from gatetwin.records import (  # noqa: E402
    HoldSegment,
    Record,
    StaticTable,
    StepOnset,
    read_record,
    read_static_table,
    record_from_arrays,
)
from gatetwin.version import __version__  # noqa: E402

__all__ = [
    "Diagnosis",
    "ExportError",
    "FlumeError",
    "GatetwinError",
    "HoldSegment",
    "IdentificationError",
    "Model",
    "ModelFileError",
    "ModelSet",
    "OperatingPoint",
    "Record",
    "RecordError",
    "SimulationResult",
    "StaticTable",
    "StepOnset",
    "ValidationReport",
    "__version__",
    "bundled_records_dir",
    "diagnose",
    "identify",
    "identify_folder",
    "load_model",
    "read_record",
    "read_static_table",
    "record_from_arrays",
    "validate",
]

#: API functions named like a stage package; importing the package must not replace them.
_FUNCTIONS_NAMED_LIKE_PACKAGES = frozenset({"diagnose", "identify", "validate"})


class _Package(_types.ModuleType):
    """The module type of ``gatetwin``.

    Importing a submodule binds it as an attribute of its parent package; for
    ``gatetwin.identify``, ``gatetwin.validate`` and ``gatetwin.diagnose`` that would
    replace the API function of the same name. This type keeps the function; the packages
    stay reachable through ``sys.modules``, that is by every ``from gatetwin.X import Y``
    and ``import gatetwin.X.Y``.
    """

    def __setattr__(self, name: str, value: object) -> None:
        if name in _FUNCTIONS_NAMED_LIKE_PACKAGES and isinstance(value, _types.ModuleType):
            return
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package
