"""Reading, checking and segmenting records: what every command reads first.

A record is a CSV or Parquet file in the format of ``docs/record_format.md`` plus an optional
JSON sidecar; a rating table is a CSV of steady operating points. The layers, each a
module of this package:

* :mod:`~gatetwin.records.limits` — which files are opened (regular files within size
  and line-length limits);
* :mod:`~gatetwin.records.arrow_csv`, :mod:`~gatetwin.records.csvtext`,
  :mod:`~gatetwin.records.parquet`, :mod:`~gatetwin.records.table` — files to columns;
* :mod:`~gatetwin.records.units` — units named in column suffixes, converted to mm and
  m³/h (:data:`UNIT_FACTORS`);
* :mod:`~gatetwin.records.sidecar`, :mod:`~gatetwin.records.bounds` — the JSON sidecar and
  the value ranges it may set;
* :mod:`~gatetwin.records.checks` — value checks and physical bounds;
* :mod:`~gatetwin.records.segments` — hold segments, steps, test type;
* :mod:`~gatetwin.records.record`, :mod:`~gatetwin.records.static` — the frozen results;
* :mod:`~gatetwin.records.summary` — what ``gatetwin check`` prints.

Nothing here identifies a model.
"""

from __future__ import annotations

from gatetwin.records.bounds import Bounds
from gatetwin.records.checks import (
    FLOW_MAX_M3H,
    GAP_MAX_S,
    LEVEL_RANGE_MM,
    OPENING_MAX_MM,
    SAMPLE_PERIOD_RANGE_S,
    TIME_ABS_MAX_S,
)
from gatetwin.records.columns import gauge_of_column
from gatetwin.records.limits import ReadLimits
from gatetwin.records.record import (
    HoldSegment,
    Record,
    StepOnset,
    read_record,
    record_from_arrays,
)
from gatetwin.records.segments import (
    GAP_FACTOR,
    PRBS_MIN_STEPS,
    PRBS_MIN_USABLE_SAMPLES,
    RESOLUTION_MM,
    STEP_WINDOW_SAMPLES,
)
from gatetwin.records.sidecar import TEST_TYPES, VALIDATION_ROLE
from gatetwin.records.static import StaticTable, detect_table_kind, read_static_table
from gatetwin.records.units import FACTORS as UNIT_FACTORS

__all__ = [
    "FLOW_MAX_M3H",
    "GAP_FACTOR",
    "GAP_MAX_S",
    "LEVEL_RANGE_MM",
    "OPENING_MAX_MM",
    "PRBS_MIN_STEPS",
    "PRBS_MIN_USABLE_SAMPLES",
    "RESOLUTION_MM",
    "SAMPLE_PERIOD_RANGE_S",
    "STEP_WINDOW_SAMPLES",
    "TEST_TYPES",
    "TIME_ABS_MAX_S",
    "UNIT_FACTORS",
    "VALIDATION_ROLE",
    "Bounds",
    "HoldSegment",
    "ReadLimits",
    "Record",
    "StaticTable",
    "StepOnset",
    "detect_table_kind",
    "gauge_of_column",
    "read_record",
    "read_static_table",
    "record_from_arrays",
]
