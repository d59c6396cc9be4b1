"""The online observer's arithmetic as casadi Functions, and their C (``casadi.CodeGenerator``).

What :class:`~gatetwin.mpc.online.OnlineObserver` does per sample is split into functions
of plain vectors, each built by running its own code (:func:`~gatetwin.mpc.discrete.
fopdt_model` through :class:`~gatetwin.mpc.codegen.SymbolicController`,
:class:`~gatetwin.mpc.observer.DisturbanceObserver`, :func:`~gatetwin.mpc.online.
correct_sample`, :func:`~gatetwin.mpc.online.advance`) on casadi symbols:

* ``start(theta, q, e, y) -> (z, d, level)`` — the observer at rest at opening ``e``, level
  ``y``, and the level it then estimates;
* ``riccati(theta, q, P) -> P`` — one correct-and-predict of the covariance (iterated to its
  fixed point: the steady prior covariance of the start);
* ``correct(theta, q, z, d, P, y, run, band, n_run) -> (z, d, P, estimate)`` — the
  correction with the level measured now; ``estimate`` is ``(filtered_level_mm,
  disturbance_mm, innovation_mm, innovation_normalised, anomaly_samples, anomaly)``;
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
            "anomaly_samples", "anomaly")  # fmt: skip


def _sx(values: Any) -> casadi.SX:
    return casadi.densify(sym.to_casadi(values))


def build_observer_functions(
    n_knots: int, register: int, settings: ObserverSettings, sample_period_s: float
) -> tuple[dict[str, casadi.Function], Layout]:
    """The casadi Functions of the online observer (see the module), and its sizes."""
    mpc_settings = MpcSettings(sample_period_s=sample_period_s, observer=settings)
    ctl = SymbolicController(n_knots, register, mpc_settings)
    lay, theta = ctl.layout, ctl.theta
    names = ("q", "q_prev", "e", "y", "d", "run", "band", "n_run")
    scalars = {n: casadi.SX.sym(n) for n in names}
    q, q_prev, e, y, d, run, band, n_run = (sym.Sym(v) for v in scalars.values())
    zs, z = sym.symbols("z", lay.n_states)
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
    add("start", [theta, s["q"], s["e"], s["y"]], ["theta", "q", "e", "y"],
        [obs.state, obs.disturbance_mm, model.level_mm(obs.state)],
        ["z", "d", "level"])  # fmt: skip

    obs = ctl.observer(model, z, d, p)
    obs.correct(model, 0.0)
    obs.predict(model, 0.0)
    add("riccati", [theta, s["q"], ps], ["theta", "q", "P"], [obs.covariance], ["P_next"])

    obs = ctl.observer(model, z, d, p)
    estimate = online.correct_sample(obs, model, y, run, band, n_run)
    add("correct", [theta, s["q"], zs, s["d"], ps, s["y"], s["run"], s["band"], s["n_run"]],
        ["theta", "q", "z", "d", "P", "y", "run", "band", "n_run"],
        [obs.state, obs.disturbance_mm, obs.covariance, list(estimate)],
        [*NEXT, "estimate"])  # fmt: skip

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
    write_generated(folder, stem, cg.dump(), "gatetwin.mpc.observer_codegen",
                    [f"{PREFIX}{name}" for name in FUNCTIONS], "the observer")
    return {name: work_sizes(f) for name, f in fns.items()}


__all__ = ["ESTIMATE", "FUNCTIONS", "PREFIX", "build_observer_functions", "generate_observer_c"]
