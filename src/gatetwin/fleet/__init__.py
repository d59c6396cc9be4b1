"""Many gates: a synthetic district, and one model set per gate on a pool or a cluster.

:func:`run_fleet` identifies every gate of a set of sources (a folder of gate folders, glob
patterns, a manifest, or records whose sidecars name their ``gate``), one task per gate,
serially, on a local process pool or on a ``dask.distributed`` cluster
(:class:`FleetSettings`), and writes one model set per gate and a fleet summary.
:func:`write_district` generates a synthetic district with known truth. Each gate brings
test records (step tests and a static rating table) like the bundled ones; routine
operation histories (:mod:`gatetwin.fleet.routine`) are generated here too and identified
one at a time by :func:`gatetwin.identification.routine.identify_routine` (a CSV file) or chunk by
chunk by :mod:`gatetwin.identification.routine_chunks` (a Parquet file or a folder of day files).
"""

from gatetwin.fleet.district import GateTruth, district_gates, write_district
from gatetwin.fleet.execute import FleetSettings, default_workers
from gatetwin.fleet.gate import GateJob, identify_gate, run_gates
from gatetwin.fleet.run import run_fleet
from gatetwin.fleet.sources import GateRecords, discover_gates, is_one_records_folder

__all__ = [
    "FleetSettings",
    "GateJob",
    "GateRecords",
    "GateTruth",
    "default_workers",
    "discover_gates",
    "district_gates",
    "identify_gate",
    "is_one_records_folder",
    "run_fleet",
    "run_gates",
    "write_district",
]
