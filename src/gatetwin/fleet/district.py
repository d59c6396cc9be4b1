"""A synthetic irrigation district: many gates around the calibrated flume, each with truth.

Every gate is the virtual flume with its own geometry and hydraulics drawn around the
calibrated one (pool length, width, bed slope, gate-law coefficients, actuator speed,
logger noise). Its records are kept cheap so that a district of tens of gates generates
in minutes on two cores: three short step tests on an operating line (role ``fit``), one
held-out step test between them, and a small static rating table at the steps' flows.
Each record's sidecar names its ``gate``; each gate folder holds a ``truth.json`` with the
parameters it was generated from, and the district folder a ``truth.json`` with all of them.

This is test and benchmark data for the fleet commands, not a model of any real district.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin._io import write_json_atomic, write_text_atomic
from gatetwin.errors import FlumeError
from gatetwin.flume.config import FlumeConfig, GateLaw
from gatetwin.flume.envelope import steady_levels_mm
from gatetwin.flume.experiments import Scenario
from gatetwin.flume.logger import FLUME_VERSION, LoggerConfig, log_run
from gatetwin.flume.simulate import run_flume, spin_up, steady_gate_depth_m

__all__ = [
    "DISTRICT_DX_M",
    "FIT_FLOWS_M3H",
    "GAUGE",
    "GAUGE_DISTANCE_M",
    "HELD_OUT_FLOW_M3H",
    "POST_STEP_S",
    "PRE_STEP_S",
    "SPIN_UP_S",
    "STATIC_OFFSETS_MM",
    "STATIC_SAMPLES",
    "STEP_MM",
    "TARGET_LEVEL_MM",
    "GateTruth",
    "district_gates",
    "expected_samples",
    "gate_conditions",
    "operating_opening_mm",
    "static_table_csv",
    "truth_document",
    "write_district",
    "write_gate",
]

#: The one gauge of a district gate: the upstream level sensor 1.1 m from the gate.
GAUGE = "U"
GAUGE_DISTANCE_M = 1.1
#: Fit conditions and the held-out one, as discharge at the calibrated 0.30 m width, m³/h;
#: each gate scales them by its width (same discharge per metre of width).
FIT_FLOWS_M3H = (35.0, 50.0, 65.0)
HELD_OUT_FLOW_M3H = 57.5
#: Operating line: the steady level at the gauge the operator holds, rising linearly with
#: discharge between the first and the last fit flow, mm.
TARGET_LEVEL_MM = (240.0, 320.0)
STEP_MM = 5.0
#: Steady start before the step and hold after it, s (the hold is over 4 time constants
#: of the longest pool drawn).
PRE_STEP_S = 180.0
POST_STEP_S = 420.0
#: Spin-up from a level surface, s: over 4 time constants of the longest pool drawn.
SPIN_UP_S = 420.0
#: Static rating table: openings around each fit condition's, mm, and samples per point.
STATIC_OFFSETS_MM = (-5.0, 0.0, 5.0, 10.0, 16.0)
STATIC_SAMPLES = 30
#: Cell size of the district flumes, m: twice the reference flume's; the gauge still lies
#: 11 cells from the gate and the run costs a quarter.
DISTRICT_DX_M = 0.1


@dataclass(frozen=True)
class GateTruth:
    """What one district gate was generated from.

    Attributes
    ----------
    gate : str
        Gate name (folder name and the sidecars' ``gate``).
    seed : int
        Seed of the logger noise of its records.
    pool_length_m, width_m, bed_slope : float
        Pool length from inlet to gate (m), channel width (m), bed slope (–).
    cd_scale : float
        Factor on the calibrated discharge-coefficient law (intercept and slope).
    actuator_speed_mm_s : float
        No-load speed of the gate, mm/s.
    noise_scale : float
        Factor on the logger's surface-fluctuation and sensor noise.
    """

    gate: str
    seed: int
    pool_length_m: float
    width_m: float
    bed_slope: float
    cd_scale: float
    actuator_speed_mm_s: float
    noise_scale: float

    def flume_config(self) -> FlumeConfig:
        """The gate's flume (one gauge ``U``)."""
        law = GateLaw()
        law = replace(law, intercept=tuple(self.cd_scale * c for c in law.intercept),
                      slope=tuple(self.cd_scale * c for c in law.slope))  # fmt: skip
        return FlumeConfig(
            width_m=self.width_m, pool_length_m=self.pool_length_m, bed_slope=self.bed_slope,
            dx_m=DISTRICT_DX_M, gate=law, actuator_speed_mm_s=self.actuator_speed_mm_s,
            gauges_m={GAUGE: GAUGE_DISTANCE_M}, gauge_datum_mm={GAUGE: 0.0},
        )  # fmt: skip

    def logger_config(self) -> LoggerConfig:
        """The gate's logger: the calibrated noise scaled by ``noise_scale``."""
        lc = LoggerConfig()
        return replace(lc, sigma0_mm=lc.sigma0_mm * self.noise_scale,
                       sigma_max_mm=lc.sigma_max_mm * self.noise_scale,
                       sensor_sd_mm=lc.sensor_sd_mm * self.noise_scale)  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def district_gates(n_gates: int, seed: int = 0) -> list[GateTruth]:
    """``n_gates`` gates drawn around the calibrated flume (deterministic for ``seed``).

    Pool length 6–11 m, width 0.27–0.33 m, bed slope 1/400–1/150, gate law ×0.92–1.08,
    actuator 1.2–2.2 mm/s, noise ×0.6–1.6 (uniform draws).
    """
    if not (isinstance(n_gates, int) and n_gates >= 1):
        raise FlumeError(f"district: the number of gates must be a whole number >= 1, "
                         f"got {n_gates!r}")  # fmt: skip
    rng = np.random.default_rng(seed)
    width = len(str(n_gates))
    gates = []
    for i in range(n_gates):
        u = rng.random(6)
        gates.append(GateTruth(
            gate=f"gate{i + 1:0{max(3, width)}d}", seed=int(seed * 100_000 + 1000 * (i + 1)),
            pool_length_m=float(round(6.0 + 5.0 * u[0], 2)),
            width_m=float(round(0.27 + 0.06 * u[1], 3)),
            bed_slope=float(round(1.0 / (400.0 - 250.0 * u[2]), 5)),
            cd_scale=float(round(0.92 + 0.16 * u[3], 3)),
            actuator_speed_mm_s=float(round(1.2 + 1.0 * u[4], 2)),
            noise_scale=float(round(0.6 + 1.0 * u[5], 2)),
        ))  # fmt: skip
    return gates


def operating_opening_mm(cfg: FlumeConfig, flow_m3h: float, target_mm: float) -> float:
    """Whole-millimetre opening (12–80 mm) whose steady gauge level is nearest ``target_mm``."""
    openings = np.arange(12.0, 81.0)
    levels = [steady_levels_mm(cfg, flow_m3h, e)[GAUGE] for e in openings]
    return float(openings[int(np.argmin(np.abs(np.asarray(levels) - target_mm)))])


def _target_mm(flow_ref_m3h: float) -> float:
    q0, q1 = FIT_FLOWS_M3H[0], FIT_FLOWS_M3H[-1]
    w = (flow_ref_m3h - q0) / (q1 - q0)
    return TARGET_LEVEL_MM[0] + w * (TARGET_LEVEL_MM[1] - TARGET_LEVEL_MM[0])


def gate_conditions(truth: GateTruth) -> list[tuple[str, float, float, str]]:
    """The gate's step conditions: (name, flow m³/h, opening before the step mm, role)."""
    cfg = truth.flume_config()
    scale = truth.width_m / 0.30
    flows = [(f"Q{q:g}".replace(".", "p"), q, "fit") for q in FIT_FLOWS_M3H]
    flows.append((f"Q{HELD_OUT_FLOW_M3H:g}".replace(".", "p"), HELD_OUT_FLOW_M3H, "held_out"))
    out = []
    for name, q_ref, role in flows:
        q = float(round(q_ref * scale, 1))
        out.append((name, q, operating_opening_mm(cfg, q, _target_mm(q_ref)), role))
    return out


def _step(truth: GateTruth, name: str, flow: float, before: float, role: str,
          k: int) -> Scenario:  # fmt: skip
    return Scenario(
        name, ((0.0, flow),), ((0.0, before), (PRE_STEP_S, before + STEP_MM)),
        PRE_STEP_S + POST_STEP_S, truth.seed + k, "step",
        {"gate": truth.gate, "role": role,
         "description": f"step {before:g} -> {before + STEP_MM:g} mm at Q = {flow:g} m3/h"},
    )  # fmt: skip


def _run_step(scn: Scenario, cfg: FlumeConfig, lc: LoggerConfig) -> Any:
    """Like :func:`~gatetwin.flume.experiments.run_scenario`, with the shorter spin-up."""
    cmd, flow = scn.sampled(cfg.sample_period_s)
    state = spin_up(cfg, float(flow[0]), float(cmd[0]), duration_s=SPIN_UP_S)
    run = run_flume(cfg, cmd, flow, state=state)
    side = {"condition": scn.name, "test": scn.test, **scn.meta}
    return log_run(run, cfg, scn.seed, logger=lc, sidecar=side)


def static_table_csv(truth: GateTruth, conditions: list[tuple[str, float, float, str]]) -> str:
    """The gate's small rating table as CSV text: the fit flows × openings around each."""
    cfg, lc = truth.flume_config(), truth.logger_config()
    lines = [f"flow_m3h,opening_mm,level_{GAUGE}_mm,level_{GAUGE}_sd_mm"]
    k = 0
    for _, q, e0, role in conditions:
        if role != "fit":
            continue
        for de in STATIC_OFFSETS_MM:
            e = e0 + de
            if 1000.0 * steady_gate_depth_m(cfg, q, e) > cfg.depth_limit_m * 1000.0:
                continue
            state = spin_up(cfg, q, e, duration_s=SPIN_UP_S)
            run = run_flume(cfg, np.full(STATIC_SAMPLES, e), np.full(STATIC_SAMPLES, q),
                            state=state)  # fmt: skip
            rec = log_run(run, cfg, truth.seed + 500 + k, logger=lc)
            k += 1
            level = rec.levels_mm[GAUGE]
            lines.append(f"{np.mean(rec.flow_m3h):.2f},{e:.0f},{np.mean(level):.2f},"
                         f"{np.std(level, ddof=1):.2f}")  # fmt: skip
    return "\n".join(lines) + "\n"


def write_gate(truth: GateTruth, folder: str | Path) -> list[Path]:
    """Write one gate's records, static table and ``truth.json`` into ``folder``."""
    out = Path(folder)
    cfg, lc = truth.flume_config(), truth.logger_config()
    conditions = gate_conditions(truth)
    paths = []
    for k, (name, q, e0, role) in enumerate(conditions):
        scn = _step(truth, name, q, e0, role, k)
        paths.append(_run_step(scn, cfg, lc).write(out / f"{name}.csv"))
    paths.append(write_text_atomic(out / "static.csv", static_table_csv(truth, conditions)))
    side = {"synthetic": True, "generator": f"gatetwin virtual flume {FLUME_VERSION}",
            "flume_version": FLUME_VERSION, "seed": truth.seed + 500, "gate": truth.gate,
            "kind": "static rating table", "gauges": {GAUGE: GAUGE_DISTANCE_M}}  # fmt: skip
    write_text_atomic(out / "static.json", json.dumps(side, indent=2) + "\n")
    write_json_atomic(out / "truth.json", truth_document(truth, conditions))
    return paths


def truth_document(truth: GateTruth,
                   conditions: list[tuple[str, float, float, str]]) -> dict[str, Any]:  # fmt: skip
    """The truth of one gate: its parameters and the conditions its records were run at."""
    cfg = truth.flume_config()
    return {
        **truth.to_dict(),
        "gauge": GAUGE, "gauge_distance_m": GAUGE_DISTANCE_M, "dx_m": cfg.dx_m,
        "cd_intercept": list(cfg.gate.intercept), "cd_slope": list(cfg.gate.slope),
        "conditions": [{"name": n, "flow_m3h": q, "opening_before_mm": e,
                        "opening_after_mm": e + STEP_MM, "role": r}
                       for n, q, e, r in conditions],
        "steady_level_mm": {n: float(round(steady_levels_mm(cfg, q, e + STEP_MM)[GAUGE], 2))
                            for n, q, e, _ in conditions},
    }  # fmt: skip


def _write_one(args: tuple[GateTruth, str]) -> str:
    truth, folder = args
    write_gate(truth, folder)
    return truth.gate


def write_district(n_gates: int, out_dir: str | Path, *, seed: int = 0, workers: int = 1,
                   progress: Any = None) -> Path:  # fmt: skip
    """Generate ``n_gates`` gates into ``out_dir/<gate>/`` and ``out_dir/truth.json``.

    ``workers`` > 1 generates gates in that many processes; the files do not depend on it.
    """
    out = Path(out_dir)
    gates = district_gates(n_gates, seed)
    jobs = [(g, str(out / g.gate)) for g in gates]
    if workers <= 1:
        done = map(_write_one, jobs)
    else:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=workers)
        done = pool.map(_write_one, jobs)
    try:
        for k, name in enumerate(done, start=1):
            if progress:
                progress(f"district: [{k}/{len(gates)}] {name} written")
    finally:
        if workers > 1:
            pool.shutdown()
    doc = {"n_gates": n_gates, "seed": seed, "flume_version": FLUME_VERSION,
           "gates": [g.to_dict() for g in gates]}  # fmt: skip
    return write_json_atomic(out / "truth.json", doc)


def expected_samples(truth: GateTruth) -> int:
    """Samples the gate's records hold (the step records' rows)."""
    per_step = math.floor((PRE_STEP_S + POST_STEP_S) / 1.2) + 1
    return per_step * (len(FIT_FLOWS_M3H) + 1)
