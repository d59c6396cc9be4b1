"""Level control of the gate: CasADi MPC, SIMC PI baseline and the closed-loop demo.

The MPC is built from the same :class:`~gatetwin.plant.model.Plant` object the FMUs are
exported from (scheduled FOPDT or ARX): exact ZOH discretisation with the dead time as a
shift register and the modified z-transform's split of its fractional part
(:mod:`~gatetwin.mpc.discrete`), re-evaluated at each step's measured discharge — or, for
a plant with an envelope, its tangent at the measured discharge and gate position, re-taken
at every step (:mod:`~gatetwin.mpc.envelope`); a Kalman
filter on an input disturbance for offset-free control (:mod:`~gatetwin.mpc.observer`);
a condensed dense QP through casadi's conic plugins (:mod:`~gatetwin.mpc.qp`), checked
against a ``casadi.Opti`` + IPOPT formulation (:mod:`~gatetwin.mpc.opti`). The PI
baseline is tuned by SIMC with python-control margins (:mod:`~gatetwin.mpc.pi`); the
arithmetic of its sample is written once (:mod:`~gatetwin.mpc.pi_law`) and also runs as a
C controller FMU, which :mod:`~gatetwin.mpc.fmu_controller` puts in the loop. Plants
in the loop (FMU, flume, Python model) share one step interface
(:mod:`~gatetwin.mpc.plants`); runs and metrics are in :mod:`~gatetwin.mpc.loop`, the demo
in :mod:`~gatetwin.mpc.demo`. The observer run online on measured data, with an anomaly
flag, is :class:`~gatetwin.mpc.online.OnlineObserver`.

This package controls plants; it does not identify or export them.
"""

from gatetwin.mpc.controller import MpcController
from gatetwin.mpc.demo import (
    DemoSettings,
    compare_controllers,
    demo_plant,
    demo_scenarios,
    envelope_comparison,
    load_demo_plant,
    run_mpc_demo,
    wide_scenario,
)
from gatetwin.mpc.discrete import DiscreteModel, discretise, fopdt_split
from gatetwin.mpc.envelope import linearised_model
from gatetwin.mpc.errors import ControlError
from gatetwin.mpc.loop import ClosedLoopRun, LoopSettings, Scenario, loop_metrics, run_closed_loop
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.online import AnomalySettings, OnlineEstimate, OnlineObserver
from gatetwin.mpc.opti import OptiBackend
from gatetwin.mpc.pi import (
    LoopMargins,
    PiController,
    PiSettings,
    PiTuning,
    loop_margins,
    simc_pi,
    simc_pi_for_plant,
)
from gatetwin.mpc.plants import FlumeCore, FmuCore, LoopPlant, MeasurementNoise, ModelCore
from gatetwin.mpc.qp import MpcProblem, MpcSolution, QpBackend
from gatetwin.mpc.settings import MpcSettings, ObserverSettings

__all__ = [
    "AnomalySettings",
    "ClosedLoopRun",
    "ControlError",
    "DemoSettings",
    "DiscreteModel",
    "DisturbanceObserver",
    "FlumeCore",
    "FmuCore",
    "LoopMargins",
    "LoopPlant",
    "LoopSettings",
    "MeasurementNoise",
    "ModelCore",
    "MpcController",
    "MpcProblem",
    "MpcSettings",
    "MpcSolution",
    "ObserverSettings",
    "OnlineEstimate",
    "OnlineObserver",
    "OptiBackend",
    "PiController",
    "PiSettings",
    "PiTuning",
    "QpBackend",
    "Scenario",
    "compare_controllers",
    "demo_plant",
    "demo_scenarios",
    "discretise",
    "envelope_comparison",
    "fopdt_split",
    "linearised_model",
    "load_demo_plant",
    "loop_margins",
    "loop_metrics",
    "run_closed_loop",
    "run_mpc_demo",
    "simc_pi",
    "simc_pi_for_plant",
    "wide_scenario",
]
