"""The MPC controller FMU's QP solver (``fmu_templates/qp_dense.c``) on its own, compiled with
the FMUs' flags and called through ctypes: against qpOASES on random strictly convex QPs and
on the demo MPC's QPs, and its failures (infeasible, iteration limit, a Hessian that is not
positive definite)."""

from __future__ import annotations

import ctypes
import shutil

import casadi
import numpy as np
import pytest

pytestmark = pytest.mark.skipif(
    shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler"
)

#: Agreement with qpOASES, relative to the solution's size. Both return the unique minimiser
#: of a strictly convex QP, each to its round-off: a few hundred eps amplified by the
#: Hessian's condition number (here below 1e4 by construction), so 1e-9 leaves margin.
RTOL = 1e-9
SOLVED, MAX_ITER, INFEASIBLE = 0, 1, 2

_P = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)


@pytest.fixture(scope="module")
def solver(tmp_path_factory):
    from gatetwin.fmu.c_build import compile_shared, templates_dir

    folder = tmp_path_factory.mktemp("qp_dense")
    for name in ("qp_dense.c", "qp_dense.h"):
        shutil.copyfile(templates_dir() / name, folder / name)
    # the FMUs' flags, with the symbols visible to ctypes
    compile_shared(folder, ("qp_dense.c",), folder / "qp_dense.so", ("-fvisibility=default",))
    lib = ctypes.CDLL(str(folder / "qp_dense.so"))
    lib.qp_dense_factor.restype = ctypes.c_int
    lib.qp_dense_solve.restype = ctypes.c_int
    return lib


def _ptr(a):
    return a.ctypes.data_as(_I if a.dtype == np.int32 else _P)


def _solve(lib, h, g, a, lba, uba, lbx, ubx, max_iter=1000, first=()):
    """(status, x, iterations, active) from the C solver, the constraints ``first`` tried
    first; raises when H is refused."""
    return _solve_with_set(lib, h, g, a, lba, uba, lbx, ubx, max_iter, first)[:4]


def _solve_with_set(lib, h, g, a, lba, uba, lbx, ubx, max_iter=1000, first=()):
    """(status, x, iterations, active, the active constraints) from the C solver."""
    n, m = len(g), a.shape[0]
    factor = np.zeros((n, n), order="F")
    work = np.zeros(2 * n * n + 5 * n + 2 + 2 * m)
    iwork = np.zeros(2 * n + m + 1, dtype=np.int32)
    if lib.qp_dense_factor(n, _ptr(np.asfortranarray(h, dtype=float)), _ptr(factor),
                           _ptr(work)) != 0:  # fmt: skip
        raise ValueError("H is not positive definite")
    x = np.zeros(n)
    it, active = ctypes.c_int(), ctypes.c_int()
    vectors = [np.ascontiguousarray(v, dtype=float) for v in (g, lba, uba, lbx, ubx)]
    a_f = np.asfortranarray(a, dtype=float)
    expected = np.asarray(first, dtype=np.int32)
    status = lib.qp_dense_solve(n, m, _ptr(factor), _ptr(vectors[0]), _ptr(a_f),
                                *(_ptr(v) for v in vectors[1:]), _ptr(expected), len(expected),
                                max_iter, _ptr(x), ctypes.byref(it), ctypes.byref(active),
                                _ptr(work), _ptr(iwork))  # fmt: skip
    return status, x, it.value, active.value, iwork[: active.value].tolist()


def _qpoases(h, g, a, lba, uba, lbx, ubx):
    n, m = len(g), a.shape[0]
    s = casadi.conic("reference", "qpoases", {"h": casadi.Sparsity.dense(n, n),
                                              "a": casadi.Sparsity.dense(m, n)},
                     {"printLevel": "none"})  # fmt: skip
    return np.array(s(h=h, g=g, a=a, lba=lba, uba=uba, lbx=lbx, ubx=ubx)["x"]).ravel()


def _random_qp(rng, n, m):
    """A strictly convex QP whose constraints hold at a random point (so it is feasible),
    some bounds infinite, some rows equalities and one row repeated (dependent)."""
    root = rng.normal(size=(n, n))
    h = root @ root.T + 0.5 * np.eye(n)
    g = 5.0 * rng.normal(size=n)
    a = rng.normal(size=(m, n))
    if m >= 2:
        a[-1] = a[0]
    inside = rng.normal(size=n)
    lba, uba = a @ inside - rng.uniform(0, 1, m), a @ inside + rng.uniform(0, 1, m)
    if m >= 3:
        lba[1] = uba[1] = a[1] @ inside
    lba[rng.random(m) < 0.2] = -np.inf
    uba[rng.random(m) < 0.2] = np.inf
    lbx, ubx = inside - rng.uniform(0, 2, n), inside + rng.uniform(0, 2, n)
    lbx[rng.random(n) < 0.3] = -np.inf
    return h, g, a, lba, uba, lbx, ubx


def test_random_qps_give_qpoases_solution(solver):
    rng = np.random.default_rng(20261127)
    active_seen = 0
    for _ in range(200):
        qp = _random_qp(rng, int(rng.integers(1, 30)), int(rng.integers(0, 40)))
        status, x, _, active = _solve(solver, *qp)
        assert status == SOLVED
        want = _qpoases(*qp)
        assert np.max(np.abs(x - want)) <= RTOL * max(1.0, np.max(np.abs(want)))
        active_seen += active
    assert active_seen > 200  # the draws do exercise constraints


def _demo_step_qp():
    """The demo MPC's QP (N = 30) from rest at 190 mm with a set-point of 350 mm, the step at
    which the rate limit holds the plan for most of the horizon: (h, g, a, lba, uba, lbx,
    ubx)."""
    from gatetwin.mpc import MpcSettings, demo_plant
    from gatetwin.mpc.discrete import discretise
    from gatetwin.mpc.observer import DisturbanceObserver
    from gatetwin.mpc.qp import CondensedQp, MpcProblem

    s = MpcSettings(horizon=30)
    model = discretise(demo_plant(), 40.0, s.sample_period_s)
    obs = DisturbanceObserver(s.observer)
    obs.reset(model, 25.0, 190.0)
    qp = CondensedQp(model, s)
    data = qp.data(MpcProblem(model, obs.state, obs.disturbance_mm, 350.0, 25.0, s))
    return data.h, data.g, data.a, data.lba, data.uba, data.lbx, data.ubx


def test_the_demo_mpcs_qps_give_qpoases_solution_after_a_large_set_point_step(solver):
    """The demo MPC (N = 30) from rest at 190 mm with a set-point of 350 mm, the step at which
    the rate limit holds the plan for most of the horizon."""
    args = _demo_step_qp()
    status, x, iterations, active = _solve(solver, *args)
    want = _qpoases(*args)
    assert status == SOLVED and active >= 10 and iterations >= active
    assert np.max(np.abs(x - want)) <= RTOL * np.max(np.abs(want))


def test_constraints_named_first_change_the_path_not_the_solution(solver):
    """Any list of constraints to try first (the real ones, indices that name no constraint,
    repeats, infinite bounds) leaves the solution qpOASES's."""
    rng = np.random.default_rng(20261128)
    for _ in range(200):
        qp = _random_qp(rng, int(rng.integers(1, 30)), int(rng.integers(0, 40)))
        n_con = 2 * (len(qp[1]) + len(qp[2]))
        first = rng.integers(-3, n_con + 3, size=int(rng.integers(0, 2 * len(qp[1]))))
        status, x, *_ = _solve(solver, *qp, first=first)
        want = _qpoases(*qp)
        assert status == SOLVED
        assert np.max(np.abs(x - want)) <= RTOL * max(1.0, np.max(np.abs(want)))


def test_the_constraints_named_first_are_added_first_in_their_order(solver):
    """H = I and every upper bound binding (x = -g beyond it, so adding one bound moves no
    other variable): named in a shuffled order, with indices that name no constraint among
    them, the bounds are added in that order, one iteration each; the search alone adds
    them by violation."""
    rng = np.random.default_rng(5)
    n = 20
    g = -10.0 * np.ones(n) + rng.normal(size=n)
    qp = (np.eye(n), g, np.zeros((0, n)), np.zeros(0), np.zeros(0), -np.ones(n), np.ones(n))
    upper = [2 * i + 1 for i in rng.permutation(n)]
    status, x, iterations, active, order = _solve_with_set(solver, *qp, first=[-1, *upper, 99])
    assert (status, iterations, active) == (SOLVED, n, n) and np.array_equal(x, np.ones(n))
    assert order == upper
    _, _, _, _, searched = _solve_with_set(solver, *qp)
    assert searched == [2 * int(i) + 1 for i in np.argsort(g)] != upper


def test_the_active_set_named_first_is_added_once_each(solver):
    """The demo MPC's QP after a large set-point step: given its own active set, the solver
    adds each of those constraints once, none dropped, and lands on the same solution."""
    args = _demo_step_qp()
    status, x, iterations, active, found = _solve_with_set(solver, *args)
    assert status == SOLVED and iterations >= active >= 10
    status, x_warm, warm_iterations, warm_active, _ = _solve_with_set(solver, *args, first=found)
    assert status == SOLVED and warm_iterations == warm_active == active
    assert np.max(np.abs(x_warm - x)) <= RTOL * np.max(np.abs(x))


def test_an_infeasible_qp_is_reported(solver):
    # x >= 1 by a bound and x <= 0 by a row
    status, *_ = _solve(solver, np.eye(1), np.zeros(1), np.ones((1, 1)), np.array([-np.inf]),
                        np.zeros(1), np.ones(1), np.array([np.inf]))  # fmt: skip
    assert status == INFEASIBLE


def test_the_iteration_limit_holds(solver):
    rng = np.random.default_rng(3)
    n = 20
    h = np.eye(n)
    g = -10.0 * np.ones(n) + rng.normal(size=n)  # every upper bound binds
    status, _, iterations, _ = _solve(solver, h, g, np.zeros((0, n)), np.zeros(0), np.zeros(0),
                                      -np.ones(n), np.ones(n), max_iter=5)  # fmt: skip
    assert (status, iterations) == (MAX_ITER, 5)
    status, x, iterations, active = _solve(solver, h, g, np.zeros((0, n)), np.zeros(0),
                                           np.zeros(0), -np.ones(n), np.ones(n))  # fmt: skip
    assert status == SOLVED and iterations == active == n and np.array_equal(x, np.ones(n))


@pytest.mark.parametrize("h", [np.diag([1.0, -1.0]), np.diag([1.0, 0.0]), np.diag([1.0, np.nan])])
def test_a_hessian_that_is_not_positive_definite_is_refused(solver, h):
    with pytest.raises(ValueError):
        _solve(solver, h, np.zeros(2), np.zeros((0, 2)), np.zeros(0), np.zeros(0),
               -np.ones(2), np.ones(2))  # fmt: skip
