"""The closed loop as an SSP 1.0 System Structure package, and a master that runs one.

:func:`write_ssp` packs a model's plant FMU, controller FMU and scenario FMU (the set-point
and discharge tables, :mod:`gatetwin.fmu.signal_source`) with a ``SystemStructure.ssd``
connecting them and a parameter set of their start values (:mod:`gatetwin.ssp.write`);
:func:`simulate_ssp` runs such a package with gatetwin's own fixed-step master through fmpy,
Gauss-Seidel or Jacobi (:mod:`gatetwin.ssp.master`). :func:`write_observer_ssp` packs the
observer FMU with a scenario FMU playing a measured record
(:mod:`gatetwin.ssp.observed_record`). The documents are checked against the SSP 1.0 schemas
fmpy ships (:mod:`gatetwin.ssp.documents`).
"""

from gatetwin.ssp.master import SspRun, simulate_ssp
from gatetwin.ssp.observed_record import write_observer_ssp
from gatetwin.ssp.write import write_ssp

__all__ = ["SspRun", "simulate_ssp", "write_observer_ssp", "write_ssp"]
