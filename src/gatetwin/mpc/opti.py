"""The same MPC problem posed with ``casadi.Opti`` and solved by IPOPT: the reference.

Unlike :mod:`gatetwin.mpc.qp` this formulation keeps the states as decision variables and
the model as equality constraints (``z_{j+1} = A z_j + B (e_j − e_ref) + B_d d + f``), so it
shares nothing with the condensing but the model and the settings: agreement of the two
checks the condensed QP. The model matrices are Opti parameters, so one compiled
function serves every discharge. It is far slower than the QP and is not meant for the
loop (``benchmarks/bench_mpc.py`` measures by how much).
"""

from __future__ import annotations

import time
from typing import Any

import casadi
import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc.qp import MpcProblem, MpcSolution
from gatetwin.mpc.settings import MpcSettings

#: IPOPT's tolerances: tight, so that the reference decides agreement to well below 1e-3 mm.
IPOPT_OPTIONS: dict[str, Any] = {
    "print_time": False,
    "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10, "acceptable_tol": 1e-9, "max_iter": 500},
}


class OptiBackend:
    """Solves :class:`MpcProblem` s with an Opti + IPOPT formulation built once per size."""

    name = "ipopt"

    def __init__(self, settings: MpcSettings) -> None:
        self.settings = settings
        self._functions: dict[tuple[MpcSettings, int], casadi.Function] = {}

    def _function(self, settings: MpcSettings, n_states: int) -> casadi.Function:
        """The formulation for these weights and this state size (built once each)."""
        key = (settings, n_states)
        if key not in self._functions:
            self._functions[key] = _build(settings, n_states)
        return self._functions[key]

    def solve(self, problem: MpcProblem) -> MpcSolution:
        m = problem.model
        fn = self._function(problem.settings, m.n_states)
        args = [
            m.a,
            m.b,
            m.c_level,
            m.b_dist,
            m.affine,
            m.level_ref_mm,
            m.opening_ref_mm,
            problem.state,
            problem.disturbance_mm,
            problem.setpoint_mm,
            problem.previous_opening_mm,
            problem.move_bound_mm,
            *problem.range_mm,
        ]
        start = time.perf_counter()
        try:
            openings, slack, levels = fn(*args)
        except RuntimeError as exc:  # casadi raises when IPOPT fails outright
            raise ControlError(f"ipopt: {exc}") from None
        solve_s = time.perf_counter() - start
        stats = fn.stats()
        return MpcSolution(
            openings_mm=np.asarray(openings, dtype=float).ravel(),
            slack_mm=float(slack),
            predicted_level_mm=np.asarray(levels, dtype=float).ravel(),
            solve_s=solve_s,
            success=bool(stats.get("success", False)),
            status=str(stats.get("return_status", "")),
        )


def _build(s: MpcSettings, nz: int) -> casadi.Function:
    n = s.horizon
    opti = casadi.Opti()
    e = opti.variable(n)
    z = opti.variable(nz, n + 1)
    a_p, b_p = opti.parameter(nz, nz), opti.parameter(nz)
    c_p, bd_p, f_p = opti.parameter(nz), opti.parameter(nz), opti.parameter(nz)
    level_ref, e_ref = opti.parameter(), opti.parameter()
    max_move, e_lo, e_hi = opti.parameter(), opti.parameter(), opti.parameter()
    z0, dist, setpoint, e_prev = (
        opti.parameter(nz),
        opti.parameter(),
        opti.parameter(),
        opti.parameter(),
    )
    opti.subject_to(z[:, 0] == z0)
    for j in range(n):
        opti.subject_to(z[:, j + 1] == a_p @ z[:, j] + b_p * (e[j] - e_ref) + bd_p * dist + f_p)
    level = level_ref + (c_p.T @ z[:, 1:]).T
    moves = e - casadi.vertcat(e_prev, e[:-1])
    cost = s.level_weight * casadi.sumsqr(level - setpoint) + s.move_weight * casadi.sumsqr(moves)
    opti.subject_to(opti.bounded(e_lo, e, e_hi))
    opti.subject_to(opti.bounded(-max_move, moves, max_move))
    slack = casadi.MX(0.0)
    if s.level_band_mm is not None:
        slack = opti.variable()
        opti.subject_to(slack >= 0)
        opti.subject_to(level + slack >= s.level_band_mm[0])
        opti.subject_to(level - slack <= s.level_band_mm[1])
        cost += s.slack_weight_quadratic * slack**2 + s.slack_weight_linear * slack
    opti.minimize(cost)
    opti.solver("ipopt", IPOPT_OPTIONS)
    params = [a_p, b_p, c_p, bd_p, f_p, level_ref, e_ref, z0, dist, setpoint, e_prev,
              max_move, e_lo, e_hi]  # fmt: skip
    return opti.to_function("mpc_ipopt", params, [e, slack, level])


__all__ = ["IPOPT_OPTIONS", "OptiBackend"]
