"""What the observer tests share: the physical plant they observe, the flume record outside
both the bundled and the calibration sets, and a run of FMU steps on measured inputs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gatetwin.flume.envelope import random_moves_scenario
from gatetwin.modelfile import read_model_file

ROOT = Path(__file__).resolve().parents[1]
#: A seed neither the bundled records (101-116) nor the calibration records (901-909) use.
SEED = 1301


def envelope_plant():
    """physical_3F with its effect blocks dropped: the observers' plant."""
    return dataclasses.replace(read_model_file(ROOT / "models/physical_3F.json").plant,
                               effects=())  # fmt: skip


def flume_scenario():
    """Six random gate moves at 50 m3/h (1120 s) on the virtual flume, seed SEED."""
    return random_moves_scenario("T50", 50.0, SEED, n_moves=6)


def held_opening(opening: np.ndarray) -> np.ndarray:
    """The logged opening with each empty sample given the next known one (the last known
    one at the end), as gatetwin.mpc.online.measured_inputs holds it."""
    known = np.flatnonzero(np.isfinite(opening))
    return opening[known[np.minimum(np.searchsorted(known, np.arange(opening.size)),
                                    known.size - 1)]]  # fmt: skip


def observer_steps(slave, vr, outputs, y, e, q, first: int, n: int = 20) -> list[list[float]]:
    """``n`` communication steps of one sample (1.2 s) from sample ``first`` on the measured
    level at 3F, opening and discharge; the outputs after each."""
    inputs = [vr["level_3F_mm"], vr["opening_mm"], vr["flow_m3h"]]
    outs = [vr[name] for name in outputs]
    rows = []
    for k in range(first, first + n):
        slave.setReal(inputs, [float(y[k]), float(e[k]), float(q[k])])
        slave.doStep(currentCommunicationPoint=k * 1.2, communicationStepSize=1.2)
        rows.append(slave.getReal(outs))
    return rows
