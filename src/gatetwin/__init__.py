"""gatetwin: control-ready digital-twin models of a canal sluice gate.

From logged step and PRBS tests of a gate (opening in mm, upstream level in mm, discharge
in m³/h) gatetwin identifies FOPDT, ARX and static rating models scheduled on discharge,
exports them as FMI 2.0 co-simulation FMUs, validates them, runs an MPC demo on them and
diagnoses what they miss. A virtual flume produces reference records.
"""

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

__version__ = "0.1.0"

__all__ = [
    "ExportError",
    "FlumeError",
    "GatetwinError",
    "HoldSegment",
    "IdentificationError",
    "ModelFileError",
    "Record",
    "RecordError",
    "StaticTable",
    "StepOnset",
    "__version__",
    "read_record",
    "read_static_table",
    "record_from_arrays",
]
