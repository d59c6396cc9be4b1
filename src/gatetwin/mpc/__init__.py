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

from __future__ import annotations

import importlib
from typing import Any

from gatetwin.errors import ControlError as ControlError

#: The public names, by the submodule that defines them. They are imported on first use:
#: the command line reads constants of :mod:`~gatetwin.mpc.online` for its help and must
#: not pay for python-control and CasADi, which the loop and the PI import.
_SOURCES: dict[str, tuple[str, ...]] = {
    "controller": ("MpcController",),
    "demo": (
        "DemoSettings",
        "compare_controllers",
        "demo_plant",
        "demo_scenarios",
        "envelope_comparison",
        "load_demo_plant",
        "run_mpc_demo",
        "wide_scenario",
    ),
    "discrete": (
        "DiscreteModel",
        "discretise",
        "fopdt_split",
    ),
    "envelope": ("linearised_model",),
    "loop": (
        "ClosedLoopRun",
        "LoopSettings",
        "Scenario",
        "loop_metrics",
        "run_closed_loop",
    ),
    "observer": ("DisturbanceObserver",),
    "online": (
        "AnomalySettings",
        "OnlineEstimate",
        "OnlineObserver",
    ),
    "opti": ("OptiBackend",),
    "pi": (
        "LoopMargins",
        "PiController",
        "PiSettings",
        "PiTuning",
        "loop_margins",
        "simc_pi",
        "simc_pi_for_plant",
    ),
    "plants": (
        "FlumeCore",
        "FmuCore",
        "LoopPlant",
        "MeasurementNoise",
        "ModelCore",
    ),
    "qp": (
        "MpcProblem",
        "MpcSolution",
        "QpBackend",
    ),
    "settings": (
        "MpcSettings",
        "ObserverSettings",
    ),
}
_MODULE_OF = {name: module for module, names in _SOURCES.items() for name in names}

__all__ = sorted([*_MODULE_OF, "ControlError"])


def __getattr__(name: str) -> Any:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
