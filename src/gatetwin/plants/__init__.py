"""Plants other than the virtual flume, driven step by step like it.

* :mod:`~gatetwin.plants.swmm` — an EPA SWMM model (through ``pyswmm``, the ``swmm``
  extra): one gate orifice, its gauges, its inflow;
* :mod:`~gatetwin.plants.swmm_experiments` — experiments on such a plant, written as
  records in the record format (step tests sized from the plant's own time constant,
  PRBS, free sequences, the static rating table).

Importing this package needs no optional extra; using a SWMM plant does.
"""

from gatetwin.plants.swmm import SwmmCore, SwmmPlantSpec

__all__ = ["SwmmCore", "SwmmPlantSpec"]
