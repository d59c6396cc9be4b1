"""The MPC demo: MPC against a SIMC-tuned PI on the exported FMU or on the virtual flume.

Two scenarios from rest at Q = 40 m³/h and a 25 mm opening, measured with gauge noise:

* ``setpoint_steps`` — the level set-point steps +20 mm, −20 mm and back;
* ``inflow_step`` — the discharge steps 40 → 60 m³/h and the set-point holds.

With a model that carries an envelope (``fopdt`` with ``plant.envelope``, as identified
from the bundled records), a third scenario crosses the gate's range:

* ``wide_range`` — from rest at Q = 50 m³/h and 120 mm (the opening that holds it, ≈ 50 mm),
  the set-point steps to 300 mm (the gate near 22 mm, where ``|K|`` is ~6 times larger),
  then the discharge steps +30 m³/h (to 80) and −30 m³/h (back to 50).

It is run by the single-point MPC (``mpc``: the schedule's model, linearised once at
``opening_ref_mm``, as in the other scenarios) and by the MPC re-linearised on the envelope
at every sample (``mpc_envelope``, :mod:`gatetwin.mpc.envelope`), and by the PI tuned at
the demo's operating point (``pi``); the JSON gives the three scores and
``envelope_vs_single_point`` the two MPCs' IAE side by side.

Each controller runs each scenario on a fresh plant with the same noise sequence; the
result is the JSON of :func:`run_mpc_demo` and one PNG per scenario.

The demo plant (:func:`demo_plant`) stands in for the identified 3F model until one is
passed in: a scheduled FOPDT with ``K`` and ``T`` after the paper's Tables 2–3 (29.5 and
72.5 m³/h) and values in between and beyond, model dead times of 2–3 s (a least-squares
dead time, shorter than the paper's 3σ detection delay), and ``level_ref_mm(Q)`` computed
from the virtual flume: its steady level at 3F at ``opening_ref_mm`` = 25 mm (depth + the
gauge's datum; spin-up at each knot), so that model and flume agree at the reference
opening at every knot. One reference opening serves all knots (the schedule's
semantics); 25 mm is the opening the demo starts at. Away from it the tangent
``level_ref + K (e − 25)`` drifts from the flume, whose own gain at 25 mm is ≈ −9 mm/mm at
40 m³/h and ≈ −21 mm/mm at 60 m³/h, and which needs ≈ 44 mm, not the model's ≈ 36 mm, to
hold the start level at 60 m³/h: the mismatch the offset-free MPC lives with on the flume.
At 85 m³/h the 25 mm level (≈ 588 mm) lies above the flume's wall; it is a schedule value
only.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import ControlError
from gatetwin.flume import FlumeConfig, run_flume, spin_up
from gatetwin.mpc.controller import MpcController
from gatetwin.mpc.envelope import (
    gate_position_mm,
    has_envelope,
    steady_level_mm,
    steady_opening_mm,
)
from gatetwin.mpc.loop import (
    ClosedLoopRun,
    LoopSettings,
    Scenario,
    loop_metrics,
    run_closed_loop,
)
from gatetwin.mpc.pi import PiController, PiSettings, PiTuning, loop_margins, simc_pi_for_plant
from gatetwin.mpc.plants import FlumeCore, FmuCore, LoopPlant, MeasurementNoise, ModelCore
from gatetwin.mpc.settings import MpcSettings
from gatetwin.plant.model import FopdtPlant, Plant, Schedule, plant_from_dict

PLANT_KINDS = ("fmu", "flume", "model", "swmm")
#: Controllers the demo compares (see :func:`compare_controllers`).
CONTROLLERS = ("mpc", "mpc_envelope", "pi")
#: Name of the scenario across the gate's range (run when the model has an envelope).
WIDE_SCENARIO = "wide_range"

#: Demo FOPDT of gauge 3F: discharge knots (m³/h), K (mm/mm), T (s), model dead time L (s).
DEMO_SCHEDULE: dict[str, tuple[float, ...]] = {
    "flow_m3h": (29.5, 40.0, 50.0, 60.0, 72.5, 85.0),
    "gain_mm_per_mm": (-15.4, -13.6, -12.5, -13.8, -10.6, -10.4),
    "time_constant_s": (71.0, 62.0, 52.0, 55.0, 42.0, 40.0),
    "dead_time_s": (2.0, 2.0, 2.0, 2.5, 2.5, 3.0),
}


@lru_cache(maxsize=8)
def _default_flume_levels(
    flows: tuple[float, ...], opening_mm: float, gauge: str
) -> tuple[float, ...]:
    return flume_levels_mm(FlumeConfig(), flows, opening_mm, gauge)


def flume_levels_mm(
    config: FlumeConfig, flows_m3h: tuple[float, ...], opening_mm: float, gauge: str = "3F"
) -> tuple[float, ...]:
    """Steady level (depth + datum) at ``gauge`` for each discharge at ``opening_mm``, mm."""
    out = []
    for q in flows_m3h:
        state = spin_up(config, q, opening_mm)
        run = run_flume(config, np.full(2, opening_mm), np.full(2, q), state=state)
        out.append(float(run.depth_mm[gauge][-1] + config.gauge_datum_mm.get(gauge, 0.0)))
    return tuple(out)


def demo_plant(config: FlumeConfig | None = None, *, opening_ref_mm: float = 25.0) -> FopdtPlant:
    """Scheduled FOPDT of gauge 3F: paper's K, T, L; level_ref from the flume (see module)."""
    flows = DEMO_SCHEDULE["flow_m3h"]
    if config is None:
        levels = _default_flume_levels(flows, float(opening_ref_mm), "3F")
    else:
        levels = flume_levels_mm(config, flows, float(opening_ref_mm), "3F")
    values = {k: v for k, v in DEMO_SCHEDULE.items() if k != "flow_m3h"}
    values["level_ref_mm"] = tuple(levels)
    return FopdtPlant("3F", float(opening_ref_mm), Schedule(flows, values))


def load_demo_plant(model_path: str | Path | None = None) -> FopdtPlant:
    """The plant of a model file (must be FOPDT); without one, the scheduled FOPDT of gauge
    3F identified from the bundled records (the model ``gatetwin run`` exports; only that
    gauge is identified)."""
    if model_path is None:
        from gatetwin.bundled import bundled_records_dir
        from gatetwin.fleet.execute import map_tasks
        from gatetwin.identification.suite import gauge_fopdt, load_folder

        ident = load_folder(bundled_records_dir())
        [doc] = map_tasks(gauge_fopdt, [(ident, "3F")], None,
                          lambda job: f"gauge {job[1]}'s FOPDT")  # fmt: skip
        return plant_from_dict(doc["plant"])  # type: ignore[return-value]
    from gatetwin.modelfile import read_model_file

    plant = read_model_file(model_path).plant
    if not isinstance(plant, FopdtPlant):
        raise ControlError(
            f"{model_path}: the mpc demo needs an FOPDT model (the PI is tuned by SIMC); "
            f"got {plant.kind}"
        )
    return plant


@dataclass(frozen=True)
class DemoSettings:
    """The demo's operating point, disturbances, noise and controller settings.

    Attributes
    ----------
    flow_m3h : float
        Initial discharge, m³/h.
    inflow_step_to_m3h : float
        Discharge after the inflow step, m³/h.
    opening_mm : float
        Initial opening, mm (the plants start steady there; the set-point starts at the
        plant's level).
    setpoint_step_mm : float
        Size of the set-point steps, mm.
    wide_flow_m3h : float
        Discharge of the ``wide_range`` scenario, m³/h.
    wide_levels_mm : tuple[float, float]
        Its start level (the plants start at the opening the model says holds it, at the
        actuator's resolution) and its set-point after the step, mm.
    wide_flow_step_m3h : float
        Its discharge steps up by this, then back down by this, m³/h.
    noise : MeasurementNoise
        Gauge noise (SD 0.7 mm, AR(1), 0.1 mm resolution).
    actuator_resolution_mm : float
        The gate's position resolution, 1 mm (paper): applied in the plant only.
    mpc : MpcSettings
        MPC settings.
    pi : PiSettings
        PI limits (tuning: SIMC at ``flow_m3h``).
    loop : LoopSettings
        Scoring of the runs.
    """

    flow_m3h: float = 40.0
    inflow_step_to_m3h: float = 60.0
    opening_mm: float = 25.0
    setpoint_step_mm: float = 20.0
    wide_flow_m3h: float = 50.0
    wide_levels_mm: tuple[float, float] = (120.0, 300.0)
    wide_flow_step_m3h: float = 30.0
    noise: MeasurementNoise = field(default_factory=MeasurementNoise)
    actuator_resolution_mm: float = 1.0
    mpc: MpcSettings = field(default_factory=MpcSettings)
    pi: PiSettings = field(default_factory=PiSettings)
    loop: LoopSettings = field(default_factory=LoopSettings)


def demo_scenarios(minutes: float, settings: DemoSettings | None = None) -> tuple[Scenario, ...]:
    """Set-point steps at 1/6, 1/2 and 5/6 of the run; the inflow step at 1/6."""
    s = settings or DemoSettings()
    if not minutes >= 2:
        raise ControlError(f"demo: need at least 2 simulated minutes (got {minutes})")
    d = float(minutes) * 60.0
    step = s.setpoint_step_mm
    common = {"duration_s": d, "flow_m3h": s.flow_m3h, "opening_mm": s.opening_mm}
    return (
        Scenario(
            "setpoint_steps",
            setpoint_changes=((d / 6, step), (d / 2, -step), (5 * d / 6, 0.0)),
            **common,
        ),
        Scenario("inflow_step", flow_changes=((d / 6, s.inflow_step_to_m3h),), **common),
    )


def wide_scenario(
    plant_model: Plant, minutes: float, settings: DemoSettings | None = None
) -> Scenario:
    """``wide_range``: set-point step at 1/15 of the run, discharge +step at 2/5 and −step
    at 7/10; the start opening and the step's size from the model's envelope."""
    s = settings or DemoSettings()
    if not minutes >= 2:
        raise ControlError(f"demo: need at least 2 simulated minutes (got {minutes})")
    start_mm, target_mm = s.wide_levels_mm
    q = s.wide_flow_m3h
    opening = gate_position_mm(
        plant_model, steady_opening_mm(plant_model, q, start_mm, s.mpc.opening_range_mm)
    )
    offset = target_mm - steady_level_mm(plant_model, q, opening)
    d = float(minutes) * 60.0
    dq = s.wide_flow_step_m3h
    return Scenario(
        WIDE_SCENARIO,
        d,
        flow_m3h=q,
        opening_mm=opening,
        setpoint_changes=((d / 15, offset),),
        flow_changes=((0.4 * d, q + dq), (0.7 * d, q)),
    )


class _PlantFactory:
    """Fresh loop plants of one kind (the FMU is exported once, to a temporary folder)."""

    def __init__(
        self, plant: Plant, kind: str, settings: DemoSettings, core_factory: Any = None,
        plant_fmu: str | Path | None = None,
    ) -> None:  # fmt: skip
        if kind not in PLANT_KINDS:
            raise ControlError(f"plant kind must be one of {', '.join(PLANT_KINDS)} (got {kind!r})")
        if (kind == "swmm") != (core_factory is not None):
            raise ControlError("plant kind swmm goes with a SWMM core factory, and only it")
        self.plant, self.kind, self.settings = plant, kind, settings
        self.core_factory = core_factory  # the SWMM plant: gatetwin.plants.swmm_loop
        if plant_fmu is not None and kind != "fmu":
            raise ControlError(f"a plant FMU goes with plant kind fmu (got {kind!r})")
        self.plant_fmu = plant_fmu
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self._fmu: FmuCore | None = None

    def __enter__(self) -> _PlantFactory:
        if self.kind == "fmu" and self.plant_fmu is not None:
            self._fmu = FmuCore(self.plant_fmu, self.settings.mpc.sample_period_s)
        elif self.kind == "fmu":
            from gatetwin.fmu import export_fmu

            self._tmp = tempfile.TemporaryDirectory(prefix="gatetwin-mpc-")
            path = export_fmu(
                self.plant,
                Path(self._tmp.name) / "gatetwin_mpc_plant.fmu",
                backend="c",
                model_name="gatetwin_mpc_plant",
                provenance={"purpose": "gatetwin mpc-demo plant"},
            )
            self._fmu = FmuCore(path, self.settings.mpc.sample_period_s)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._fmu is not None:
            self._fmu.cleanup()
        if self._tmp is not None:
            self._tmp.cleanup()

    def make(self) -> LoopPlant:
        s = self.settings
        core: Any
        if self.kind == "fmu":
            core = self._fmu
        elif self.kind == "flume":
            core = FlumeCore()
        elif self.kind == "swmm":
            core = self.core_factory()
        else:
            core = ModelCore(self.plant, s.mpc.sample_period_s)
        return LoopPlant(
            core,
            noise=s.noise,
            actuator_resolution_mm=s.actuator_resolution_mm,
            sample_period_s=s.mpc.sample_period_s,
        )


def compare_controllers(
    plant_model: FopdtPlant,
    scenario: Scenario,
    *,
    plant_kind: str = "fmu",
    settings: DemoSettings | None = None,
    controllers: tuple[str, ...] = ("mpc", "pi"),
    core_factory: Any = None,
    plant_fmu: str | Path | None = None,
) -> dict[str, ClosedLoopRun]:
    """Run ``scenario`` with each controller, each on a fresh plant of one kind.

    All runs see the same noise sequence. ``controllers`` among ``"mpc"`` (the single-point
    MPC: the schedule's model at the measured discharge), ``"mpc_envelope"`` (re-linearised
    on the envelope at every sample; the model needs an envelope) and ``"pi"`` (SIMC,
    tuned at ``settings.flow_m3h``). ``core_factory`` makes the cores of plant kind
    ``"swmm"`` (:func:`gatetwin.plants.swmm_loop.core_factory`); ``plant_fmu``, the plant of
    kind ``"fmu"`` when ``plant_model`` was exported already (the C FMU, FMI 2.0; else it is
    exported here). Returns ``{name: run}``.
    """
    s = settings or DemoSettings()
    unknown = [c for c in controllers if c not in CONTROLLERS]
    if unknown:
        raise ControlError(f"demo: unknown controller(s) {', '.join(unknown)}; known: "
                           f"{', '.join(CONTROLLERS)}")  # fmt: skip
    runs = {}
    with _PlantFactory(plant_model, plant_kind, s, core_factory, plant_fmu) as factory:
        for name in controllers:
            runs[name] = _run_one(factory.make(), _controller(name, plant_model, s), scenario, s)
    return runs


def pi_controller(plant_model: Plant, settings: DemoSettings | None = None) -> PiController:
    """The demo's PI: SIMC-tuned at ``settings.flow_m3h`` on ``plant_model`` (an FOPDT), with
    the limits of ``settings.pi`` (also the C controller FMU's start values,
    :mod:`gatetwin.fmu.controller`)."""
    s = settings or DemoSettings()
    return PiController(_pi_tuning(plant_model, s), s.pi)


def _controller(name: str, plant_model: FopdtPlant, s: DemoSettings) -> Any:
    if name == "pi":
        return pi_controller(plant_model, s)
    linearisation = "schedule" if name == "mpc" else "envelope"
    return MpcController(plant_model, s.mpc, linearisation=linearisation)


def _pi_tuning(plant_model: Plant, s: DemoSettings) -> PiTuning:
    if not isinstance(plant_model, FopdtPlant):
        raise ControlError(
            "mpc demo: the PI baseline is tuned from an FOPDT plant; got "
            f"{type(plant_model).__name__}"
        )
    # tuned for the period it steps at (its own; the MPC's prediction step may be coarser)
    return simc_pi_for_plant(plant_model, s.flow_m3h, sample_period_s=s.pi.sample_period_s,
                             filter_time_s=s.pi.filter_time_s)  # fmt: skip


def run_mpc_demo(
    plant_model: FopdtPlant,
    *,
    plant_kind: str = "fmu",
    minutes: float = 30.0,
    out_plots_dir: str | Path | None = None,
    settings: DemoSettings | None = None,
    progress: Callable[[str], None] | None = None,
    core_factory: Any = None,
    plant_fmu: str | Path | None = None,
) -> dict[str, Any]:
    """Run the scenarios with the MPCs and the PI on one kind of plant.

    Parameters
    ----------
    plant_model : FopdtPlant
        The scheduled FOPDT the controllers are built from (and the FMU exported from).
    plant_kind : {"fmu", "flume", "model", "swmm"}
        The plant in the loop: the exported C FMU through fmpy, the virtual flume, the
        Python reference simulation, or an EPA SWMM model (made by ``core_factory``).
    minutes : float
        Simulated minutes per scenario (at the settings' control periods), at least 2.
    out_plots_dir : path, optional
        Where to write ``<scenario>.png``.
    settings : DemoSettings, optional
    progress : callable, optional
        Receives one line per finished scenario.
    core_factory : callable, optional
        Plant kind ``"swmm"``: makes a fresh SWMM core per run.
    plant_fmu : path, optional
        Plant kind ``"fmu"``: ``plant_model``'s C FMU (FMI 2.0) when it was exported already
        (else the demo exports it once per scenario).

    Returns
    -------
    dict
        ``{"plant", "model", "pi_tuning", "pi_margins", "settings",
        "scenarios": {name: {"mpc": metrics, "pi": metrics}}, "envelope_vs_single_point"}``,
        JSON-ready; the metrics are those of :func:`gatetwin.mpc.loop.loop_metrics`. With
        an envelope model, ``scenarios["wide_range"]`` holds ``{"mpc": metrics,
        "mpc_envelope": metrics, "pi": metrics}`` and ``envelope_vs_single_point`` their IAE and
        violations (:func:`envelope_comparison`; empty without an envelope).
    """
    s = settings or DemoSettings()
    tuning = _pi_tuning(plant_model, s)
    scenarios = demo_scenarios(minutes, s)
    out: dict[str, Any] = {
        "plant": plant_kind,
        "model": {
            "kind": plant_model.kind,
            "gauge": plant_model.gauge,
            "opening_ref_mm": plant_model.opening_ref_mm,
            "effects": [dict(e) for e in plant_model.effects],
        },
        "pi_tuning": tuning.to_dict(),
        "pi_margins": loop_margins(tuning).to_dict(),
        "settings": _settings_summary(s, minutes),
        "scenarios": {},
    }
    plan = [(scenario, ("mpc", "pi")) for scenario in scenarios]
    if has_envelope(plant_model):
        plan.append((wide_scenario(plant_model, minutes, s), CONTROLLERS))
    for scenario, controllers in plan:
        runs = compare_controllers(
            plant_model,
            scenario,
            plant_kind=plant_kind,
            settings=s,
            controllers=controllers,
            core_factory=core_factory,
            plant_fmu=plant_fmu,
        )
        metrics = {name: {**loop_metrics(run, s.loop), **run.extra} for name, run in runs.items()}
        out["scenarios"][scenario.name] = metrics
        if out_plots_dir is not None:
            plot_runs(runs, Path(out_plots_dir) / f"{scenario.name}.png", s.loop,
                      plant_model.gauge)  # fmt: skip
        if progress is not None:
            iae = ", ".join(f"{name} {m['iae']:.0f}" for name, m in metrics.items())
            progress(f"{plant_kind} {scenario.name}: IAE (mm·s) {iae}")
    out["envelope_vs_single_point"] = envelope_comparison(out["scenarios"])
    return out


def envelope_comparison(scenarios: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """IAE and violations of the envelope and the single-point MPC, per scenario run by
    both (``iae_ratio`` = envelope / single-point; below 1: the envelope MPC is better)."""
    out = {}
    for name, metrics in scenarios.items():
        if "mpc_envelope" not in metrics or "mpc" not in metrics:
            continue
        env, single = metrics["mpc_envelope"], metrics["mpc"]
        out[name] = {
            "iae_mpc": single["iae"],
            "iae_mpc_envelope": env["iae"],
            "iae_ratio": env["iae"] / single["iae"] if single["iae"] > 0 else None,
            "violations_mpc": single["violations"],
            "violations_mpc_envelope": env["violations"],
        }
    return out


def _run_one(
    plant: LoopPlant, controller: Any, scenario: Scenario, s: DemoSettings
) -> ClosedLoopRun:
    try:
        run = run_closed_loop(
            plant,
            controller,
            scenario,
            level_band_mm=s.mpc.level_band_mm,
            max_move_mm=s.mpc.max_move_mm,
            opening_range_mm=s.mpc.opening_range_mm,
            sample_period_s=s.mpc.sample_period_s,
        )
    finally:
        plant.close()
    if isinstance(controller, MpcController):
        run.extra["solver_failures"] = controller.failures
        run.extra["qp_solver"] = s.mpc.qp_solver
        run.extra["linearisation"] = controller.linearisation
    return run


def _settings_summary(s: DemoSettings, minutes: float) -> dict[str, Any]:
    return {
        "minutes": float(minutes),
        "sample_period_s": s.mpc.sample_period_s,
        "flow_m3h": s.flow_m3h,
        "inflow_step_to_m3h": s.inflow_step_to_m3h,
        "opening_mm": s.opening_mm,
        "setpoint_step_mm": s.setpoint_step_mm,
        "wide_flow_m3h": s.wide_flow_m3h,
        "wide_levels_mm": list(s.wide_levels_mm),
        "wide_flow_step_m3h": s.wide_flow_step_m3h,
        "noise": asdict(s.noise),
        "actuator_resolution_mm": s.actuator_resolution_mm,
        "mpc": {k: v for k, v in asdict(s.mpc).items() if k != "observer"},
        "observer": asdict(s.mpc.observer),
        "pi": asdict(s.pi),
        "loop": asdict(s.loop),
        "metrics_on": "true (noise-free) level; travel of the applied (rounded) opening",
    }


def plot_runs(runs: dict[str, ClosedLoopRun], path: str | Path,
              loop: LoopSettings | None = None, gauge: str = "3F") -> Path:  # fmt: skip
    """Level, set-point, opening and discharge of each controller's run, one PNG; the title's
    IAE scored with ``loop`` (its sample period: the loop's, default the flume's), the level
    axis named for ``gauge``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True, height_ratios=[3, 2, 1])
    colors = {"mpc": "tab:blue", "pi": "tab:orange", "mpc_envelope": "tab:green"}
    first = next(iter(runs.values()))
    on_top = ("pi", "mpc", "mpc_envelope")  # the PI first, the envelope MPC last
    for name in sorted(runs, key=lambda n: on_top.index(n) if n in on_top else -1):
        runs[name].plot(axes, color=colors.get(name))
    axes[0].step(
        first.time_s / 60,
        first.setpoint_mm,
        where="post",
        color="k",
        ls="--",
        lw=1.0,
        label="set-point",
    )
    axes[0].set_ylabel(f"level at {gauge} (mm)")
    axes[1].set_ylabel("opening (mm)")
    axes[2].set_ylabel("Q (m³/h)")
    axes[2].set_xlabel("time (min)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    iae = ", ".join(f"{name} {loop_metrics(run, loop)['iae']:.0f}" for name, run in runs.items())
    fig.suptitle(f"{first.scenario.name} — {first.plant} — IAE (mm·s): {iae}")
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=110)
    return target


__all__ = [
    "CONTROLLERS",
    "DEMO_SCHEDULE",
    "PLANT_KINDS",
    "WIDE_SCENARIO",
    "DemoSettings",
    "compare_controllers",
    "demo_plant",
    "demo_scenarios",
    "envelope_comparison",
    "flume_levels_mm",
    "load_demo_plant",
    "pi_controller",
    "plot_runs",
    "run_mpc_demo",
    "wide_scenario",
]
