"""Routine operation histories of a synthetic district: one week-long SCADA log per gate.

Each district gate (:func:`~gatetwin.fleet.district.district_gates`) is logged in routine
operation (:mod:`gatetwin.flume.routine`) around the middle of its operating line: the
middle fit flow scaled by its width, the level the operator holds there. The gate folder
gets ``routine.csv`` with its sidecar and ``truth.json`` (the gate's parameters and the
flume's FOPDT at every move); the district folder a ``truth.json`` listing the gates.

Test and benchmark data for :mod:`gatetwin.identification.routine`, not a model of a real district.
"""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from gatetwin._io import write_json_atomic
from gatetwin.errors import FlumeError
from gatetwin.fleet.district import (
    FIT_FLOWS_M3H,
    GAUGE,
    GAUGE_DISTANCE_M,
    TARGET_LEVEL_MM,
    GateTruth,
    district_gates,
)
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.logger import FLUME_VERSION
from gatetwin.flume.routine import ROUTINE_DX_M, RoutineSettings, routine_history

__all__ = [
    "DISTRICT_CONTROLS",
    "ROUTINE_NAME",
    "base_flow_m3h",
    "gate_control",
    "routine_flume",
    "write_routine_district",
    "write_routine_gate",
]

#: How district gates are driven: ``mixed`` puts every fourth gate under level control.
DISTRICT_CONTROLS = ("schedule", "pi", "mixed")
#: File stem of a gate's history.
ROUTINE_NAME = "routine"


def routine_flume(truth: GateTruth) -> FlumeConfig:
    """The gate's flume at the routine runs' cell size."""
    return truth.flume_config().with_(dx_m=ROUTINE_DX_M)


def base_flow_m3h(truth: GateTruth) -> float:
    """Mean inflow of the gate's history: the middle fit flow scaled by its width, m³/h."""
    return float(round(FIT_FLOWS_M3H[1] * truth.width_m / 0.30, 1))


def gate_control(control: str, index: int) -> str:
    """The control mode of the ``index``-th gate (0-based) for a district ``control``."""
    if control not in DISTRICT_CONTROLS:
        raise FlumeError(f"routine district: control {control!r}; expected one of "
                         f"{', '.join(DISTRICT_CONTROLS)}")  # fmt: skip
    if control == "mixed":
        return "pi" if index % 4 == 3 else "schedule"
    return control


def write_routine_gate(truth: GateTruth, folder: str | Path,
                       settings: RoutineSettings) -> Path:  # fmt: skip
    """Write the gate's ``routine.csv`` (+ sidecar) and ``truth.json``; returns the CSV."""
    out = Path(folder)
    target = 0.5 * (TARGET_LEVEL_MM[0] + TARGET_LEVEL_MM[1])
    rec, routine_truth = routine_history(
        routine_flume(truth), truth.logger_config(), settings,
        base_flow_m3h=base_flow_m3h(truth), target_level_mm=target, gauge=GAUGE,
        seed=truth.seed, sidecar={"gate": truth.gate, "gauges": {GAUGE: GAUGE_DISTANCE_M}},
    )  # fmt: skip
    path = rec.write(out / f"{ROUTINE_NAME}.csv")
    write_json_atomic(out / "truth.json", {**truth.to_dict(), "routine": routine_truth})
    return path


def _write_one(args: tuple[GateTruth, str, RoutineSettings]) -> str:
    truth, folder, settings = args
    write_routine_gate(truth, folder, settings)
    return truth.gate


def write_routine_district(n_gates: int, out_dir: str | Path, *, seed: int = 0,
                           control: str = "mixed", days: float = 7.0, workers: int = 1,
                           progress: Any = None) -> Path:  # fmt: skip
    """Generate one routine history per gate into ``out_dir/<gate>/`` (see module doc).

    ``workers`` > 1 generates gates in that many processes; the files do not depend on it.
    """
    gates = district_gates(n_gates, seed)
    out = Path(out_dir)
    jobs = [(g, str(out / g.gate), replace(RoutineSettings(days=days),
                                          control=gate_control(control, i)))
            for i, g in enumerate(gates)]  # fmt: skip
    if workers <= 1:
        done = map(_write_one, jobs)
    else:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=workers)
        done = pool.map(_write_one, jobs)
    try:
        for k, name in enumerate(done, start=1):
            if progress:
                progress(f"routine district: [{k}/{len(gates)}] {name} written")
    finally:
        if workers > 1:
            pool.shutdown()
    doc = {"n_gates": n_gates, "seed": seed, "flume_version": FLUME_VERSION,
           "kind": "routine operation histories", "control": control, "days": days,
           "gates": [{**g.to_dict(), "control": s.control, "settings": asdict(s)}
                     for g, _, s in jobs]}  # fmt: skip
    return write_json_atomic(out / "truth.json", doc)
