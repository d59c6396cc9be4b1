"""Identification: FOPDT models from step tests, ARX models from PRBS tests.

Layout (one concept per module):

* :mod:`~gatetwin.identification.preprocess` -- segments, NaN splitting, Hampel spike filter,
  opening reconstruction during actuator motion, hold-out split;
* :mod:`~gatetwin.identification.fopdt` -- the reference study's step method and the
  least-squares FOPDT fit, on arrays;
* :mod:`~gatetwin.identification.step` -- step identification of a record (every gauge);
* :mod:`~gatetwin.identification.lagproducts` -- normal equations from lagged dot products;
* :mod:`~gatetwin.identification.arx` -- ARX fit, one-step prediction, free-run simulation;
* :mod:`~gatetwin.identification.metrics` -- fit metrics, residual whiteness, poles;
* :mod:`~gatetwin.identification.orders` -- order search and choice;
* :mod:`~gatetwin.identification.prbs` -- PRBS identification of a record;
* :mod:`~gatetwin.identification.pem`, :mod:`~gatetwin.identification.pemfit` -- prediction-error
  fits of the polynomial family (innovations, minimisation, the fitted model);
* :mod:`~gatetwin.identification.oe`, :mod:`~gatetwin.identification.armax`,
  :mod:`~gatetwin.identification.bj` -- output-error, ARMAX and Box-Jenkins fits;
* :mod:`~gatetwin.identification.discrete_select` -- the structure that simulates best;
* :mod:`~gatetwin.identification.routine` -- FOPDT windows and a schedule on Q from a routine
  operation history (no designed test); :mod:`~gatetwin.identification.routine_chunks` -- the
  same from a history read a chunk at a time.
"""

from gatetwin.identification.armax import fit_armax
from gatetwin.identification.arx import ArxFit, fit_arx, predict_one_step, simulate_free
from gatetwin.identification.bj import fit_bj
from gatetwin.identification.discrete_select import DiscreteSelection, select_discrete
from gatetwin.identification.fopdt import FopdtFit, PaperStepResult, fit_fopdt, paper_step_method
from gatetwin.identification.metrics import (
    DominantPole,
    OneStepMetrics,
    SimulationMetrics,
    Whiteness,
    arx_poles,
    dc_gain,
    dominant_pole,
    free_run_on_segments,
    is_stable,
    one_step_metrics,
    residual_whiteness,
    simulation_metrics,
)
from gatetwin.identification.oe import fit_oe
from gatetwin.identification.orders import OrderChoice, OrderRow, choose, search_orders
from gatetwin.identification.pemfit import PemFit
from gatetwin.identification.prbs import PrbsIdentification, identify_prbs
from gatetwin.identification.preprocess import (
    SpikeCorrection,
    continuous_segments,
    hampel_filter,
    holdout_split,
    reconstructed_opening,
    record_segments,
    split_segments,
)
from gatetwin.identification.routine import RoutineIdentification, WindowCriteria, identify_routine
from gatetwin.identification.routine_chunks import identify_routine_chunked
from gatetwin.identification.step import GaugeStep, StepIdentification, identify_step

__all__ = [
    "ArxFit",
    "DiscreteSelection",
    "DominantPole",
    "FopdtFit",
    "GaugeStep",
    "OneStepMetrics",
    "OrderChoice",
    "OrderRow",
    "PaperStepResult",
    "PemFit",
    "PrbsIdentification",
    "RoutineIdentification",
    "SimulationMetrics",
    "SpikeCorrection",
    "StepIdentification",
    "Whiteness",
    "WindowCriteria",
    "arx_poles",
    "choose",
    "continuous_segments",
    "dc_gain",
    "dominant_pole",
    "fit_armax",
    "fit_arx",
    "fit_bj",
    "fit_fopdt",
    "fit_oe",
    "free_run_on_segments",
    "hampel_filter",
    "holdout_split",
    "identify_prbs",
    "identify_routine",
    "identify_routine_chunked",
    "identify_step",
    "is_stable",
    "one_step_metrics",
    "paper_step_method",
    "predict_one_step",
    "reconstructed_opening",
    "record_segments",
    "residual_whiteness",
    "search_orders",
    "select_discrete",
    "simulate_free",
    "simulation_metrics",
    "split_segments",
]
