"""Generated records with one hidden effect (or none), for
tests/diagnosis/test_diagnose_generated.py.

The truth plant is an FOPDT (K in [-14, -10] mm/mm, T in [40, 60] s, L in [1, 3] s, a level
of 400-500 mm mid-range) plus one effect block drawn with physically material parameters.
The record is what a logger would write: 12 moves of 3-10 mm in both directions (reversals
and continuing moves), holds of 100-150 s, commands issued at sample instants, the discharge
stepping between 35, 55 and 75 m3/h in the middle of holds (three times in the first two
thirds, once after), white level noise of SD 0.3-1.0 mm (0.1 mm resolution), flow-meter
noise of 0.05 m3/h. The logger shows only the commanded opening on ``hold`` samples and
``open`` (opening empty) while the gate moves: for a rate-limited gate every sample of the
ramp, otherwise the one sample at which the gate jumps (it reaches each command within a
sample). The workflow under test sees only the CSV and its sidecar.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gatetwin.diagnosis import diagnose_record
from gatetwin.plant.effects import KINDS, effect_dict
from gatetwin.plant.model import FopdtPlant, Schedule
from gatetwin.plant.simulate import simulate

TS = 1.2
EFFECTS = ("none", *KINDS)
#: The truth parameters each effect is judged on.
JUDGED = {
    "actuator_rate_limit": ("rate_mm_per_s",),
    "actuator_backlash": ("deadband_mm",),
    "opening_nonlinearity": ("gain_slope_per_mm",),
    "flow_dependent_gain": ("gain_slope_per_m3h", "time_constant_slope_per_m3h"),
    "seiche": ("period_s", "decay_time_s", "amplitude_mm_per_mm"),
    "inflow_disturbance": ("gain_mm_per_m3h", "time_constant_s"),
    "sensor_drift": ("rate_mm_per_s",),
    "sensor_lag": ("time_constant_s",),
    "none": (),
}


@dataclass(frozen=True)
class Case:
    """One generated record and its truth."""

    seed: int
    effect: str
    truth: FopdtPlant
    params: dict[str, float]
    sigma_mm: float
    time_s: np.ndarray
    opening_mm: np.ndarray
    open_: np.ndarray
    flow_m3h: np.ndarray
    level_mm: np.ndarray

    def write(self, folder: Path) -> Path:
        path = folder / f"case_{self.seed}_{self.effect}.csv"
        rows = ["time_s,opening_mm,state,flow_m3h,level_3F_mm"]
        for t, e, o, q, y in zip(self.time_s, self.opening_mm, self.open_, self.flow_m3h,
                                 self.level_mm, strict=True):  # fmt: skip
            opening = "" if o else f"{e:.0f}"
            rows.append(f"{t:.3f},{opening},{'open' if o else 'hold'},{q:.2f},{y:.1f}")
        path.write_text("\n".join(rows) + "\n")
        sidecar = {"test": "step", "sample_period_s": TS, "synthetic": True}
        path.with_suffix(".json").write_text(json.dumps(sidecar))
        return path


def _moves(rng: np.random.Generator) -> list[float]:
    """Openings after each of 12 moves: sizes 3-10 mm, both directions, within 8-40 mm."""
    openings, direction = [float(rng.integers(18, 27))], 1.0
    for _ in range(12):
        direction = direction if rng.random() < 0.5 else -direction
        size = float(rng.choice([3, 4, 5, 6, 8, 10]))
        nxt = openings[-1] + direction * size
        if not 8.0 <= nxt <= 40.0:
            direction, nxt = -direction, openings[-1] - direction * size
        openings.append(nxt)
    return openings


def _effect_params(rng: np.random.Generator, effect: str, sigma: float, move: float
                   ) -> dict[str, float]:  # fmt: skip
    u = rng.uniform
    sign = 1.0 if rng.random() < 0.5 else -1.0
    period = u(5.0, 30.0)
    draws = {
        "none": {},
        "actuator_rate_limit": {"rate_mm_per_s": u(0.2, 1.0)},
        "actuator_backlash": {"deadband_mm": u(0.8, 2.5)},
        "opening_nonlinearity": {"gain_slope_per_mm": -u(0.015, 0.05)},
        "flow_dependent_gain": {"gain_slope_per_m3h": -u(0.006, 0.015),
                                "time_constant_slope_per_m3h": -u(0.006, 0.015),
                                "flow_ref_m3h": 55.0},
        "seiche": {"period_s": period, "decay_time_s": u(1.0, 2.5) * period,
                   "amplitude_mm_per_mm": sign * u(3.0, 8.0) * sigma / move},
        "inflow_disturbance": {"gain_mm_per_m3h": u(1.0, 4.0), "time_constant_s": u(20.0, 80.0),
                               "flow_ref_m3h": 55.0},
        "sensor_drift": {"rate_mm_per_s": sign * u(0.004, 0.02)},
        "sensor_lag": {"time_constant_s": u(5.0, 15.0)},
    }  # fmt: skip
    return draws[effect]


def _schedule(rng: np.random.Generator, openings: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Sample index of every move, and the record length."""
    holds = [50] + [int(rng.integers(84, 126)) for _ in range(len(openings) - 1)]
    starts = np.cumsum([0, *holds])
    return starts[1:-1], int(starts[-1])


def _flow(rng: np.random.Generator, n: int, move_at: np.ndarray) -> np.ndarray:
    """55 m3/h, stepping to 35/55/75 in the middle of four holds: three in the first two
    thirds of the record, one after."""
    q = np.full(n, 55.0)
    early = rng.choice(np.arange(1, 7), size=3, replace=False)
    holds = np.append(early, rng.integers(8, move_at.size - 1))
    levels = [35.0, 75.0, 55.0, 35.0, 75.0]
    rng.shuffle(levels)
    for level, h in zip(levels, sorted(holds), strict=False):
        q[(move_at[h] + move_at[h + 1]) // 2 :] = level
    return q


def draw_case(seed: int, effect: str) -> Case:
    """One generated record with ``effect`` hidden in it (``"none"``: a clean plant)."""
    rng = np.random.default_rng(seed)
    openings = _moves(rng)
    move_at, n = _schedule(rng, openings)
    time_s = np.arange(n) * TS
    command = np.repeat(openings, np.diff(np.concatenate([[0], move_at, [n]])))
    flow = _flow(rng, n, move_at)
    sigma = float(rng.uniform(0.3, 1.0))
    sizes = np.abs(np.diff(openings))
    params = _effect_params(rng, effect, sigma, float(np.median(sizes)))
    gain = rng.uniform(-14.0, -10.0)
    opening_ref = float(rng.integers(min(openings), max(openings) + 1))
    middle = 0.5 * (min(openings) + max(openings))
    tau, delay, level = rng.uniform(40, 60), rng.uniform(1.0, 3.0), rng.uniform(400.0, 500.0)
    values = {
        "gain_mm_per_mm": gain,
        "time_constant_s": tau,
        "dead_time_s": delay,
        "level_ref_mm": level - gain * (middle - opening_ref),
    }
    truth = FopdtPlant(
        "3F",
        opening_ref,
        Schedule((30.0, 80.0), {k: (float(v), float(v)) for k, v in values.items()}),
        effects=(effect_dict(effect, **params),) if effect != "none" else (),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        level = simulate(truth, time_s, command, flow)
    level = np.round(level + rng.normal(0.0, sigma, n), 1)
    moving = np.zeros(n, dtype=bool)
    rate = params.get("rate_mm_per_s") if effect == "actuator_rate_limit" else None
    for i, size in zip(move_at, sizes, strict=True):
        duration = size / rate if rate else 0.0
        moving[i : i + max(1, int(np.ceil(duration / TS - 1e-9)))] = True
    measured_flow = np.round(flow + rng.normal(0.0, 0.05, n), 2)
    judged = {k: float(params[k]) for k in JUDGED[effect]}
    return Case(seed, effect, truth, judged, sigma, time_s, command, moving, measured_flow, level)


def case_plan(n_cases: int, first_seed: int = 1000) -> list[tuple[int, str]]:
    """``(seed, effect)`` of ``n_cases`` cases: about 1/9 none, the rest over the 8 effects."""
    return [(first_seed + i, EFFECTS[i % len(EFFECTS)]) for i in range(n_cases)]


#: What the generated cases must reach (tests/diagnosis/test_diagnose_generated.py).
GAP_REDUCTION = 0.5
PARAMETER_TOLERANCE = 0.25


@dataclass(frozen=True)
class Outcome:
    seed: int
    truth: str
    named: str
    gap_reduction: float
    parameter_errors: dict[str, float]

    @property
    def right(self) -> bool:
        return self.named == self.truth

    @property
    def parameters_ok(self) -> bool:
        return bool(self.parameter_errors) and all(
            e <= PARAMETER_TOLERANCE for e in self.parameter_errors.values()
        )


def run_case(seed: int, effect: str, folder: Path) -> Outcome:
    case = draw_case(seed, effect)
    result = diagnose_record(case.write(folder))
    errors: dict[str, float] = {}
    if result["named_effect"] == effect and effect != "none":
        fitted = result["effect_fit"]["parameters"]
        errors = {k: abs(fitted[k]["value"] - v) / abs(v) for k, v in case.params.items()}
    return Outcome(seed, effect, result["named_effect"], result["gap_reduction"], errors)


def rates(outcomes: list[Outcome]) -> dict[str, float]:
    none = [o for o in outcomes if o.truth == "none"]
    present = [o for o in outcomes if o.truth != "none"]
    return {
        "cases": len(outcomes),
        "right_name": sum(o.right for o in outcomes) / len(outcomes),
        "none_flagged": sum(o.named != "none" for o in none) / max(len(none), 1),
        "false_positive_overall": sum(o.named not in ("none", o.truth) for o in outcomes)
        / len(outcomes),
        "missed": sum(o.named == "none" for o in present) / max(len(present), 1),
        "gap_down_50": sum(o.gap_reduction >= GAP_REDUCTION for o in present)
        / max(len(present), 1),
        "parameters_within_25": sum(o.parameters_ok for o in present) / max(len(present), 1),
        "median_gap_reduction": (
            sorted(o.gap_reduction for o in present)[len(present) // 2] if present else float("nan")
        ),
        "worst_parameter_error": max(
            (e for o in present for e in o.parameter_errors.values()), default=0.0
        ),
    }
