"""Identification: FOPDT models from step tests, ARX models from PRBS tests.

Layout (one concept per module):

* :mod:`~gatetwin.identify.preprocess` -- segments, NaN splitting, Hampel spike filter,
  opening reconstruction during actuator motion, hold-out split;
* :mod:`~gatetwin.identify.fopdt` -- the reference study's step method and the
  least-squares FOPDT fit, on arrays;
* :mod:`~gatetwin.identify.step` -- step identification of a record (every gauge);
* :mod:`~gatetwin.identify.lagproducts` -- normal equations from lagged dot products;
* :mod:`~gatetwin.identify.arx` -- ARX fit, one-step prediction, free-run simulation;
* :mod:`~gatetwin.identify.metrics` -- fit metrics, residual whiteness, poles;
* :mod:`~gatetwin.identify.orders` -- order search and choice;
* :mod:`~gatetwin.identify.prbs` -- PRBS identification of a record;
* :mod:`~gatetwin.identify.pem`, :mod:`~gatetwin.identify.pemfit` -- prediction-error
  fits of the polynomial family (innovations, minimisation, the fitted model);
* :mod:`~gatetwin.identify.oe`, :mod:`~gatetwin.identify.armax`,
  :mod:`~gatetwin.identify.bj` -- output-error, ARMAX and Box-Jenkins fits;
* :mod:`~gatetwin.identify.discrete_select` -- the structure that simulates best;
* :mod:`~gatetwin.identify.routine` -- FOPDT windows and a schedule on Q from a routine
  operation history (no designed test); :mod:`~gatetwin.identify.routine_chunks` -- the
  same from a history read a chunk at a time.
"""

from gatetwin.identify.armax import fit_armax
from gatetwin.identify.arx import ArxFit, fit_arx, predict_one_step, simulate_free
from gatetwin.identify.bj import fit_bj
from gatetwin.identify.discrete_select import DiscreteSelection, select_discrete
from gatetwin.identify.fopdt import FopdtFit, PaperStepResult, fit_fopdt, paper_step_method
from gatetwin.identify.metrics import (
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
from gatetwin.identify.oe import fit_oe
from gatetwin.identify.orders import OrderChoice, OrderRow, choose, search_orders
from gatetwin.identify.pemfit import PemFit
from gatetwin.identify.prbs import PrbsIdentification, identify_prbs
from gatetwin.identify.preprocess import (
    SpikeCorrection,
    continuous_segments,
    hampel_filter,
    holdout_split,
    reconstructed_opening,
    record_segments,
    split_segments,
)
from gatetwin.identify.routine import RoutineIdentification, WindowCriteria, identify_routine
from gatetwin.identify.routine_chunks import identify_routine_chunked
from gatetwin.identify.step import GaugeStep, StepIdentification, identify_step

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
