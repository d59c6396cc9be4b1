"""The online observer's arithmetic as casadi Functions, and their C (``casadi.CodeGenerator``).

What :class:`~gatetwin.mpc.online.OnlineObserver` does per sample is split into functions
of plain vectors, each built by running its own code (:func:`~gatetwin.mpc.discrete.
fopdt_model` through :class:`~gatetwin.mpc.codegen.SymbolicController`,
:class:`~gatetwin.mpc.observer.DisturbanceObserver`, :func:`~gatetwin.mpc.online.
monitor_sample`, :func:`~gatetwin.mpc.online.advance`) on casadi symbols:

* ``start(theta, q, e, y) -> (z, d, level, monitor)`` — the observer at rest at opening
  ``e``, level ``y``, the level it then estimates and the anomaly rules' state
  (:data:`~gatetwin.mpc.online.MONITOR`);
* ``riccati(theta, q, P) -> P`` — one correct-and-predict of the covariance (iterated to its
  fixed point: the steady prior covariance of the start);
* ``correct(theta, q, z, d, P, y, monitor, limits) -> (z, d, P, estimate, monitor)`` — the
  correction with the level measured now and the anomaly rules; ``limits`` is
  ``(band_sigma, run_samples, cusum_slack_sigma, cusum_threshold)``, ``estimate`` is
  :data:`ESTIMATE` (``move_uncertainty`` and ``scale_window_samples`` are built in);
* ``advance(theta, q, z, d, e) -> z`` — one sample of the model, inputs held (the forecast
  is this, ``horizon_s / Ts`` times);
* ``level(theta, q, z) -> level`` — the level the model reads in state ``z``;
* ``predict(theta, q_prev, q, z, d, P, e) -> (z, d, P)`` — the observer's prediction.

Either observer adds, given reference gauges, ``drift(window, count, y, others, threshold,
kind) -> (window_next, count_next, rule)``: the redundancy rule of
:mod:`gatetwin.mpc.gauge_drift` (:func:`~gatetwin.mpc.gauge_drift.drift_sample` and
:func:`~gatetwin.mpc.gauge_drift.with_drift_rule` on symbols; ``rule`` is
:data:`DRIFT_RULE`).

``theta`` is the MPC controller's (:func:`gatetwin.mpc.codegen.theta_names`): the schedule
interpolated at the measured discharge inside the functions.

The envelope observer (``linearisation="envelope"``) has its own functions
(:func:`build_envelope_functions`, prefix :data:`ENVELOPE_PREFIX`): its model is re-rendered
at every sample from the tangent's steady points ``x``, which the FMU computes with the plant
kernel's C at the openings ``openings(e)`` gives (:class:`SymbolicTangent`: the tangent's own
code, :func:`gatetwin.plant.model.tangent_point` and
:func:`gatetwin.mpc.envelope.tangent_model`, with the steady points as symbols), and its slow
filter and rule are :func:`gatetwin.mpc.online.slow_sample` and
:func:`~gatetwin.mpc.online.with_slow_rule` on symbols.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi
import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc import online
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.codegen import NEXT, Layout, SymbolicController, work_sizes, write_generated
from gatetwin.mpc.envelope import _datum_mm, envelope_register_length, tangent_model
from gatetwin.mpc.gauge_drift import WINDOW_SAMPLES, drift_sample, slope_weights, with_drift_rule
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.settings import MpcSettings, ObserverSettings
from gatetwin.mpc.statespace import DiscreteModel
from gatetwin.plant.model import FopdtPlant, PhysicalPlant, tangent_point

#: Prefix of every generated C function.
PREFIX = "gt_obs_"
#: Names of the generated functions (without the prefix), in generation order.
FUNCTIONS = ("start", "riccati", "correct", "advance", "level", "predict")
#: Entries of ``correct``'s ``estimate`` output, in order.
ESTIMATE = ("filtered_level_mm", "disturbance_mm", "innovation_mm", "innovation_normalised",
            "anomaly_samples", "anomaly", "anomaly_kind", "cusum_high", "cusum_low",
            "innovation_scale")  # fmt: skip
#: Entries of ``correct``'s ``limits`` input, in order (:meth:`AnomalySettings.limits`).
LIMITS = ("band_sigma", "run_samples", "cusum_slack_sigma", "cusum_threshold")


#: Entries of the ``drift`` function's ``rule`` output, in order: the FMU's outputs of the same
#: names (``anomaly_kind`` and ``anomaly`` overwrite the observer's own where the rule alone
#: holds).
DRIFT_RULE = ("gauge_slope_mm_per_s", "gauge_drift", "anomaly_kind", "anomaly")


def _sx(values: Any) -> casadi.SX:
    return casadi.densify(sym.to_casadi(values))


def drift_function(prefix: str, n_references: int, sample_period_s: float,
                   window_samples: int = WINDOW_SAMPLES) -> casadi.Function:  # fmt: skip
    """The redundancy rule's ``drift`` function (see the module) for ``n_references`` other
    gauges, named ``<prefix>drift``."""
    if n_references < 1:
        raise ControlError("gauge drift: at least one reference gauge is needed")
    names = ("count", "y", "threshold", "kind")
    s = {n: casadi.SX.sym(n) for n in names}
    window_sx, window = sym.symbols("window", window_samples)
    others_sx, others = sym.symbols("others", n_references)
    weights = [float(w) for w in slope_weights(window_samples, sample_period_s)]
    window_next, count, slope, flag = drift_sample(
        tuple(window), sym.Sym(s["count"]), sym.Sym(s["y"]), list(others), weights,
        sym.Sym(s["threshold"]))  # fmt: skip
    kind = with_drift_rule(sym.Sym(s["kind"]), flag)
    rule = [slope, flag, kind, sym.where(kind > 0.0, 1.0, 0.0)]
    return casadi.Function(prefix + "drift",
                           [window_sx, s["count"], s["y"], others_sx, s["threshold"], s["kind"]],
                           [_sx(list(window_next)), _sx(count), _sx(rule)],
                           ["window", "count", "y", "others", "threshold", "kind"],
                           ["window_next", "count_next", "rule"])  # fmt: skip


def build_observer_functions(
    n_knots: int,
    register: int,
    settings: ObserverSettings,
    sample_period_s: float,
    anomaly: online.AnomalySettings | None = None,
    n_references: int = 0,
) -> tuple[dict[str, casadi.Function], Layout]:
    """The casadi Functions of the online observer (see the module; ``drift`` for
    ``n_references`` > 0 reference gauges), and its sizes."""
    anomaly = anomaly or online.AnomalySettings()
    mpc_settings = MpcSettings(sample_period_s=sample_period_s, observer=settings)
    ctl = SymbolicController(n_knots, register, mpc_settings)
    lay, theta = ctl.layout, ctl.theta
    names = ("q", "q_prev", "e", "y", "d")
    scalars = {n: casadi.SX.sym(n) for n in names}
    q, q_prev, e, y, d = (sym.Sym(v) for v in scalars.values())
    zs, z = sym.symbols("z", lay.n_states)
    monitor_sx, monitor = sym.symbols("monitor", len(online.MONITOR))
    limits_sx, limits = sym.symbols("limits", len(LIMITS))
    ps = casadi.SX.sym("P", lay.n_states + 1, lay.n_states + 1)
    p = sym.from_casadi(ps)
    s = scalars
    fns: dict[str, casadi.Function] = {}

    def add(name: str, ins: list[Any], in_names: list[str], outs: list[Any],
            out_names: list[str]) -> None:  # fmt: skip
        fns[name] = casadi.Function(PREFIX + name, ins, [_sx(o) for o in outs],
                                    in_names, out_names)  # fmt: skip

    model = ctl.model(q)
    obs = ctl.observer(model, z, d, p)
    obs.start(model, e, y)
    level = model.level_mm(obs.state)
    add("start", [theta, s["q"], s["e"], s["y"]], ["theta", "q", "e", "y"],
        [obs.state, obs.disturbance_mm, level, list(online.start_monitor(level))],
        ["z", "d", "level", "monitor"])  # fmt: skip

    obs = ctl.observer(model, z, d, p)
    obs.correct(model, 0.0)
    obs.predict(model, 0.0)
    add("riccati", [theta, s["q"], ps], ["theta", "q", "P"], [obs.covariance], ["P_next"])

    obs = ctl.observer(model, z, d, p)
    estimate, monitor_next = online.monitor_sample(obs, model, y, tuple(monitor),
                                                   tuple(limits), anomaly)  # fmt: skip
    add("correct", [theta, s["q"], zs, s["d"], ps, s["y"], monitor_sx, limits_sx],
        ["theta", "q", "z", "d", "P", "y", "monitor", "limits"],
        [obs.state, obs.disturbance_mm, obs.covariance, list(estimate), list(monitor_next)],
        [*NEXT, "estimate", "monitor_next"])  # fmt: skip

    add("advance", [theta, s["q"], zs, s["d"], s["e"]], ["theta", "q", "z", "d", "e"],
        [online.advance(model, z, d, e)], ["z_next"])  # fmt: skip
    add("level", [theta, s["q"], zs], ["theta", "q", "z"], [model.level_mm(z)], ["level"])

    obs = ctl.observer(ctl.model(q_prev), z, d, p)
    obs.predict(model, e)
    add("predict", [theta, s["q_prev"], s["q"], zs, s["d"], ps, s["e"]],
        ["theta", "q_prev", "q", "z", "d", "P", "e"],
        [obs.state, obs.disturbance_mm, obs.covariance], NEXT)  # fmt: skip
    if n_references:
        fns["drift"] = drift_function(PREFIX, n_references, sample_period_s)
    return fns, lay


def generate_observer_c(
    fns: dict[str, casadi.Function], folder: Path, stem: str, what: str = "the observer"
) -> dict[str, dict[str, int]]:
    """Write ``<stem>.c`` and ``<stem>.h`` (the C of ``what``) into ``folder``; return each
    function's work sizes."""
    cg = casadi.CodeGenerator(f"{stem}.c", {"with_header": False, "verbose": False})
    for f in fns.values():
        cg.add(f)
    write_generated(folder, stem, cg.dump(), "gatetwin.mpc.observer_codegen",
                    [f.name() for f in fns.values()], what)  # fmt: skip
    return {name: work_sizes(f) for name, f in fns.items()}


# -- the envelope observer -----------------------------------------------------------------------
#: Prefix of every generated C function of the envelope observer.
ENVELOPE_PREFIX = "gt_env_"
#: Names of the envelope observer's generated functions (without the prefix), in order.
ENVELOPE_FUNCTIONS = ("openings", "start", "riccati", "slow_riccati", "correct", "slow",
                      "predict", "advance", "level")  # fmt: skip
#: Entries of the envelope ``slow`` function's ``rule`` output, in order.
SLOW_RULE = ("anomaly_kind", "anomaly", "slow_cusum")


class _PointInputs:
    """:func:`gatetwin.plant.model.envelope_point` on symbols: its ``i``-th call returns the
    ``i``-th (level, time constant) pair of ``values`` and records the opening it was asked
    at, which the C computes the point at (with the kernel's own C, ``physical_kernel.c``)."""

    def __init__(self, values: np.ndarray) -> None:
        self.values = values
        self.openings: list[Any] = []

    def __call__(self, opening_mm: Any, flow_m3h: Any, p: list[float]) -> tuple[Any, Any]:
        i = len(self.openings)
        self.openings.append(opening_mm)
        return self.values[2 * i], self.values[2 * i + 1]


def envelope_dead_time_s(plant: FopdtPlant | PhysicalPlant) -> float:
    """The tangent's dead time, which the generated register is built for: none for a
    physical plant; an envelope FOPDT's only if one dead time holds at every knot."""
    if isinstance(plant, PhysicalPlant):
        return 0.0
    delays = set(plant.schedule.values["dead_time_s"])
    if len(delays) != 1:
        raise ControlError("envelope observer FMU: the schedule's dead time must be one value "
                           f"at every knot (got {sorted(delays)} s)")  # fmt: skip
    return float(delays.pop())


class SymbolicTangent:
    """The envelope observer's re-linearised model on casadi symbols, from its own code
    (:func:`gatetwin.plant.model.tangent_point`, :func:`gatetwin.mpc.envelope.tangent_model`).

    ``x`` is :data:`N_POINTS` steady points ``(level_mm, time_constant_s)`` in a row, computed
    at the openings :meth:`openings` gives for the opening ``e``."""

    def __init__(self, plant: FopdtPlant | PhysicalPlant, sample_period_s: float) -> None:
        self.plant, self.sample_period_s = plant, sample_period_s
        self.delay_s = envelope_dead_time_s(plant)
        self.register = envelope_register_length(plant, sample_period_s)

    def model(self, x: np.ndarray, q: Any, e: Any) -> tuple[DiscreteModel, list[Any]]:
        """The tangent model at (``q``, ``e``) and the openings its points were asked at."""
        points = _PointInputs(x)
        point = tangent_point(points, self.plant, q, e, [], self.delay_s)
        model = tangent_model(self.plant, point, _datum_mm(self.plant, q), q, e,
                              self.sample_period_s)  # fmt: skip
        return model, points.openings


#: Steady points the tangent takes (the opening itself and the two of the central difference).
N_POINTS = 3


def build_envelope_functions(
    plant: FopdtPlant | PhysicalPlant,
    settings: ObserverSettings,
    slow_settings: ObserverSettings,
    sample_period_s: float,
    anomaly: online.AnomalySettings,
    n_references: int = 0,
) -> tuple[dict[str, casadi.Function], Layout]:
    """The casadi Functions of the envelope observer (``drift`` for ``n_references`` > 0
    reference gauges), and its sizes.

    ``x`` (a model's steady points, :class:`SymbolicTangent`), ``q`` and ``e`` name the model
    re-linearised at the discharge and opening of a sample; ``x_prev``, ``q_prev``, ``e_prev``
    the last prediction's. ``openings(e) -> o``: where the points of ``x`` are taken;
    ``start(x, q, e, y) -> (z, d, level, monitor)``; ``riccati`` and ``slow_riccati``
    ``(x, q, e, P) -> P``; ``correct(x_prev, q_prev, e_prev, z, d, P, y, monitor, limits)`` as
    the schedule observer's; ``slow(x_prev, q_prev, e_prev, x, q, e, z, d, P, y, monitor,
    kind) -> (z, d, P, monitor, rule)`` (:func:`~gatetwin.mpc.online.slow_sample` and
    :func:`~gatetwin.mpc.online.with_slow_rule`, ``rule`` is :data:`SLOW_RULE`);
    ``predict(x_prev, q_prev, e_prev, x, q, e, z, d, P) -> (z, d, P, d_now)`` (the
    disturbance rescaled to the new gain, then predicted); ``advance(x, q, e, z, d) -> z``;
    ``level(x, q, e, z) -> level``.
    """
    tangent = SymbolicTangent(plant, sample_period_s)
    nz = 1 + tangent.register
    lay = Layout(0, tangent.register, nz, 0, 0)
    names = ("q", "q_prev", "e", "e_prev", "y", "d", "kind")
    s = {n: casadi.SX.sym(n) for n in names}
    q, q_prev, e, e_prev, y, d, kind = (sym.Sym(v) for v in s.values())
    xs, x = sym.symbols("x", 2 * N_POINTS)
    xps, xp = sym.symbols("x_prev", 2 * N_POINTS)
    zs, z = sym.symbols("z", nz)
    monitor_sx, monitor = sym.symbols("monitor", len(online.MONITOR))
    limits_sx, limits = sym.symbols("limits", len(LIMITS))
    ps = casadi.SX.sym("P", nz + 1, nz + 1)
    p = sym.from_casadi(ps)
    fns: dict[str, casadi.Function] = {}

    def add(name: str, ins: list[str], outs: list[Any], out_names: list[str]) -> None:
        by_name = {**s, "x": xs, "x_prev": xps, "z": zs, "P": ps, "monitor": monitor_sx,
                   "limits": limits_sx}  # fmt: skip
        fns[name] = casadi.Function(ENVELOPE_PREFIX + name, [by_name[n] for n in ins],
                                    [_sx(o) for o in outs], ins, out_names)  # fmt: skip

    def observer(obs_settings: ObserverSettings) -> DisturbanceObserver:
        obs = DisturbanceObserver(obs_settings)
        obs.set_estimate(z, d, p, 0.0)
        return obs

    model, openings = tangent.model(x, q, e)
    last, _ = tangent.model(xp, q_prev, e_prev)
    if len(openings) != N_POINTS:
        raise ControlError(f"envelope observer: the tangent takes {len(openings)} steady points, "
                           f"the generated code {N_POINTS}")  # fmt: skip
    add("openings", ["e"], [openings], ["openings"])

    obs = observer(settings)
    obs.start(model, e, y)
    level = model.level_mm(obs.state)
    add("start", ["x", "q", "e", "y"],
        [obs.state, obs.disturbance_mm, level, list(online.start_monitor(level))],
        ["z", "d", "level", "monitor"])  # fmt: skip
    for name, obs_settings in (("riccati", settings), ("slow_riccati", slow_settings)):
        obs = observer(obs_settings)
        obs.correct(model, 0.0)
        obs.predict(model, 0.0)
        add(name, ["x", "q", "e", "P"], [obs.covariance], ["P_next"])

    obs = observer(settings)
    estimate, monitor_next = online.monitor_sample(obs, last, y, tuple(monitor), tuple(limits),
                                                   anomaly)  # fmt: skip
    add("correct", ["x_prev", "q_prev", "e_prev", "z", "d", "P", "y", "monitor", "limits"],
        [obs.state, obs.disturbance_mm, obs.covariance, list(estimate), list(monitor_next)],
        [*NEXT, "estimate", "monitor_next"])  # fmt: skip

    obs = observer(slow_settings)
    estimate, monitor_next = online.slow_sample(obs, last, model, y, e, tuple(monitor), anomaly)
    rule_kind, slow_cusum = online.with_slow_rule(kind, estimate)
    rule = [rule_kind, sym.where(rule_kind > 0.0, 1.0, 0.0), slow_cusum]
    add("slow", ["x_prev", "q_prev", "e_prev", "x", "q", "e", "z", "d", "P", "y", "monitor",
                 "kind"],
        [obs.state, obs.disturbance_mm, obs.covariance, list(monitor_next), rule],
        [*NEXT, "monitor_next", "rule"])  # fmt: skip

    obs = observer(settings)
    obs.rescale_disturbance(last.dc_gain_mm_per_mm(), model.dc_gain_mm_per_mm())
    d_now = obs.disturbance_mm
    obs.predict(model, e)
    add("predict", ["x_prev", "q_prev", "e_prev", "x", "q", "e", "z", "d", "P"],
        [obs.state, obs.disturbance_mm, obs.covariance, d_now], [*NEXT, "d_now"])  # fmt: skip

    add("advance", ["x", "q", "e", "z", "d"], [online.advance(model, z, d, e)], ["z_next"])
    add("level", ["x", "q", "e", "z"], [model.level_mm(z)], ["level"])
    if n_references:
        fns["drift"] = drift_function(ENVELOPE_PREFIX, n_references, sample_period_s)
    return fns, lay


def generate_envelope_c(
    fns: dict[str, casadi.Function], folder: Path, stem: str
) -> dict[str, dict[str, int]]:
    """Write the envelope observer's ``<stem>.c`` and ``<stem>.h`` into ``folder``; return
    each function's work sizes."""
    return generate_observer_c(fns, folder, stem, "the envelope observer")


__all__ = ["DRIFT_RULE", "ENVELOPE_FUNCTIONS", "ENVELOPE_PREFIX", "ESTIMATE", "FUNCTIONS",
           "LIMITS", "N_POINTS", "PREFIX", "SLOW_RULE", "SymbolicTangent",
           "build_envelope_functions", "build_observer_functions", "drift_function",
           "envelope_dead_time_s", "generate_envelope_c", "generate_observer_c"]  # fmt: skip
