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

``theta`` is the MPC controller's (:func:`gatetwin.mpc.codegen.theta_names`): the schedule
interpolated at the measured discharge inside the functions.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import casadi

from gatetwin.mpc import online
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.codegen import NEXT, Layout, SymbolicController, work_sizes, write_generated
from gatetwin.mpc.settings import MpcSettings, ObserverSettings

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


def _sx(values: Any) -> casadi.SX:
    return casadi.densify(sym.to_casadi(values))


def build_observer_functions(
    n_knots: int,
    register: int,
    settings: ObserverSettings,
    sample_period_s: float,
    anomaly: online.AnomalySettings | None = None,
) -> tuple[dict[str, casadi.Function], Layout]:
    """The casadi Functions of the online observer (see the module), and its sizes."""
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
    return fns, lay


def generate_observer_c(
    fns: dict[str, casadi.Function], folder: Path, stem: str
) -> dict[str, dict[str, int]]:
    """Write ``<stem>.c`` and ``<stem>.h`` into ``folder``; return each function's work sizes."""
    cg = casadi.CodeGenerator(f"{stem}.c", {"with_header": False, "verbose": False})
    for name in FUNCTIONS:
        cg.add(fns[name])
    write_generated(
        folder,
        stem,
        cg.dump(),
        "gatetwin.mpc.observer_codegen",
        [f"{PREFIX}{name}" for name in FUNCTIONS],
        "the observer",
    )
    return {name: work_sizes(f) for name, f in fns.items()}


__all__ = ["ESTIMATE", "FUNCTIONS", "LIMITS", "PREFIX", "build_observer_functions",
           "generate_observer_c"]  # fmt: skip
