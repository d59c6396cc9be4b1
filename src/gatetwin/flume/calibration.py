"""Calibration of the virtual flume to the reference study's tables.

Run ``python -m gatetwin.flume.calibration`` to recompute the calibrated values of
:class:`~gatetwin.flume.config.FlumeConfig` and print them next to the defaults:

1. **Gate law.** For each steady state of Tables 2–3 (A and B, before and after the step)
   find the constant Cd at which the flume's mean level over the five gauges equals the
   published mean over the five gauges. Each state gives a point (e/h, Cd); the two points
   of a condition fix a line Cd = intercept + slope·e/h at that condition's flow.
2. **Gauge datums.** What is left per gauge (published − simulated, averaged over the four
   states) is that gauge's datum offset; by construction they average to zero.
3. **Pool length and actuator speed** are fitted to T and L by :func:`dynamic_misfit`
   (step runs through the logger and the paper's method).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from gatetwin.flume.config import FlumeConfig, GateLaw
from gatetwin.flume.paper_targets import GAUGES, STEP_TABLES
from gatetwin.flume.simulate import spin_up
from gatetwin.flume.solver import Grid

__all__ = ["calibrate_gate", "constant_cd_for", "main", "steady_depths_mm"]

_CONSTANT = dict(r_low=0.0, r_high=10.0)


def steady_depths_mm(cfg: FlumeConfig, flow_m3h: float, opening_mm: float) -> dict[str, float]:
    """Steady depth at every gauge and at the gate cell (key ``"gate"``), mm."""
    state = spin_up(cfg, flow_m3h, opening_mm)
    grid = Grid.of(cfg)
    out = {}
    for g, dist in cfg.gauges_m.items():
        i, w = grid.probe(dist)
        out[g] = 1000.0 * ((1 - w) * state.depth_m[i] + w * state.depth_m[i + 1])
    out["gate"] = 1000.0 * state.depth_m[-1]
    return out


def _states() -> list[tuple[str, float, float, dict[str, float]]]:
    rows = []
    for cond, tab in STEP_TABLES.items():
        rows.append((cond, tab.flow_m3h, tab.opening_before_mm, tab.pre_mean_mm))
        rows.append((cond, tab.flow_m3h, tab.opening_after_mm, tab.post_mean_mm))
    return rows


def constant_cd_for(
    cfg: FlumeConfig, flow_m3h: float, opening_mm: float, target_mean_mm: float
) -> tuple[float, dict[str, float]]:
    """Constant Cd at which the five-gauge mean steady level equals ``target_mean_mm``."""
    cd = 0.8
    for _ in range(8):
        law = GateLaw(flow_m3h=(0.0, 1.0), intercept=(cd, cd), slope=(0.0, 0.0), **_CONSTANT)
        depths = steady_depths_mm(replace(cfg, gate=law), flow_m3h, opening_mm)
        mean = float(np.mean([depths[g] for g in GAUGES]))
        if abs(mean - target_mean_mm) < 1e-3:
            break
        cd *= np.sqrt(mean / target_mean_mm)  # free underflow: h ∝ 1/Cd²
    return cd, depths


def calibrate_gate(cfg: FlumeConfig) -> tuple[GateLaw, dict[str, float]]:
    """Gate law and gauge datums from the four steady states of Tables 2–3."""
    points: dict[str, list[tuple[float, float]]] = {}
    residual = {g: [] for g in GAUGES}
    for cond, flow, opening, means in _states():
        target = float(np.mean([means[g] for g in GAUGES]))
        cd, depths = constant_cd_for(cfg, flow, opening, target)
        points.setdefault(cond, []).append((opening / depths["gate"], cd))
        for g in GAUGES:
            residual[g].append(means[g] - depths[g])
    intercepts, slopes = [], []
    for cond in ("A", "B"):
        (r0, c0), (r1, c1) = points[cond]
        s = (c1 - c0) / (r1 - r0)
        slopes.append(s)
        intercepts.append(c0 - s * r0)
    law = replace(
        cfg.gate,
        flow_m3h=(STEP_TABLES["A"].flow_m3h, STEP_TABLES["B"].flow_m3h),
        intercept=(round(float(intercepts[0]), 4), round(float(intercepts[1]), 4)),
        slope=(round(float(slopes[0]), 4), round(float(slopes[1]), 4)),
    )
    datum = {g: round(float(np.mean(v)), 2) for g, v in residual.items()}
    return law, datum


def main() -> None:
    cfg = FlumeConfig()
    law, datum = calibrate_gate(cfg)
    print("gate law (calibrated):", law)
    print("gate law (default):   ", cfg.gate)
    print("gauge datum (calibrated):", datum)
    print("gauge datum (default):   ", cfg.gauge_datum_mm)


if __name__ == "__main__":
    main()
