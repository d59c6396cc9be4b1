"""Experiments on a SWMM plant, sized from the plant's own time constants, as records.

A first step test on the noise-free plant (:func:`measure_step`) measures the level's
response at the output gauge: gain, and by Smith's two-point method (the times the
response reaches 28.3 % and 63.2 % of its final change) the time constant T and the dead
time L. Every design follows from them (the rules, stated once here):

* gate step: 10 % of the base opening (whole mm, at least 1 mm);
* ``step`` record: steady for max(T, 5 samples), then the step, then 5·(T + L) (the FOPDT
  response is within 1 % of its end) — at flows 0.7, 0.85, 1.0 and 1.15 × the base flow
  (role ``fit``) and 0.92 × (role ``held_out``), each at the opening that keeps the gate's
  Δh of the base point (the orifice law: opening ∝ flow at fixed head);
* ``prbs`` record: a 63-bit maximum-length sequence of ± the gate step, switching time
  T / 2 (rounded to whole samples), plus the gate's travel;
* ``free`` records (role ``validation``): wide gate moves (± 1, 2, 3 gate steps), inflow
  steps of −40 % and +40 %, both together, and a random sequence (openings within ± 3
  gate steps, flows within ± 30 %), each held 3·(T + L). Every hold must stay in bank and
  in orifice regime: its steady level at the output gauge at least one gate step's level
  change (|K|·gate step) below the node's top (SWMM's full depth), with no gauge node
  flooding, and above the opening. A hold that is not is moved, one gate step at a time,
  to the nearest opening that is (opened when too high, closed when too low): with the
  gate held, +40 % inflow raises the orifice's head by about 1.4² and overtops a pool
  run near its bank, where SWMM clips the level and loses the overflow;
* ``static`` table: flows 0.6–1.3 × base and openings 0.5–1.5 × base (6 × 6), each point
  kept when its steady level at the gate lies above the opening (orifice regime) and
  below the gauge node's top; 30 samples per point.

Any record during which a gauge node floods is refused (:func:`check_in_bank`).

Gauge noise: independent Gaussian, ``noise_mm`` standard deviation, read to 0.1 mm.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin._io import write_text_atomic
from gatetwin.errors import PlantError
from gatetwin.plants.swmm import RESOLUTION_MM, SwmmCore, swmm_versions

__all__ = [
    "DESIGNS",
    "FIT_FLOW_FACTORS",
    "HELD_OUT_FLOW_FACTOR",
    "STATIC_FLOW_FACTORS",
    "STATIC_OPENING_FACTORS",
    "Schedule",
    "StepResponse",
    "check_in_bank",
    "check_regime",
    "gate_step_mm",
    "measure_step",
    "record_csv",
    "run_schedule",
    "sidecar",
    "write_outputs",
]

DESIGNS = ("static", "step", "prbs", "free", "all")
FIT_FLOW_FACTORS = (0.7, 0.85, 1.0, 1.15)
HELD_OUT_FLOW_FACTOR = 0.92
STATIC_FLOW_FACTORS = tuple(np.linspace(0.6, 1.3, 6))
STATIC_OPENING_FACTORS = tuple(np.linspace(0.5, 1.5, 6))


@dataclass(frozen=True)
class StepResponse:
    """The first step test's measurement at the output gauge (true levels).

    Attributes
    ----------
    gain_mm_per_mm : float
        Level change per opening change, mm/mm.
    time_constant_s, dead_time_s : float
        Smith's two-point T = 1.5 (t63 − t28) and L = t63 − T, s (from the step command).
    step_mm : float
        Opening change, mm.
    """

    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    step_mm: float

    def to_dict(self) -> dict[str, float]:
        return {"gain_mm_per_mm": round(self.gain_mm_per_mm, 4),
                "time_constant_s": round(self.time_constant_s, 1),
                "dead_time_s": round(self.dead_time_s, 1), "step_mm": self.step_mm}  # fmt: skip


@dataclass
class Schedule:
    """Piecewise-constant inputs: (start time s, value) breakpoints over a duration."""

    name: str
    test: str
    role: str
    opening_mm: list[tuple[float, float]]
    flow_m3h: list[tuple[float, float]]
    duration_s: float
    description: str
    meta: dict[str, Any] = field(default_factory=dict)

    def at(self, t: float) -> tuple[float, float]:
        def value(bps: list[tuple[float, float]]) -> float:
            return [v for s, v in bps if s <= t + 1e-9][-1]

        return value(self.opening_mm), value(self.flow_m3h)


def gate_step_mm(opening_mm: float) -> float:
    """The design's gate step: 10 % of the opening, whole mm, at least 1 mm."""
    return float(max(1, round(0.1 * opening_mm)))


def measure_step(core: SwmmCore, opening_mm: float, flow_m3h: float) -> StepResponse:
    """Step the gate by :func:`gate_step_mm` from steady state and measure K, T, L."""
    step = gate_step_mm(opening_mm)
    h0 = core.start(opening_mm, flow_m3h)
    times, levels = [0.0], [h0]
    tolerance, period = core.spec.steady_tolerance_mm, core.spec.sample_period_s
    while times[-1] < core.spec.max_spin_up_s:
        levels.append(core.advance(opening_mm + step, flow_m3h))
        times.append(times[-1] + period)
        n = max(10, len(levels) // 4)  # steady over the last quarter of the response
        window = levels[-n:]
        if len(levels) > 40 and max(window) - min(window) < tolerance:
            break
    else:
        raise PlantError(f"step test at Q = {flow_m3h:g} m³/h: no steady level after the step")
    t, y = np.array(times), (np.array(levels) - h0) / (levels[-1] - h0)
    t28, t63 = (float(np.interp(f, *_rising(t, y))) for f in (0.283, 0.632))
    tau = 1.5 * (t63 - t28)
    return StepResponse((levels[-1] - h0) / step, tau, max(t63 - tau, 0.0), step)


def _rising(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(y, t) of the normalised response made monotone, for interpolating crossing times."""
    return np.maximum.accumulate(y), t


def run_schedule(core: SwmmCore, sch: Schedule, noise_mm: float, seed: int) -> dict[str, Any]:
    """Spin up at the first inputs, run, and log every sample: the record's columns."""
    rng = np.random.default_rng(seed)
    period = core.spec.sample_period_s
    e0, q0 = sch.at(0.0)
    core.start(e0, q0)
    rows = [_row(core, 0.0, e0, q0, moving=False)]
    t, flooded = 0.0, []
    while t + period <= sch.duration_s + 1e-9:
        command, flow = sch.at(t)
        before = core.position_mm
        core.advance(command, flow)
        t += period
        rows.append(_row(core, t, command, flow, moving=core.position_mm != before))
        if core.flooding():
            flooded.append(t)
    names = list(core.spec.gauge_names.values())
    levels = {g: np.array([r["levels"][g] for r in rows]) for g in names}
    for g in names:
        noisy = levels[g] + noise_mm * rng.standard_normal(levels[g].size)
        levels[g] = np.round(noisy / RESOLUTION_MM) * RESOLUTION_MM
    return {"rows": rows, "levels": levels, "flooded_s": flooded}


def check_in_bank(run: dict[str, Any], name: str) -> None:
    """Refuse a record during which a gauge node flooded: SWMM clips the level at the node's
    top and loses the overflow, so the record no longer shows the pool's response."""
    flooded = run["flooded_s"]
    if flooded:
        raise PlantError(
            f"record {name}: a gauge node floods (over its full depth) for {len(flooded)} "
            f"samples from t = {flooded[0]:g} s; the level there is clipped at the bank"
        )


def _row(core: SwmmCore, t: float, command: float, flow: float, moving: bool) -> dict[str, Any]:
    return {"time_s": t, "opening_mm": None if moving else core.position_mm,
            "state": "open" if moving else "hold", "flow_m3h": flow,
            "levels": core.levels_mm()}  # fmt: skip


def record_csv(run: dict[str, Any]) -> str:
    """The record's CSV text (``time_s, opening_mm, state, flow_m3h, level_<G>_mm``)."""
    names = list(run["levels"])
    lines = [",".join(["time_s", "opening_mm", "state", "flow_m3h"]
                      + [f"level_{g}_mm" for g in names])]  # fmt: skip
    for i, r in enumerate(run["rows"]):
        opening = "" if r["opening_mm"] is None else f"{r['opening_mm']:.1f}"
        cells = [f"{r['time_s']:.1f}", opening, r["state"], f"{r['flow_m3h']:.2f}"]
        cells += [f"{run['levels'][g][i]:.1f}" for g in names]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def sidecar(core: SwmmCore, *, seed: int, noise_mm: float, **extra: Any) -> dict[str, Any]:
    """The JSON sidecar every SWMM record carries."""
    spec, orifice = core.spec, core.orifice
    return {
        "synthetic": True,
        "generator": swmm_versions(),
        "swmm_model": spec.inp_path.name,
        "seed": seed,
        "sample_period_s": spec.sample_period_s,
        "gauges": {spec.gauge_names[n]: d for n, d in spec.gauges.items()},
        "gauge_nodes": dict(spec.gauge_names),
        "gate_link": spec.gate,
        "gate_width_m": orifice.width_m,
        "gate_height_m": orifice.height_m,
        "gate_speed_mm_s": spec.gate_speed_mm_s,
        "noise_sd_mm": noise_mm,
        "level_datum": f"gate sill: bottom of orifice {spec.gate}'s opening, elevation "
        f"{orifice.sill_elevation_m:g} m in the model",
        **extra,
    }


def write_outputs(out_dir: Path, outputs: list[tuple[str, str, dict[str, Any]]]) -> list[Path]:
    """Write ``NAME.csv`` and ``NAME.json`` per output (after every record was made)."""
    paths = []
    for name, text, side in outputs:
        paths.append(write_text_atomic(out_dir / f"{name}.csv", text))
        write_text_atomic(out_dir / f"{name}.json", json.dumps(side, indent=2) + "\n")
    return paths


def check_regime(core: SwmmCore, opening_mm: float, flow_m3h: float) -> float:
    """Start at the base point; refuse it unless the level at the output gauge lies above
    the opening (the orifice regime). Returns that level, mm."""
    gate_level = core.start(opening_mm, flow_m3h)
    if not gate_level > opening_mm:
        raise PlantError(
            f"base point e = {opening_mm:g} mm, Q = {flow_m3h:g} m³/h: level {gate_level:.0f} mm "
            "at the gate is not above the opening (no orifice regime); pick a smaller --opening"
        )
    return gate_level
