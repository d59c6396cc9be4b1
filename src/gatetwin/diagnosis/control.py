"""Does the augmented model control? The named effect in the MPC, against a blind one.

An augmented model is rendered in the MPC like any plant (:mod:`gatetwin.mpc`): its output
blocks as model states, its input blocks on the command. :func:`control_check` runs the
same noise-free set-point step twice on the augmented plant (its Python reference as the
process): once with the MPC built from the augmented model, once with the MPC built from
the same plant without the block (the refitted baseline), and reports both runs' scores
(:func:`gatetwin.mpc.loop_metrics`). What the effect costs a controller that ignores it
is the difference.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Any

import numpy as np

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.errors import GatetwinError
from gatetwin.plant.model import Plant

#: Set-point step of the check, mm: a few times the gauge noise and a fraction of a
#: condition's operating range, small enough to stay inside the model's opening band.
SETPOINT_STEP_MM = 10.0
#: Length of the check, s: the step at 60 s, then > 3 T of the slowest condition (~70 s).
DURATION_S = 600.0
#: Scores kept in the JSON.
KEYS = ("iae", "max_dev_mm", "settling_s", "overshoot_mm", "final_error_mm", "travel_mm",
        "command_travel_mm", "violations")  # fmt: skip


def _run(model: Plant, process: Plant, opening_mm: float, flow_m3h: float) -> dict[str, Any]:
    from gatetwin.mpc import (
        LoopPlant,
        ModelCore,
        MpcController,
        MpcSettings,
        Scenario,
        loop_metrics,
        run_closed_loop,
    )

    settings = MpcSettings(horizon=80, level_band_mm=None)
    loop = LoopPlant(ModelCore(process), noise=None, actuator_resolution_mm=0.0)
    scenario = Scenario("diagnosis_check", DURATION_S, flow_m3h=flow_m3h, opening_mm=opening_mm,
                        setpoint_changes=((60.0, SETPOINT_STEP_MM),))  # fmt: skip
    run = run_closed_loop(
        loop, MpcController(model, settings), scenario, level_band_mm=None,
        max_move_mm=settings.max_move_mm, opening_range_mm=settings.opening_range_mm,
    )  # fmt: skip
    metrics = loop_metrics(run)
    return {k: metrics[k] for k in KEYS}


def control_check(plant: Plant, data: DiagnosisData) -> dict[str, Any]:
    """Closed-loop scores of the augmented and the blind MPC on the augmented plant.

    Returns ``{"setpoint_step_mm", "duration_s", "opening_mm", "flow_m3h", "augmented_mpc",
    "blind_mpc"}``, or ``{"error": reason}`` when the plant cannot be controlled at the
    MPC's period (an ARX model sampled at another period) or the loop fails.
    """
    opening = float(data.command_mm[0])
    flow = float(np.median(data.flow_m3h))
    out: dict[str, Any] = {"setpoint_step_mm": SETPOINT_STEP_MM, "duration_s": DURATION_S,
                           "opening_mm": opening, "flow_m3h": flow}  # fmt: skip
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # Q outside the schedule: clamped
            out["augmented_mpc"] = _run(plant, plant, opening, flow)
            out["blind_mpc"] = _run(replace(plant, effects=()), plant, opening, flow)
    except GatetwinError as exc:
        return {"error": str(exc)}
    return out


__all__ = ["control_check"]
