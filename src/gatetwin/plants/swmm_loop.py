"""A SWMM model in the closed loop: the controllers' settings from the identified twin,
scenarios sized from its time constant, and the canal-control indicators.

Nothing here is a constant of one canal. From the twin's FOPDT at the operating discharge
(gain ``K``, time constant ``T``, dead time ``L``) and the records (sample period ``Ts``,
gauge noise SD ``σ``, gate speed, the opening and level ranges the experiments covered):

* MPC horizon and prediction step, and its move weight: the rules the controller FMUs
  follow (:func:`gatetwin.fmu.controller_settings.horizon` and
  :func:`~gatetwin.mpc.settings.gate_move_weight`), so that the Python loop and the
  exported MPC are one design;
* observer: :func:`gatetwin.fmu.controller_settings.observer_settings` of ``σ`` (the one
  rule the controller FMUs follow too): measurement SD and level process noise ``σ``, an
  input disturbance walking a tenth of the opening per time constant, so such a mismatch
  is integrated out in about T;
* opening range: the gate's own (0 to the orifice height): an inflow step may need an
  opening the experiments never set, and the offset-free MPC lives with the twin's
  extrapolation there; level band: the levels the experiments' records covered;
* set-point step ``|K| s_e`` (the level change of one gate step); inflow steps +40 % and
  −30 %; each event held ``HOLD_TIME_CONSTANTS`` × (T + L).

Indicators after Clemmens et al. (1998), on the true (noise-free) level, mm: ``mae_mm``
maximum absolute error, ``iae_mean_mm`` integrated absolute error divided by the window
(time-averaged), ``ste_mm`` steady-state error (mean error over the last (T + L)),
``iaw_mm`` integrated absolute change of gate position (gate travel); also violations and
``gate_reversals_per_hour`` (:func:`gatetwin.mpc.loop.loop_metrics`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import PlantError
from gatetwin.fmu.controller_settings import horizon, observer_settings
from gatetwin.mpc.loop import ClosedLoopRun, LoopSettings, Scenario, loop_metrics
from gatetwin.mpc.pi import PiSettings
from gatetwin.mpc.plants import MeasurementNoise
from gatetwin.mpc.settings import MpcSettings, gate_move_weight
from gatetwin.plant.model import FopdtPlant
from gatetwin.plants.swmm import SwmmCore, SwmmPlantSpec

#: Each scenario event is held this many (T + L): the FOPDT response is within 2 % of its end.
HOLD_TIME_CONSTANTS = 4.0
#: Inflow steps of the scenarios, as factors of the operating discharge.
INFLOW_UP, INFLOW_DOWN = 1.4, 0.7
#: The step up is the largest of these that the gate can take (:func:`inflow_up_factor`).
INFLOW_UP_STEPS = (INFLOW_UP, 1.3, 1.2, 1.1)
#: Share of the gate's range kept in reserve above the opening an inflow step needs.
OPENING_RESERVE = 0.1
#: Keys of a plant spec file (``--swmm-plant PLANT.json``).
SPEC_KEYS = ("inp", "gate", "gauges", "inflow", "gate_speed_mm_s", "sample_period_s")


def spec_to_dict(spec: SwmmPlantSpec) -> dict[str, Any]:
    """The JSON plant spec of ``spec`` (paths absolute)."""
    return {"inp": str(spec.inp_path.resolve()), "gate": spec.gate,
            "gauges": dict(spec.gauges), "inflow": list(spec.inflow_nodes),
            "gate_speed_mm_s": spec.gate_speed_mm_s,
            "sample_period_s": spec.sample_period_s}  # fmt: skip


def read_spec(path: str | Path) -> SwmmPlantSpec:
    """A :class:`SwmmPlantSpec` from a JSON plant spec file (keys :data:`SPEC_KEYS`; a
    relative ``inp`` is taken from the file's folder)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PlantError(f"{path}: not a readable JSON plant spec ({exc})") from None
    missing = [k for k in SPEC_KEYS[:4] if not isinstance(doc, dict) or k not in doc]
    if missing:
        raise PlantError(f"{path}: plant spec lacks {', '.join(missing)}")
    try:
        gauges = {str(n): float(d) for n, d in dict(doc["gauges"]).items()}
        inflow = (doc["inflow"],) if isinstance(doc["inflow"], str) else tuple(doc["inflow"])
        extra = {k: float(doc[k]) for k in SPEC_KEYS[4:] if k in doc}
    except (TypeError, ValueError):
        raise PlantError(f"{path}: plant spec gauges/inflow/numbers malformed") from None
    return SwmmPlantSpec(path.parent / doc["inp"], str(doc["gate"]), gauges, inflow, **extra)


def core_factory(spec: SwmmPlantSpec) -> Callable[[], SwmmCore]:
    """Fresh SWMM cores of ``spec`` (one simulation open at a time: each loop closes its
    own)."""
    SwmmCore(spec)  # refuses a bad spec now, before any loop runs
    return lambda: SwmmCore(spec)


@dataclass(frozen=True)
class TwinPoint:
    """The twin at the operating point.

    Attributes
    ----------
    gain_mm_per_mm, time_constant_s, dead_time_s : float
        FOPDT at ``flow_m3h``: K (mm/mm), T (s), L (s).
    flow_m3h, opening_mm : float
        Operating discharge (m³/h) and opening (mm).
    gate_step_mm : float
        The experiments' gate step, mm.
    level_mm : float
        The twin's steady level there, mm.
    """

    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    flow_m3h: float
    opening_mm: float
    gate_step_mm: float
    level_mm: float = math.nan

    @classmethod
    def of(cls, plant: FopdtPlant, flow_m3h: float, opening_mm: float,
           gate_step_mm: float) -> TwinPoint:  # fmt: skip
        s = plant.schedule
        k, t, lag = (s.at(q, flow_m3h) for q in ("gain_mm_per_mm", "time_constant_s",
                                                 "dead_time_s"))  # fmt: skip
        if not (math.isfinite(k) and k != 0 and t > 0 and lag >= 0):
            raise PlantError(f"twin {plant.gauge}: K = {k}, T = {t} s, L = {lag} s at "
                             f"{flow_m3h:g} m³/h; no loop can be designed on it")  # fmt: skip
        level = s.at("level_ref_mm", flow_m3h) + k * (opening_mm - plant.opening_ref_mm)
        return cls(float(k), float(t), float(lag), float(flow_m3h), float(opening_mm),
                   float(gate_step_mm), float(level))  # fmt: skip

    @property
    def response_s(self) -> float:
        return self.time_constant_s + self.dead_time_s


def record_ranges(
    records: list[Any], gauge: str
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The opening range (mm) and the level range at ``gauge`` (mm) the time-series
    records covered: the loop's opening range and level band when the twin states none."""
    openings = np.concatenate([r.opening_mm for r in records])
    levels = np.concatenate([r.levels_mm[gauge] for r in records if gauge in r.levels_mm])
    openings, levels = openings[np.isfinite(openings)], levels[np.isfinite(levels)]
    if openings.size == 0 or levels.size == 0:
        raise PlantError(f"no opening or level at {gauge} in the records to bound the loop")
    return ((float(openings.min()), float(openings.max())),
            (float(levels.min()), float(levels.max())))  # fmt: skip


def loop_settings(point: TwinPoint, *, sample_period_s: float, noise_sd_mm: float,
                  gate_speed_mm_s: float, opening_range_mm: tuple[float, float],
                  level_band_mm: tuple[float, float] | None):  # fmt: skip
    """The demo settings of a SWMM loop, every number from the twin (see the module).

    Returns
    -------
    gatetwin.mpc.demo.DemoSettings
    """
    from gatetwin.mpc.demo import DemoSettings

    ts, k = sample_period_s, point.gain_mm_per_mm
    sd = max(noise_sd_mm, 0.1)  # the gauge reads to 0.1 mm: no finer noise is meaningful
    observer = observer_settings(sd, point.opening_mm, point.time_constant_s, ts)
    n, step = horizon(point.time_constant_s, point.dead_time_s, ts)
    mpc = MpcSettings(horizon=n, sample_period_s=step, opening_range_mm=opening_range_mm,
                      opening_rate_mm_s=gate_speed_mm_s, level_band_mm=level_band_mm,
                      move_weight=gate_move_weight(k), move_weight_gain_mm_per_mm=abs(k),
                      observer=observer)  # fmt: skip
    pi = PiSettings(opening_range_mm=opening_range_mm, opening_rate_mm_s=gate_speed_mm_s,
                    sample_period_s=ts)  # fmt: skip
    step = abs(k) * point.gate_step_mm
    # white gauge noise: a correlation time far below the sample period (phi = e^-10)
    noise = MeasurementNoise(sd_mm=noise_sd_mm, correlation_s=ts / 10, resolution_mm=0.1)
    wide = {
        "wide_flow_m3h": point.flow_m3h,
        "wide_flow_step_m3h": 0.3 * point.flow_m3h,
        "wide_levels_mm": (point.level_mm, point.level_mm + step),
    }
    up = INFLOW_UP * point.flow_m3h
    return DemoSettings(**wide, flow_m3h=point.flow_m3h, inflow_step_to_m3h=up,
                        opening_mm=point.opening_mm, setpoint_step_mm=step, noise=noise,
                        actuator_resolution_mm=0.1, mpc=mpc, pi=pi,
                        loop=LoopSettings(settle_band_mm=3 * sd, sample_period_s=ts))  # fmt: skip


def mpc_demo_inputs(plant: FopdtPlant, spec_path: str | Path) -> tuple[Any, Any]:
    """``(settings, core_factory)`` of ``gatetwin mpc-demo --plant swmm``: the SWMM plant of
    a plant spec file (``noise_sd_mm`` in it, default 0: exact gauges) and the loop's
    settings derived from the twin ``plant`` at its reference opening and the model's
    base inflow; opening range the gate's; no level band (the twin states none here)."""
    from gatetwin.plants.swmm_experiments import gate_step_mm

    spec = read_spec(spec_path)
    doc = json.loads(Path(spec_path).read_text(encoding="utf-8"))
    noise = float(doc.get("noise_sd_mm", 0.0))
    if not (math.isfinite(noise) and noise >= 0):
        raise PlantError(f"{spec_path}: noise_sd_mm {noise}; expected >= 0 mm")
    factory = core_factory(spec)
    core = factory()
    opening = plant.opening_ref_mm
    point = TwinPoint.of(plant, 3600.0 * core.base_flow_m3s, opening, gate_step_mm(opening))
    settings = loop_settings(point, sample_period_s=spec.sample_period_s, noise_sd_mm=noise,
                             gate_speed_mm_s=spec.gate_speed_mm_s,
                             opening_range_mm=(0.0, core.height_mm),
                             level_band_mm=None)  # fmt: skip
    return settings, factory


def inflow_up_factor(plant: FopdtPlant, point: TwinPoint,
                     opening_range_mm: tuple[float, float]) -> float:  # fmt: skip
    """The largest of :data:`INFLOW_UP_STEPS` at which the twin holds the operating level
    with the gate short of :data:`OPENING_RESERVE` of its range from fully open: past that
    no controller can hold the level, and the scenario would compare two saturated gates."""
    from gatetwin.mpc.envelope import steady_opening_mm

    lo, hi = opening_range_mm
    reach = hi - OPENING_RESERVE * (hi - lo)
    for factor in INFLOW_UP_STEPS:
        need = steady_opening_mm(plant, factor * point.flow_m3h, point.level_mm, (lo, hi))
        if need <= reach:
            return factor
    return INFLOW_UP_STEPS[-1]


def canal_scenarios(point: TwinPoint, setpoint_step_mm: float,
                    up: float = INFLOW_UP) -> tuple[Scenario, ...]:  # fmt: skip
    """Set-point steps (+step, back), an inflow step up (by the factor ``up``) and one down;
    each event held :data:`HOLD_TIME_CONSTANTS` × (T + L) after one (T + L) at rest."""
    hold, rest = HOLD_TIME_CONSTANTS * point.response_s, point.response_s
    common = {"flow_m3h": point.flow_m3h, "opening_mm": point.opening_mm}
    q = point.flow_m3h
    return (
        Scenario(
            "setpoint_steps",
            rest + 2 * hold,
            setpoint_changes=((rest, setpoint_step_mm), (rest + hold, 0.0)),
            **common,
        ),  # fmt: skip
        Scenario("inflow_up", rest + hold, flow_changes=((rest, up * q),), **common),
        Scenario("inflow_down", rest + hold, flow_changes=((rest, INFLOW_DOWN * q),), **common),
    )


def canal_indicators(run: ClosedLoopRun, point: TwinPoint,
                     settings: LoopSettings) -> dict[str, Any]:  # fmt: skip
    """Clemmens et al. (1998) indicators over the window from the first event to the end,
    with :func:`loop_metrics`' violations and gate reversals (see the module)."""
    ts = settings.sample_period_s
    first = int(round(min(run.scenario.event_times_s(), default=0.0) / ts))
    err = (run.level_mm - run.setpoint_mm)[first:]
    tail = max(1, int(round(point.response_s / ts)))
    applied = np.concatenate([[run.scenario.opening_mm], run.applied_mm])
    base = loop_metrics(run, settings)
    return {
        "mae_mm": float(np.max(np.abs(err))),
        "iae_mean_mm": float(np.mean(np.abs(err))),
        "ste_mm": float(np.mean(err[-tail:])),
        "iaw_mm": float(np.sum(np.abs(np.diff(applied)))),
        "iae_mm_s": base["iae"],
        "violations": base["violations"],
        "violations_by_kind": base["violations_by_kind"],
        "gate_reversals_per_hour": base.get("gate_reversals_per_hour"),
        "settling_s": base["settling_s"],
        "window_s": float(err.size * ts),
        "solve_ms_median": base["solve_ms_median"],
    }


def settings_summary(settings: Any) -> dict[str, Any]:
    """The loop's settings as JSON (the MPC's, the observer's, the PI's, the noise)."""
    return {"mpc": {k: v for k, v in asdict(settings.mpc).items() if k != "observer"},
            "observer": asdict(settings.mpc.observer), "pi": asdict(settings.pi),
            "noise": asdict(settings.noise), "setpoint_step_mm": settings.setpoint_step_mm,
            "actuator_resolution_mm": settings.actuator_resolution_mm}  # fmt: skip


__all__ = [
    "record_ranges",
    "HOLD_TIME_CONSTANTS",
    "SPEC_KEYS",
    "TwinPoint",
    "canal_indicators",
    "canal_scenarios",
    "inflow_up_factor",
    "core_factory",
    "loop_settings",
    "mpc_demo_inputs",
    "read_spec",
    "settings_summary",
    "spec_to_dict",
]
