"""The single-point MPC's arithmetic as casadi Functions, and their C (``casadi.CodeGenerator``).

What :class:`~gatetwin.mpc.controller.MpcController` does per sample with the schedule's
model (``linearisation="schedule"``) is split into functions of plain vectors, each built
by running the controller's own code (:func:`~gatetwin.mpc.discrete.fopdt_model`,
:class:`~gatetwin.mpc.observer.DisturbanceObserver`,
:class:`~gatetwin.mpc.qp.CondensedQp`) on casadi symbols (:mod:`gatetwin.mpc.symbolic`):

* ``start(theta, q, e, y) -> (z, d)`` — the observer at rest at opening ``e``, level ``y``;
* ``riccati(theta, q, P) -> P`` — one correct-and-predict of the observer's covariance
  (iterated to its fixed point, the steady prior covariance of the start);
* ``correct(theta, q, z, d, P, y) -> (z, d, P)`` — the observer's correction;
* ``matrices(theta, q) -> (H, A)`` — the condensed QP's matrices at discharge ``q``;
* ``vectors(theta, q, z, d, e, r) -> (g, lba, uba, lbx, ubx)`` — its vectors;
* ``plan(theta, q, z, d, e, x) -> (opening, level)`` — the first opening of the plan
  (clipped to the range) and the level it predicts one sample ahead;
* ``predict(theta, q_prev, q, z, d, P, e) -> (z, d, P)`` — the observer's prediction.

The QP itself is solved by the FMU's own dense active-set solver (``qp_dense.c``), from the
matrices and vectors these functions form.

``theta`` holds the schedule (knots, then ``K``, ``T``, ``L``, ``level_ref_mm`` at each
knot) and ``opening_ref_mm``; the parameters are interpolated in ``q`` inside the
functions, so the C controller re-renders the model at each measured discharge. Effect
blocks, ARX and the envelope re-linearisation are not covered.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi
import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.discrete import fopdt_model
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.qp import CondensedQp, MpcProblem, qp_matrices, qp_vectors
from gatetwin.mpc.settings import MpcSettings
from gatetwin.mpc.statespace import DiscreteModel

#: Schedule columns of the FOPDT, in the order ``theta`` holds them after the knots.
COLUMNS = ("gain_mm_per_mm", "time_constant_s", "dead_time_s", "level_ref_mm")
#: Prefix of every generated C function.
PREFIX = "gt_mpc_"
#: Output names of the observer's functions.
NEXT = ["z_next", "d_next", "P_next"]
#: Names of the generated functions (without the prefix), in generation order.
FUNCTIONS = ("start", "riccati", "correct", "matrices", "vectors", "plan", "predict")


@dataclass(frozen=True)
class Layout:
    """Sizes of the controller: knots, register, states, QP variables and constraints."""

    n_knots: int
    register: int
    n_states: int
    n_var: int
    n_con: int

    @property
    def n_theta(self) -> int:
        return self.n_knots * (1 + len(COLUMNS)) + 1


def theta_names(n_knots: int) -> list[str]:
    """FMU variable names of ``theta``'s entries, in order."""
    names = [f"schedule.flow_m3h[{k + 1}]" for k in range(n_knots)]
    for col in COLUMNS:
        names += [f"schedule.{col}[{k + 1}]" for k in range(n_knots)]
    return [*names, "opening_ref_mm"]


def interp_clamped_symbolic(knots: np.ndarray, values: np.ndarray, x: Any) -> Any:
    """:func:`gatetwin.plant.model.interp_clamped` on symbols: the same clamps and segment
    formula, with casadi ``if_else`` for the comparisons."""
    n = len(knots)
    if n == 1:
        return values[0]
    out = values[-1]
    for i in reversed(range(n - 1)):
        w = (x - knots[i]) / (knots[i + 1] - knots[i])
        out = sym.where(x <= knots[i + 1], values[i] + w * (values[i + 1] - values[i]), out)
    out = sym.where(x >= knots[-1], values[-1], out)
    return sym.where(x <= knots[0], values[0], out)


class SymbolicController:
    """The controller's per-sample arithmetic on casadi symbols, one model per discharge."""

    def __init__(self, n_knots: int, register: int, settings: MpcSettings) -> None:
        self.settings = settings
        nz = 1 + register
        n = settings.horizon
        band = settings.level_band_mm is not None
        self.layout = Layout(n_knots, register, nz, n + band, n * (3 if band else 1))
        self.theta, self._theta = sym.symbols("theta", self.layout.n_theta)

    def model(self, q: Any) -> DiscreteModel:
        """The FOPDT's discrete model at the (symbolic) discharge ``q``."""
        nk = self.layout.n_knots
        t = self._theta
        knots = t[:nk]
        at = {c: interp_clamped_symbolic(knots, t[nk * (i + 1): nk * (i + 2)], q)
              for i, c in enumerate(COLUMNS)}  # fmt: skip
        return fopdt_model(
            at["gain_mm_per_mm"], at["time_constant_s"], at["dead_time_s"],
            at["level_ref_mm"], t[-1], q, self.settings.sample_period_s, self.layout.register,
        )  # fmt: skip

    def observer(self, model: DiscreteModel, z: np.ndarray, d: Any, p: np.ndarray) -> Any:
        obs = DisturbanceObserver(self.settings.observer)
        obs.set_estimate(z, d, p, model.level_ref_mm)
        return obs

    def problem(self, q: Any, z: np.ndarray, d: Any, e: Any, r: Any) -> MpcProblem:
        return MpcProblem(self.model(q), z, d, r, e, self.settings)


def _vec(name: str, n: int) -> tuple[casadi.SX, np.ndarray]:
    return sym.symbols(name, n)


def _mat(name: str, n: int) -> tuple[casadi.SX, np.ndarray]:
    s = casadi.SX.sym(name, n, n)
    return s, sym.from_casadi(s)


def _sx(values: Any) -> casadi.SX:
    return casadi.densify(sym.to_casadi(values))


def _toeplitz(column: casadi.MX) -> casadi.MX:
    """The lower-triangular Toeplitz matrix of ``column`` (``CondensedQp.move_gain``'s form)
    as one indexing of it: its ``N`` values, not ``N²`` scalar expressions, in the C."""
    n = column.shape[0]
    j, i = np.indices((n, n))
    return casadi.vertcat(column, 0.0)[casadi.DM(np.where(j >= i, j - i, n))]


def build_functions(
    n_knots: int, register: int, settings: MpcSettings
) -> tuple[dict[str, casadi.Function], Layout]:
    """The casadi Functions of the controller (see the module), and its sizes."""
    if settings.level_band_mm is None:
        raise ControlError("mpc codegen: the controller is generated with a level band")
    ctl = SymbolicController(n_knots, register, settings)
    lay, theta = ctl.layout, ctl.theta
    scalars = {n: casadi.SX.sym(n) for n in ("q", "q_prev", "e", "y", "r", "d")}
    q, q_prev, e, y, r, d = (sym.Sym(v) for v in scalars.values())
    qs, q_prev_s, es, ys, rs, ds = scalars.values()
    zs, z = _vec("z", lay.n_states)
    ps, p = _mat("P", lay.n_states + 1)
    xs, x = _vec("x", lay.n_var)
    fns: dict[str, casadi.Function] = {}

    def add(name: str, ins: list[Any], in_names: list[str], outs: list[Any],
            out_names: list[str]) -> None:  # fmt: skip
        fns[name] = casadi.Function(PREFIX + name, ins, [_sx(o) for o in outs],
                                    in_names, out_names)  # fmt: skip

    model = ctl.model(q)
    obs = ctl.observer(model, z, d, p)
    obs.start(model, e, y)
    add("start", [theta, qs, es, ys], ["theta", "q", "e", "y"],
        [obs.state, obs.disturbance_mm], ["z", "d"])  # fmt: skip

    obs = ctl.observer(model, z, d, p)
    obs.correct(model, 0.0)
    obs.predict(model, 0.0)
    add("riccati", [theta, qs, ps], ["theta", "q", "P"], [obs.covariance], ["P_next"])

    obs = ctl.observer(model, z, d, p)
    obs.correct(model, y)
    add("correct", [theta, qs, zs, ds, ps, ys], ["theta", "q", "z", "d", "P", "y"],
        [obs.state, obs.disturbance_mm, obs.covariance], NEXT)  # fmt: skip

    qp = CondensedQp(model, settings, matrices=False)
    theta_mx, q_mx = casadi.MX.sym("theta", lay.n_theta), casadi.MX.sym("q")
    move_gain = _toeplitz(casadi.Function("step_response", [theta, qs],
                                          [_sx(qp.step_response)])(theta_mx, q_mx))  # fmt: skip
    h, a = qp_matrices(move_gain, settings)
    fns["matrices"] = casadi.Function(PREFIX + "matrices", [theta_mx, q_mx],
                                      [casadi.densify(h), casadi.densify(a)],
                                      ["theta", "q"], ["H", "A"])  # fmt: skip

    # the vectors as CondensedQp.data forms them: the held levels (O(N) per state) scalar by
    # scalar, G S's product with them as one matrix product (N² scalar operations would
    # make the generated C, and its compile, grow with N²)
    problem = ctl.problem(q, z, d, e, r)
    hold = casadi.Function("hold", [theta, qs, zs, ds, es], [_sx(qp.hold_levels(problem))])
    mx = {n: casadi.MX.sym(n, *shape) for n, shape in
          (("z", (lay.n_states, 1)), ("d", (1, 1)), ("e", (1, 1)), ("r", (1, 1)))}  # fmt: skip
    vectors = qp_vectors(
        move_gain, hold(theta_mx, q_mx, mx["z"], mx["d"], mx["e"]), mx["r"], mx["e"],
        problem.move_bound_mm, problem.range_mm, settings,
    )  # fmt: skip
    fns["vectors"] = casadi.Function(
        PREFIX + "vectors", [theta_mx, q_mx, *mx.values()],
        [casadi.densify(casadi.MX(v)) for v in vectors], ["theta", "q", *mx],
        ["g", "lba", "uba", "lbx", "ubx"],
    )  # fmt: skip

    openings = qp.openings(problem, x)
    lo, hi = settings.opening_range_mm
    level = qp.predicted_levels(problem, openings, samples=1)[0]
    add("plan", [theta, qs, zs, ds, es, xs], ["theta", "q", "z", "d", "e", "x"],
        [sym.clip(openings[0], lo, hi), level], ["opening", "level"])  # fmt: skip

    obs = ctl.observer(ctl.model(q_prev), z, d, p)
    obs.predict(model, e)
    add("predict", [theta, q_prev_s, qs, zs, ds, ps, es],
        ["theta", "q_prev", "q", "z", "d", "P", "e"],
        [obs.state, obs.disturbance_mm, obs.covariance], NEXT)  # fmt: skip
    return fns, lay


def generate_c(fns: dict[str, casadi.Function], folder: Path, stem: str) -> dict[str, Any]:
    """Write ``<stem>.c`` and ``<stem>.h`` into ``folder``; return each function's work sizes."""
    cg = casadi.CodeGenerator(f"{stem}.c", {"with_header": True, "verbose": False})
    for name in FUNCTIONS:
        cg.add(fns[name])
    write_generated(
        folder,
        stem,
        cg.dump(),
        "gatetwin.mpc.codegen",
        [f"{PREFIX}{name}" for name in FUNCTIONS],
        "the MPC controller",
    )
    return {name: work_sizes(f) for name, f in fns.items()}


def work_sizes(fn: casadi.Function) -> dict[str, int]:
    """``arg``, ``res``, ``iw`` and ``w`` sizes a call of ``fn`` needs."""
    return {"arg": int(fn.sz_arg()), "res": int(fn.sz_res()), "iw": int(fn.sz_iw()),
            "w": int(fn.sz_w())}  # fmt: skip


def write_generated(folder: Path, stem: str, code: str, module: str, functions: list[str],
                    what: str) -> None:  # fmt: skip
    """Write casadi's ``code`` as ``<stem>.c`` (with a prologue that keeps the FMU's strict
    build flags for everything else) and ``<stem>.h`` declaring ``functions`` (their full C
    names), both saying they come from ``module`` and hold ``what``'s functions."""
    # casadi's code leaves parameters unused and its exported symbols visible
    prologue = (
        f"/* Generated by casadi.CodeGenerator from {module}; do not edit. */\n"
        "#define CASADI_SYMBOL_EXPORT\n"
        "#if defined(__GNUC__)\n"
        '#pragma GCC diagnostic ignored "-Wunused-parameter"\n'
        '#pragma GCC diagnostic ignored "-Wunused-variable"\n'
        '#pragma GCC diagnostic ignored "-Wunused-function"\n'
        '#pragma GCC diagnostic ignored "-Wsign-compare"\n'
        "#endif\n"
    )
    guard = f"GATETWIN_{stem.upper()}_H"
    lines = [
        f"/* Generated by {module}: the casadi functions of {what}. */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "",
        "#ifndef casadi_real",
        "#define casadi_real double",
        "#endif",
        "#ifndef casadi_int",
        "#define casadi_int long long int",
        "#endif",
        "",
    ]
    for name in functions:
        lines.append(f"int {name}(const casadi_real** arg, casadi_real** res, "
                     "casadi_int* iw, casadi_real* w, int mem);")  # fmt: skip
    lines += ["", "#endif", ""]
    (folder / f"{stem}.c").write_text(prologue + code, encoding="utf-8")
    (folder / f"{stem}.h").write_text("\n".join(lines), encoding="utf-8")


__all__ = [
    "COLUMNS",
    "FUNCTIONS",
    "Layout",
    "SymbolicController",
    "build_functions",
    "generate_c",
    "interp_clamped_symbolic",
    "theta_names",
    "work_sizes",
    "write_generated",
]
