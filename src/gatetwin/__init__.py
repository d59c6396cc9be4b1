"""gatetwin: control-ready digital-twin models of a canal sluice gate.

From logged step and PRBS tests of a gate (opening in mm, upstream level in mm, discharge
in m³/h) gatetwin identifies FOPDT, ARX and static rating models scheduled on discharge,
exports them as FMI 2.0 co-simulation FMUs, validates them, runs an MPC demo on them and
diagnoses what they miss. A virtual flume produces reference records.

The names below are the public API (see docs/python.md). ``identify``, ``validate`` and
``diagnose`` are functions here; the stage packages behind them are
``gatetwin.identification``, ``gatetwin.validation`` and ``gatetwin.diagnosis``
(``from gatetwin.validation import validate_fmu``).
"""

from gatetwin.api import (
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
from gatetwin.bundled import bundled_records_dir
from gatetwin.errors import (
    ExportError,
    FlumeError,
    GatetwinError,
    IdentificationError,
    ModelFileError,
    RecordError,
)
from gatetwin.records import (
    HoldSegment,
    Record,
    StaticTable,
    StepOnset,
    read_record,
    read_static_table,
    record_from_arrays,
)
from gatetwin.version import __version__

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
