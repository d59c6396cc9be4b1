"""Controller settings derived from a model file: nothing of the lab flume, all from the model.

A controller FMU is built for the gate its model describes, so its operating point, limits,
sample period, horizon and weights come from that model (rules below); an explicit
:class:`~gatetwin.mpc.demo.DemoSettings` still overrides them all.

* **Plant**: an FOPDT model as it is, an envelope FOPDT's schedule carried to the validity's
  discharge range by its gate law (:func:`_extended`: a clamped schedule holds the last
  step condition's level where the records went further); a physical model (which neither
  SIMC nor the MPC takes) linearised along its discharge range at the reference opening
  (:func:`~gatetwin.plant.model.local_fopdt` at :data:`LINEARISATION_KNOTS` discharges: K,
  T and the steady level; no dead time: the pool answers at once, the actuator's travel is
  the rate limit) at the opening that holds the middle of the validity's level range at its
  middle discharge; knots where the gate does not control the level (gain below
  :data:`GAIN_FLOOR` of the largest) are dropped. Its seiche is left out.
* **Operating point**: the middle of the validity's discharge range and the FOPDT's
  ``opening_ref_mm`` (for a physical model, the opening of its linearisation).
* **Sample period** ``Ts``: the records' (``validity.sample_period_s``, or the ARX's); a file
  written before it was recorded keeps the controllers' historical 1.2 s.
* **Limits**: the validity's opening range, or the gate's range when given; the gate's
  loaded speed at the operating depth where the model knows its actuator (physical or
  envelope parameters), else no rate limit (the whole range in one sample); the MPC's level
  band is the validity's level range, else the levels the schedule reaches over the opening
  range.
* **MPC horizon**: it covers the 2 % settling time ``4 T_max + L_max`` of the slowest
  knot in at most :data:`HORIZON_MAX` prediction steps. The prediction step is the sample
  period ``Ts`` while ``HORIZON_MAX`` samples reach one time constant past the dead time
  (``T_max + L_max``, 63 %); beyond, it is ``k Ts`` with ``k = ceil((T_max + L_max) /
  (HORIZON_MAX Ts))``, which the controller FMU also steps at. ``N = min(HORIZON_MAX,
  ceil((4 T_max + L_max) / (k Ts)))``. A pool answering in 520 s at 10 s sampling: a 10 s
  step and N = 100 (1000 s); one answering in an hour: k = 4, a 40 s step and N = 100.
  Reacting at every sample weighs more than predicting to the end of settling: on the
  ASCE canal's SWMM model the MPC FMU sampling at 30 s (N = 70) lost to the PI FMU on
  every scenario, at 10 s (N = 100) it beat it.
* **Observer**: where the model file states its gauge's noise (``validity.level_noise_sd_mm``,
  the noise floors of the records it was identified from), :func:`observer_settings`;
  else the observer's defaults.
* **MPC weights**: the level error's 1/mm²; a gate move's
  :func:`~gatetwin.mpc.settings.gate_move_weight` ``K²`` at the operating point, so that a
  move costs what its whole steady effect on the level costs as a level error (the rule of
  every MPC here); the envelope's move-weight reference gain is the operating point's
  ``|K|``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from gatetwin.errors import ExportError
from gatetwin.modelfile import ModelFile, validity_envelope
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.model import (
    OPENING_RANGE_MM,
    ArxPlant,
    FopdtPlant,
    PhysicalPlant,
    Schedule,
    kernel_parameters,
    local_fopdt,
    steady_depth_m,
)

__all__ = [
    "BISECTION_STEPS",
    "DEMO_HORIZON_SPANS",
    "DEMO_MINUTES",
    "DISTURBANCE_SHARE",
    "GAIN_FLOOR",
    "HORIZON_MAX",
    "HORIZON_MIN",
    "LEGACY_SAMPLE_PERIOD_S",
    "LINEARISATION_KNOTS",
    "SETPOINT_STEP_SHARE",
    "SETTLING_TIME_CONSTANTS",
    "WIDE_FLOW_STEP_SHARE",
    "controller_plant",
    "demo_minutes",
    "demo_settings",
    "derived_settings",
    "horizon",
    "level_band_mm",
    "observer_settings",
    "opening_rate_mm_s",
    "operating_point",
    "sample_period_s",
]

#: Longest MPC horizon, samples (the step's cost grows about as N³; 100 is what the C MPC
#: solves within a sample on the flume's 1.2 s).
HORIZON_MAX = 100
#: Shortest MPC horizon, samples.
HORIZON_MIN = 10
#: Settling time in time constants (2 %: e^-4 = 1.8 %).
SETTLING_TIME_CONSTANTS = 4.0
#: Discharge knots of a physical model's linearisation.
LINEARISATION_KNOTS = 5
#: Knots whose gain is below this fraction of the largest are dropped (the gate not in control).
GAIN_FLOOR = 0.01
#: Bisection steps of the operating opening (a range of 50 m to 0.1 micrometre).
BISECTION_STEPS = 40
#: Sample period of model files written before they recorded one, s.
LEGACY_SAMPLE_PERIOD_S = 1.2


def controller_plant(model: ModelFile) -> FopdtPlant:
    """The FOPDT a controller is tuned on: the model's, or a physical model's linearisation."""
    plant = model.plant
    if isinstance(plant, FopdtPlant):
        return _extended(plant, model) if plant.envelope is not None else plant
    if not isinstance(plant, PhysicalPlant):
        raise ExportError(f"controllers are tuned on an FOPDT or a physical model; got a "
                          f"{plant.kind} model")  # fmt: skip
    q_lo, q_hi = validity_envelope(model.content).get("flow_m3h", plant.schedule.flow_range_m3h)
    opening = operating_point(model)[1]
    flows = np.linspace(q_lo, q_hi, LINEARISATION_KNOTS) if q_hi > q_lo else np.array([q_lo])
    rows = [local_fopdt(plant, float(q), opening) for q in flows]
    # where the gate passes the flow at the critical-flow cap (lifted clear of the water) the
    # level does not answer the opening: no knot there
    biggest = max(abs(r["gain_mm_per_mm"]) for r in rows)
    keep = [i for i, r in enumerate(rows) if abs(r["gain_mm_per_mm"]) > GAIN_FLOOR * biggest]
    if not keep:
        raise ExportError(f"{model.name}: the level does not answer the opening anywhere in the "
                          "validity range; no controller can be tuned")  # fmt: skip
    flows, rows = flows[keep], [rows[i] for i in keep]
    values = {
        "gain_mm_per_mm": tuple(r["gain_mm_per_mm"] for r in rows),
        "time_constant_s": tuple(r["time_constant_s"] for r in rows),
        "dead_time_s": tuple(0.0 for _ in rows),
        "level_ref_mm": tuple(r["level_mm"] for r in rows),
    }
    return FopdtPlant(plant.gauge, opening, Schedule(tuple(float(q) for q in flows), values))


def operating_point(model: ModelFile) -> tuple[float, float]:
    """A physical model's operating point, ``(flow_m3h, opening_mm)``: the middle of its
    validity's discharge range and the opening that holds the middle of its level range
    there (within its opening range), where its controller is linearised."""
    plant = model.plant
    box = validity_envelope(model.content)
    q_lo, q_hi = box.get("flow_m3h", plant.schedule.flow_range_m3h)
    e_lo, e_hi = box.get("opening_mm") or _no_range(model, "opening_range_mm")
    h_lo, h_hi = box.get("level_mm") or _no_range(model, "level_range_mm")
    flow = 0.5 * (q_lo + q_hi)
    return flow, _opening_for(plant, flow, 0.5 * (h_lo + h_hi), (e_lo, e_hi))


def _extended(plant: FopdtPlant, model: ModelFile) -> FopdtPlant:
    """An envelope FOPDT's schedule carried out to the validity's discharge range: a knot at
    each end the step conditions did not reach, its K and T the nearest condition's scaled by
    the envelope's ratio between the two discharges, its level the nearest condition's
    moved by the envelope's difference (the gate law extrapolates where a clamped schedule
    would hold the last condition's level: an inflow step to the range's end then moves the
    steady level the model predicts)."""
    s = plant.schedule
    q_lo, q_hi = validity_envelope(model.content).get("flow_m3h", s.flow_range_m3h)
    knots, values = list(s.flow_m3h), {k: list(v) for k, v in s.values.items()}
    ends = [(q, 0) for q in (q_lo,) if q < knots[0]] + [(q, -1) for q in (q_hi,) if q > knots[-1]]
    for q, i in ends:
        near = local_fopdt(plant, knots[i], plant.opening_ref_mm)
        far = local_fopdt(plant, float(q), plant.opening_ref_mm)
        if not (abs(near["gain_mm_per_mm"]) > 0.0 and near["time_constant_s"] > 0.0):
            continue  # the envelope gives no ratio to scale the condition's K and T by
        row = {
            "gain_mm_per_mm": values["gain_mm_per_mm"][i]
            * far["gain_mm_per_mm"]
            / near["gain_mm_per_mm"],
            "time_constant_s": values["time_constant_s"][i]
            * far["time_constant_s"]
            / near["time_constant_s"],
            "dead_time_s": values["dead_time_s"][i],
            "level_ref_mm": values["level_ref_mm"][i] + far["level_mm"] - near["level_mm"],
        }
        # the gate lifted clear of the water at the reference opening: no control there (as
        # a physical model's linearisation drops such knots)
        biggest = max(abs(k) for k in values["gain_mm_per_mm"])
        if not (all(math.isfinite(v) for v in row.values()) and row["time_constant_s"] > 0
                and abs(row["gain_mm_per_mm"]) > GAIN_FLOOR * biggest):  # fmt: skip
            continue
        at = 0 if i == 0 else len(knots)
        knots.insert(at, float(q))
        for key in values:
            values[key].insert(at, float(row[key]))
    if len(knots) == len(s.flow_m3h):
        return plant
    schedule = Schedule(tuple(knots), {k: tuple(v) for k, v in values.items()})
    return replace(plant, schedule=schedule)


def _opening_for(plant: PhysicalPlant, flow_m3h: float, level_mm: float,
                 opening_range_mm: tuple[float, float]) -> float:  # fmt: skip
    """The opening holding ``level_mm`` at ``flow_m3h`` (the steady level falls as the gate
    opens: bisection), clamped to the range, mm."""
    lo, hi = opening_range_mm
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if plant.steady_level_mm(mid, flow_m3h) > level_mm:
            lo = mid
        else:
            hi = mid
    return round(0.5 * (lo + hi), 3)


def _no_range(model: ModelFile, key: str) -> Any:
    raise ExportError(f"{model.name}: the model file states no validity {key}; a controller "
                      "needs the opening range it may use")  # fmt: skip


def sample_period_s(model: ModelFile) -> float:
    """The records' sample period the model file states (see the module docstring), s."""
    if isinstance(model.plant, ArxPlant):
        return float(model.plant.sample_period_s)
    value = model.content.get("validity", {}).get("sample_period_s")
    return float(value) if value is not None else LEGACY_SAMPLE_PERIOD_S


def _kernel_parameters(model: ModelFile) -> list[float] | None:
    carried = kernel_parameters(model.plant)
    return list(carried[1].values()) if carried else None


def opening_rate_mm_s(model: ModelFile, opening_mm: float, flow_m3h: float,
                      opening_range_mm: tuple[float, float], ts: float) -> float:  # fmt: skip
    """The gate's loaded speed at the operating point, else the whole range per sample."""
    p = _kernel_parameters(model)
    if p is None:
        return (opening_range_mm[1] - opening_range_mm[0]) / ts
    depth = steady_depth_m(opening_mm, flow_m3h, p)
    return float(kernel.actuator_speed_mm_s(depth, p))


def horizon(time_constant_s: float, dead_time_s: float, ts: float) -> tuple[int, float]:
    """MPC horizon (prediction steps) and prediction step (s) of a plant answering with
    ``time_constant_s`` after ``dead_time_s`` (the module docstring)."""
    settling = SETTLING_TIME_CONSTANTS * time_constant_s + dead_time_s
    k = max(1, math.ceil((time_constant_s + dead_time_s) / (HORIZON_MAX * ts)))
    n = min(HORIZON_MAX, math.ceil(settling / (k * ts)))
    return max(HORIZON_MIN, n), k * ts


def level_band_mm(model: ModelFile, plant: FopdtPlant, opening_range_mm: tuple[float, float]
                  ) -> tuple[float, float]:  # fmt: skip
    """The validity's level range, else the schedule's levels over the opening range."""
    box = validity_envelope(model.content)
    if "level_mm" in box and box["level_mm"][1] > box["level_mm"][0]:
        return float(box["level_mm"][0]), float(box["level_mm"][1])
    s = plant.schedule
    levels = [
        ref + k * (e - plant.opening_ref_mm)
        for ref, k in zip(s.values["level_ref_mm"], s.values["gain_mm_per_mm"], strict=True)
        for e in opening_range_mm
    ]
    return min(levels), max(levels)


#: The input disturbance the observer expects per time constant, as a share of the opening: an
#: inflow change of some 10 % is what a gate under the MPC takes up (the size of the gate
#: step of the experiments that identify it).
DISTURBANCE_SHARE = 0.1


def observer_settings(noise_sd_mm: float, opening_mm: float, time_constant_s: float,
                      ts: float) -> Any:  # fmt: skip
    """The disturbance observer of a gate whose gauge reads with ``noise_sd_mm``: readings
    and the level's own wander weighed by that noise, and an input disturbance walking
    ``DISTURBANCE_SHARE`` of the opening per time constant (``sqrt(Ts / T)`` of it per
    sample).

    Returns
    -------
    gatetwin.mpc.settings.ObserverSettings
    """
    from gatetwin.mpc.settings import ObserverSettings

    walk = DISTURBANCE_SHARE * opening_mm * math.sqrt(ts / max(time_constant_s, ts))
    return ObserverSettings(measurement_sd_mm=noise_sd_mm, level_sd_mm=noise_sd_mm,
                            disturbance_sd_mm=max(walk, 1e-6))  # fmt: skip


#: The demo's set-point steps as a share of the model's level band (the flume's 20 mm steps are
#: 7 % of its 100-360 mm band).
SETPOINT_STEP_SHARE = 0.1
#: The wide-range scenario's discharge step as a share of its discharge (the flume's 30 m³/h
#: at 50 m³/h is 0.6; a field gate's range is narrower relative to its discharge).
WIDE_FLOW_STEP_SHARE = 0.3


def demo_settings(model: ModelFile) -> Any:
    """The closed loop's :class:`~gatetwin.mpc.demo.DemoSettings` for ``model``'s gate.

    The flume demo's (``DemoSettings()``) where the model's validity holds their operating
    point (discharge and opening), so the bundled models keep their published loop. Any
    other gate gets its own: the operating point, limits, sample period, horizon and
    observer of :func:`derived_settings` (those ``export-controller`` builds with), set-point
    steps of :data:`SETPOINT_STEP_SHARE` of its level band, the inflow step up to the top of
    its discharge range, the wide-range scenario between the band's quarter points with
    discharge steps of :data:`WIDE_FLOW_STEP_SHARE`, gauge noise of the records' level noise
    (white at the sample period) and a settle band of three times that noise, all sized
    from the validity's level range. A model file with none keeps the flume demo's steps
    and scoring at its own operating point and sample period.
    """
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.loop import LoopSettings
    from gatetwin.mpc.plants import MeasurementNoise

    demo = DemoSettings()
    box = validity_envelope(model.content)
    q_lo, q_hi = box.get("flow_m3h", (-math.inf, math.inf))
    e_lo, e_hi = box.get("opening_mm", (-math.inf, math.inf))
    if q_lo <= demo.flow_m3h <= q_hi and e_lo <= demo.opening_mm <= e_hi:
        return demo
    s = derived_settings(model, controller_plant(model))
    ts = s.pi.sample_period_s
    band = box.get("level_mm")
    if band is None:  # no level range to size the steps by: the flume demo's steps
        return replace(s, loop=replace(s.loop, sample_period_s=ts))
    band_lo, band_hi = band
    width = band_hi - band_lo
    sd = float(model.content.get("validity", {}).get("level_noise_sd_mm") or demo.noise.sd_mm)
    return replace(
        s, setpoint_step_mm=SETPOINT_STEP_SHARE * width,
        inflow_step_to_m3h=max(q_hi, s.flow_m3h) if math.isfinite(q_hi) else s.flow_m3h,
        wide_flow_m3h=s.flow_m3h, wide_flow_step_m3h=WIDE_FLOW_STEP_SHARE * s.flow_m3h,
        wide_levels_mm=(band_lo + 0.25 * width, band_hi - 0.25 * width),
        noise=MeasurementNoise(sd_mm=sd, correlation_s=ts / 10.0, resolution_mm=0.1),
        loop=LoopSettings(settle_band_mm=3.0 * sd, sample_period_s=ts),
    )  # fmt: skip


#: The demo's scenarios last at least this long, min (the flume's loop).
DEMO_MINUTES = 30.0
#: ... and at least this many spans of the MPC's horizon (which covers the plant's settling,
#: 4 T + L): each of the set-point steps at 1/6, 1/2 and 5/6 of the run gets two.
DEMO_HORIZON_SPANS = 6.0


def demo_minutes(settings: Any) -> float:
    """How long the demo's scenarios run for ``settings`` (:func:`demo_settings`'), min:
    :data:`DEMO_MINUTES`, or :data:`DEMO_HORIZON_SPANS` spans of the MPC's horizon where
    longer (a pool that settles in hours runs for hours)."""
    span_s = settings.mpc.horizon * settings.mpc.sample_period_s
    return max(DEMO_MINUTES, DEMO_HORIZON_SPANS * span_s / 60.0)


def derived_settings(model: ModelFile, plant: FopdtPlant,
                     opening_range_mm: tuple[float, float] | None = None) -> Any:  # fmt: skip
    """:class:`~gatetwin.mpc.demo.DemoSettings` of ``model``'s gate (module docstring);
    ``opening_range_mm`` the gate's range the controllers may use, when it is wider (or
    narrower) than the openings the model was identified over (the default): an inflow step
    may need an opening the records never set."""
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.pi import PiSettings
    from gatetwin.mpc.settings import gate_move_weight

    box = validity_envelope(model.content)
    q_lo, q_hi = box.get("flow_m3h", plant.schedule.flow_range_m3h)
    flow = 0.5 * (q_lo + q_hi)
    lo, hi = opening_range_mm or box.get("opening_mm") or _no_range(model, "opening_range_mm")
    if not (OPENING_RANGE_MM[0] <= lo < hi <= OPENING_RANGE_MM[1]):
        raise ExportError(f"{model.name}: opening range [{lo}, {hi}] mm is empty or outside "
                          f"{OPENING_RANGE_MM[0]:g}..{OPENING_RANGE_MM[1]:g} mm")  # fmt: skip
    opening = min(max(plant.opening_ref_mm, lo), hi)
    ts = sample_period_s(model)
    rate = opening_rate_mm_s(model, opening, flow, (lo, hi), ts)
    n, step = horizon(max(plant.schedule.values["time_constant_s"]), plant.max_dead_time_s, ts)
    gain = abs(plant.schedule.at("gain_mm_per_mm", flow))
    demo = DemoSettings()
    noise = model.content.get("validity", {}).get("level_noise_sd_mm")
    observer = demo.mpc.observer if not noise else observer_settings(
        float(noise), opening, plant.schedule.at("time_constant_s", flow), ts)  # fmt: skip
    mpc = replace(
        demo.mpc, horizon=n, observer=observer, sample_period_s=step, opening_range_mm=(lo, hi),
        opening_rate_mm_s=rate, level_band_mm=level_band_mm(model, plant, (lo, hi)),
        level_weight=1.0, move_weight=gate_move_weight(gain),
        move_weight_gain_mm_per_mm=max(gain, 1e-9),
    )  # fmt: skip
    pi = PiSettings(opening_range_mm=(lo, hi), opening_rate_mm_s=rate, sample_period_s=ts)
    return replace(demo, flow_m3h=flow, opening_mm=opening, mpc=mpc, pi=pi)
