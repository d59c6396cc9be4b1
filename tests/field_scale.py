"""A field-scale gate as synthetic truth: records a canal's logger would write.

A 1.5 m wide sluice gate below a pool of 3000 m² passing about 2 m³/s at openings near
0.4 m (depth about 1.6 m at the gate), sampled every 10 s; the pool's time constant is about
an hour and a quarter. The truth is :class:`gatetwin.plant.model.PhysicalPlant` itself, so
identification can be held against known parameters. Records are written as the record
format asks (mm, m³/h, one CSV and its sidecar each, with ``gate_width_m``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gatetwin.plant.model import PhysicalPlant, Schedule
from gatetwin.plant.physical import PhysicalSimulator

SAMPLE_PERIOD_S = 10.0
GAUGE = "P1"
#: Gauges' distances upstream of the gate, m; P2 also reads the pool, with more noise.
GAUGES_M = {"P1": 40.0, "P2": 400.0}
WIDTH_M = 1.5
AREA_M2 = 3000.0
#: Level noise (gauge SD, mm) and inflow noise (fraction of the flow, SD).
LEVEL_SD_MM = {"P1": 2.0, "P2": 6.0}
FLOW_SD_FRACTION = 0.005
#: Each hold lasts this long: about five time constants (settled).
HOLD_S = 6.0 * 3600.0

TRUTH = {
    "cd_small": 0.61, "cd_small_per_q": 0.0, "cd_large": 0.50, "cd_large_per_q": 0.0,
    "cd_mid_log_ratio": -0.9, "cd_mid_per_q": 0.0, "cd_log_width": -0.5,
    "cd_log_width_per_q": 0.0, "cd_log_shape": 0.0, "width_m": WIDTH_M, "offset_mm": 50.0,
    "offset_per_flow2_mm": 0.0, "area_m2": AREA_M2, "area_per_depth_m": 0.0,
    "speed_mm_s": 4.0, "stall_depth_m": 12.0, "resolution_mm": 1.0, "max_substep_s": 5.0,
    "flow_centre_m3h": 7200.0, "flow_scale_m3h": 10000.0, "depth_max_m": 16.0,
}  # fmt: skip


def truth_plant() -> PhysicalPlant:
    """The field gate (one gauge; P2 reads the same pool)."""
    return PhysicalPlant(GAUGE, dict(TRUTH), Schedule((3600.0, 10800.0),
                                                       {"level_ref_mm": (0.0, 0.0)}))  # fmt: skip


def _simulate(plant: PhysicalPlant, command: np.ndarray, flow: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Level (mm) and gate position (mm) at every sample, inputs held between samples."""
    sim = PhysicalSimulator(plant)
    sim.initialize(float(command[0]), float(flow[0]))
    level, gate = [sim.level_mm], [sim.gate_mm]
    for k in range(1, command.size):
        level.append(sim.do_step(SAMPLE_PERIOD_S, float(command[k - 1]), float(flow[k - 1])))
        gate.append(sim.gate_mm)
    return np.asarray(level), np.asarray(gate)


def write_record(folder: Path, name: str, command: np.ndarray, flow_m3h: np.ndarray,
                 rng: np.random.Generator, sidecar: dict) -> Path:  # fmt: skip
    """Simulate the truth on the inputs and write ``name``.csv/.json as a logger would."""
    plant = truth_plant()
    level, gate = _simulate(plant, command, flow_m3h)
    time_s = np.arange(command.size) * SAMPLE_PERIOD_S
    moving = np.abs(gate - np.round(command)) > 1e-9
    lines = ["time_s,opening_mm,state,flow_m3h," + ",".join(f"level_{g}_mm" for g in GAUGES_M)]
    flow_read = flow_m3h * (1.0 + FLOW_SD_FRACTION * rng.standard_normal(flow_m3h.size))
    for k in range(command.size):
        levels = [level[k] + LEVEL_SD_MM[g] * rng.standard_normal() for g in GAUGES_M]
        opening = "" if moving[k] else f"{gate[k]:.0f}"
        state = "open" if moving[k] else "hold"
        lines.append(f"{time_s[k]:.1f},{opening},{state},{flow_read[k]:.1f},"
                     + ",".join(f"{v:.1f}" for v in levels))  # fmt: skip
    path = folder / f"{name}.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    side = {"sample_period_s": SAMPLE_PERIOD_S, "gauges": GAUGES_M, "gate_width_m": WIDTH_M,
            **sidecar}  # fmt: skip
    (folder / f"{name}.json").write_text(json.dumps(side, indent=2) + "\n", encoding="utf-8")
    return path


def step_inputs(flow_m3h: float, openings_mm: tuple[float, ...]
                ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Commands holding each opening for :data:`HOLD_S` at a constant inflow."""
    n = int(HOLD_S / SAMPLE_PERIOD_S)
    command = np.concatenate([np.full(n, e) for e in openings_mm])
    return command, np.full(command.size, float(flow_m3h))


def static_table(folder: Path, rng: np.random.Generator) -> Path:
    """Steady levels on a grid of discharge and opening (means of many samples)."""
    plant = truth_plant()
    rows = ["flow_m3h,opening_mm," + ",".join(f"level_{g}_mm" for g in GAUGES_M)]
    for q in np.linspace(3600.0, 10800.0, 9):
        for e in (250.0, 300.0, 350.0, 400.0, 450.0, 500.0, 600.0, 700.0):
            h = plant.steady_level_mm(e, q)
            if not 800.0 <= h <= 5000.0:  # the pool's banks and the gate's sill
                continue
            # a steady mean of 60 samples: the gauge noise shrinks by sqrt(60)
            levels = [h + LEVEL_SD_MM[g] / np.sqrt(60.0) * rng.standard_normal() for g in GAUGES_M]
            rows.append(f"{q:.1f},{e:.0f}," + ",".join(f"{v:.2f}" for v in levels))
    path = folder / "static.csv"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    side = {"gauges": GAUGES_M, "gate_width_m": WIDTH_M, "kind": "static rating table"}
    (folder / "static.json").write_text(json.dumps(side, indent=2) + "\n", encoding="utf-8")
    return path


#: Step tests: (name, inflow m³/h, openings mm, role).
STEPS = (
    ("S1", 5400.0, (350.0, 400.0), "fit"),
    ("S2", 7200.0, (400.0, 450.0), "fit"),
    ("S3", 9000.0, (450.0, 500.0), "fit"),
    ("S4", 6300.0, (420.0, 380.0), "fit"),
    ("H1", 8100.0, (430.0, 470.0), "held_out"),
)


def write_field_records(folder: Path, seed: int = 7) -> Path:
    """The static table, the step tests and a held-out validation record in ``folder``."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    static_table(folder, rng)
    for name, q, openings, role in STEPS:
        command, flow = step_inputs(q, openings)
        write_record(folder, name, command, flow, rng, {"test": "step", "role": role})
    return folder


def write_validation_record(path: Path, seed: int = 11) -> Path:
    """A record of neither the fit nor the held-out set: opening and inflow both move."""
    rng = np.random.default_rng(seed)
    n = int(HOLD_S / SAMPLE_PERIOD_S)
    command = np.concatenate([np.full(n, 400.0), np.full(n, 460.0), np.full(n, 420.0)])
    flow = np.concatenate([np.full(n, 6500.0), np.full(n, 7600.0), np.full(n, 7000.0)])
    path.mkdir(parents=True, exist_ok=True)
    return write_record(path, "V1", command, flow, rng, {"test": "free", "role": "validation"})
