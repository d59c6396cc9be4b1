"""The MPC problem as a condensed, dense QP, solved by DAQP or a casadi conic plugin.

The predicted levels are affine in the openings, ``level = f + G e``, with ``G`` the
lower-triangular Toeplitz matrix of the model's Markov parameters ``C A^m B`` and ``f``
the free response from the estimated state and disturbance (condensing: the states are
eliminated and the QP stays small and dense). Decision variables are the moves
``Δe_0 … Δe_{N−1}`` (mm), so that the rate limit is a bound, and with a level band one
slack ``s`` (mm) shared by the horizon.

DAQP (the default) is reached through its own package: one workspace per model's matrices,
set up (``H`` factored) once, its working set kept from one sample to the next; casadi's DAQP
plugin would set it up afresh at every call. The other solvers go to :func:`casadi.conic`
(the matrix-level interface under ``casadi.qpsol``): ``qpsol`` would take the problem
symbolically and re-derive the dense Hessian ``G'G`` (``N³`` scalar operations) in casadi's
virtual machine at every call, while here numpy forms it once per discharge with BLAS.
qpOASES keeps its working set between calls (casadi hot-starts its ``SQProblem`` from the
second call on); OSQP is warm-started from the previous primal solution.

See :mod:`gatetwin.mpc.opti` for the same problem posed with ``casadi.Opti`` and IPOPT.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi
import numpy as np
from scipy.linalg import toeplitz

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.discrete import DiscreteModel
from gatetwin.mpc.settings import MpcSettings


@dataclass(frozen=True, eq=False)
class MpcProblem:
    """One MPC decision: the model at the measured discharge and what the observer knows.

    Attributes
    ----------
    model : DiscreteModel
        Plant rendering at the measured discharge (held over the horizon).
    state : ndarray
        Estimated state ``z(k|k)``.
    disturbance_mm : float
        Estimated input disturbance, mm of opening (held over the horizon).
    setpoint_mm : float
        Level set-point over the horizon (no preview of future changes), mm.
    previous_opening_mm : float
        Opening commanded at the previous sample (the rate limit's anchor), mm.
    settings : MpcSettings
        Horizon, constraints and weights.
    max_move_mm : float or None
        Largest move per sample in the model's input, mm; ``None``: the settings' (the
        controller narrows it for an actuator rate limit and maps it through an opening
        nonlinearity, :mod:`gatetwin.mpc.actuation`).
    opening_range_mm : tuple[float, float] or None
        Allowed model input, mm; ``None``: the settings'.
    """

    model: DiscreteModel
    state: np.ndarray
    disturbance_mm: float
    setpoint_mm: float
    previous_opening_mm: float
    settings: MpcSettings
    max_move_mm: float | None = None
    opening_range_mm: tuple[float, float] | None = None

    @property
    def move_bound_mm(self) -> float:
        return self.settings.max_move_mm if self.max_move_mm is None else self.max_move_mm

    @property
    def range_mm(self) -> tuple[float, float]:
        rng = self.opening_range_mm
        return self.settings.opening_range_mm if rng is None else rng


@dataclass(frozen=True, eq=False)
class MpcSolution:
    """A solved MPC problem.

    Attributes
    ----------
    openings_mm : ndarray
        Planned openings over the horizon, mm; the first is applied.
    slack_mm : float
        Band violation the plan accepts, mm (0 without a band).
    predicted_level_mm : ndarray
        Predicted levels at samples ``k+1 … k+N``, mm.
    solve_s : float
        Wall time of the solver call alone, s.
    success : bool
        The solver reported success.
    status : str
        The solver's return status.
    """

    openings_mm: np.ndarray
    slack_mm: float
    predicted_level_mm: np.ndarray
    solve_s: float
    success: bool
    status: str

    @property
    def first_move_mm(self) -> float:
        return float(self.openings_mm[0])


def markov_parameters(model: DiscreteModel, horizon: int) -> np.ndarray:
    """``C_level A^m B`` for ``m = 0 … N−1``: level at ``k+1+m`` per mm of ``e_k``."""
    markov = sym.zeros(horizon, model.a, model.b)
    v = model.b.copy()
    for m in range(horizon):
        markov[m] = model.c_level @ v
        v = model.a @ v
    return markov


def prediction_matrix(model: DiscreteModel, horizon: int) -> np.ndarray:
    """``G`` with ``G[j, i] = C_level A^(j−i) B``: level at ``k+1+j`` per mm of ``e_i``."""
    return toeplitz(markov_parameters(model, horizon), np.zeros(horizon))


def free_response(
    model: DiscreteModel, horizon: int, state: np.ndarray, disturbance_mm: float
) -> np.ndarray:
    """Levels at ``k+1 … k+N`` if every opening stayed at ``opening_ref_mm``, mm.

    The water level (``C_level``), not the gauge reading: the sensor blocks are the
    observer's business.
    """
    drive = model.b_dist * disturbance_mm + model.affine
    z = sym.asarray(state)
    out = sym.zeros(horizon, model.a, z, drive)
    for j in range(horizon):
        z = model.a @ z + drive
        out[j] = model.c_level @ z
    return out + model.level_ref_mm


def free_response_maps(model: DiscreteModel, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``C_level A^(j+1)`` and ``C_level (I + A + … + A^j)``, ``j = 0 … N−1``:
    :func:`free_response` is ``of_state @ z + of_drive @ drive + level_ref_mm``."""
    n_x = model.a.shape[0]
    of_state, of_drive = np.empty((horizon, n_x)), np.empty((horizon, n_x))
    power, total = np.eye(n_x), np.zeros((n_x, n_x))
    for j in range(horizon):
        total = total + power
        power = power @ model.a
        of_state[j] = model.c_level @ power
        of_drive[j] = model.c_level @ total
    return of_state, of_drive


@dataclass(frozen=True, eq=False)
class QpData:
    """``min ½ x'Hx + g'x  s.t.  lba <= A x <= uba,  lbx <= x <= ubx`` (numpy arrays)."""

    h: np.ndarray
    g: np.ndarray
    a: np.ndarray
    lba: np.ndarray
    uba: np.ndarray
    lbx: np.ndarray
    ubx: np.ndarray

    def as_casadi_args(self) -> dict[str, Any]:
        return {
            "h": self.h,
            "g": self.g,
            "a": self.a,
            "lba": self.lba,
            "uba": self.uba,
            "lbx": self.lbx,
            "ubx": self.ubx,
        }


class CondensedQp:
    """The matrices of one model's QP (they change only when the discharge does).

    Variables are the moves ``Δe_j = e_j − e_{j−1}`` (and the slack): the rate limit is
    then a simple bound, the kind of constraint an active-set solver adds and drops
    cheapest, and it is the constraint that is active through every large transient.
    Openings are ``e = e_prev + S Δe`` with ``S`` the lower-triangular matrix of ones.
    """

    def __init__(
        self, model: DiscreteModel, settings: MpcSettings, *, matrices: bool = True
    ) -> None:
        n = settings.horizon
        self.model = model
        self.settings = settings
        self.has_band = settings.level_band_mm is not None
        self._dm: tuple[casadi.DM, casadi.DM] | None = None
        #: DAQP's workspace for these matrices (:class:`QpBackend`; set up on first use)
        self.workspace: Any = None
        markov = markov_parameters(model, n)
        self.gain = toeplitz(markov, np.zeros(n))
        #: level at k+1+j per mm of opening held from k on: the rows of G summed
        self.step_response = np.cumsum(markov)
        self.cumulative = np.tril(np.ones((n, n)))
        # G @ S: entry (j, i) sums G's row j from column i on, i.e. the step response at j − i
        self.move_gain = toeplitz(self.step_response, np.zeros(n))
        # with matrices=False (the code generator's symbolic model) H and A are formed from
        # move_gain as casadi matrices instead: qp_matrices on an MX
        self.h, self.a = qp_matrices(self.move_gain, settings) if matrices else (None, None)
        #: the free response's maps, C A^(j+1) of the state and C (I + A + … + A^j) of the
        #: drive (rows j = 0 … N−1): a product per sample instead of N matrix products
        self.free_maps = free_response_maps(model, n) if matrices else None

    def serves(self, model: DiscreteModel, settings: MpcSettings) -> bool:
        """Whether these matrices are ``model``'s under ``settings``: they depend on ``A``,
        ``B``, ``C_level`` and the weights only (a model that differs in its known drive or
        level shares them)."""
        mine = self.model
        if settings != self.settings:
            return False
        return model is mine or (
            model.a.shape == mine.a.shape
            and np.array_equal(model.a, mine.a)
            and np.array_equal(model.b, mine.b)
            and np.array_equal(model.c_level, mine.c_level)
        )

    def free_levels(self, problem: MpcProblem, samples: int) -> np.ndarray:
        """:func:`free_response` of the problem over its first ``samples``, mm, from the
        maps (the problem's model shares ``A`` and ``C_level`` with this one's)."""
        if self.free_maps is None:
            return free_response(problem.model, samples, problem.state, problem.disturbance_mm)
        model = problem.model
        of_state, of_drive = self.free_maps
        drive = model.b_dist * problem.disturbance_mm + model.affine
        return (of_state[:samples] @ np.asarray(problem.state, dtype=float)
                + of_drive[:samples] @ drive + model.level_ref_mm)  # fmt: skip

    def hold_levels(self, problem: MpcProblem) -> np.ndarray:
        """Predicted levels at ``k+1 … k+N`` if the opening stayed at the previous one, mm."""
        model = problem.model
        free = self.free_levels(problem, self.settings.horizon)
        # the model's input is e − e_ref
        return free + self.step_response * (problem.previous_opening_mm - model.opening_ref_mm)

    def data(self, problem: MpcProblem) -> QpData:
        """QP data for the problem's state, disturbance, set-point and previous opening."""
        vectors = qp_vectors(
            self.move_gain, self.hold_levels(problem), problem.setpoint_mm,
            problem.previous_opening_mm, problem.move_bound_mm, problem.range_mm, self.settings,
        )  # fmt: skip
        return QpData(self.h, vectors[0], self.a, *vectors[1:])

    def openings(self, problem: MpcProblem, x: np.ndarray) -> np.ndarray:
        """Openings (mm) from the QP's solution vector."""
        return problem.previous_opening_mm + np.cumsum(x[: self.settings.horizon])

    def casadi_matrices(self) -> tuple[casadi.DM, casadi.DM]:
        """``H`` and ``A`` as casadi matrices (numpy → DM costs ~4 ms at N = 100)."""
        if self._dm is None:
            self._dm = (casadi.DM(self.h), casadi.DM(self.a))
        return self._dm

    def predicted_levels(
        self, problem: MpcProblem, openings_mm: np.ndarray, samples: int | None = None
    ) -> np.ndarray:
        """Levels at ``k+1 …`` for the planned openings, mm: the horizon's, or its first
        ``samples`` (the generated controller needs one)."""
        model = problem.model
        n = self.settings.horizon if samples is None else samples
        return self.free_levels(problem, n) + self.gain[:n] @ (openings_mm - model.opening_ref_mm)


def _stack(parts: list[Any]) -> Any:
    """Vectors end to end: numpy, or a casadi column when any part is casadi's."""
    if any(isinstance(p, (casadi.SX, casadi.MX)) for p in parts):
        return casadi.vertcat(*parts)
    return np.concatenate([np.atleast_1d(p) for p in parts])


def _full(n: int, value: Any) -> Any:
    if isinstance(value, (casadi.SX, casadi.MX)):
        return casadi.repmat(value, n, 1)
    return np.full(n, value)


def qp_vectors(
    move_gain: Any, hold: Any, setpoint_mm: Any, previous_opening_mm: Any, move_bound_mm: float,
    range_mm: tuple[float, float], settings: MpcSettings,
) -> tuple[Any, Any, Any, Any, Any]:  # fmt: skip
    """``g``, ``lba``, ``uba``, ``lbx``, ``ubx`` of the QP from ``G S`` (``move_gain``) and
    the levels if the opening were held (``hold``): numpy arrays, or casadi columns for
    casadi arguments (the generated controller's, which forms ``G S``'s product as a matrix
    product rather than ``N²`` scalar operations)."""
    s, n = settings, settings.horizon
    g = 2.0 * s.level_weight * (move_gain.T @ (hold - setpoint_mm))
    step = np.full(n, move_bound_mm)
    lo_e, hi_e = range_mm
    range_lo, range_hi = _full(n, lo_e - previous_opening_mm), _full(n, hi_e - previous_opening_mm)
    if s.level_band_mm is None:
        return g, range_lo, range_hi, -step, step
    band_lo, band_hi = s.level_band_mm
    inf = np.full(n, np.inf)
    return (
        _stack([g, s.slack_weight_linear]),
        _stack([range_lo, band_lo - hold, -inf]),
        _stack([range_hi, inf, band_hi - hold]),
        np.append(-step, 0.0),
        np.append(step, np.inf),
    )


def qp_matrices(move_gain: Any, settings: MpcSettings) -> tuple[Any, Any]:
    """``H`` and ``A`` of the QP from ``G S`` (``move_gain``): numpy arrays, or casadi
    matrices for a casadi ``move_gain`` (the generated controller's)."""
    n = settings.horizon
    h_move = 2.0 * (
        settings.level_weight * move_gain.T @ move_gain + settings.move_weight * np.eye(n)
    )
    cumulative = np.tril(np.ones((n, n)))
    if settings.level_band_mm is None:
        return h_move, cumulative
    corner = np.array([[2.0 * settings.slack_weight_quadratic]])
    one = np.ones((n, 1))
    if isinstance(move_gain, (casadi.SX, casadi.MX)):
        zero = np.zeros((n, 1))
        h = casadi.blockcat([[h_move, zero], [zero.T, corner]])
        return h, casadi.blockcat([[cumulative, zero], [move_gain, one], [move_gain, -one]])
    h = np.zeros((n + 1, n + 1))
    h[:n, :n] = h_move
    h[n, n] = corner[0, 0]
    a = np.block([[cumulative, np.zeros((n, 1))], [move_gain, one], [move_gain, -one]])
    return h, a


def _solver_options(name: str) -> dict[str, Any]:
    if name == "qpoases":
        return {
            "printLevel": "none",
            "hessian_type": "posdef",
            "error_on_fail": False,
            "sparse": False,
        }
    if name == "osqp":
        return {
            "error_on_fail": False,
            "warm_start_primal": True,
            "osqp": {
                "verbose": False,
                "eps_abs": 1e-7,
                "eps_rel": 1e-7,
                "max_iter": 20000,
                "polish": True,
            },
        }
    if name == "qrqp":
        return qrqp_options(QRQP_MAX_ITER)
    return {"error_on_fail": False}


#: Iterations qrqp may take on one QP (each adds or drops one constraint; a warm start
#: from the last solution's multipliers needs a few, a cold one about as many as there are
#: active constraints).
QRQP_MAX_ITER = 200


def qrqp_options(max_iter: int) -> dict[str, Any]:
    """Options of casadi's ``qrqp`` (the QP solver casadi generates C for), silent."""
    return {
        "max_iter": int(max_iter),
        "print_iter": False,
        "print_header": False,
        "print_info": False,
        "error_on_fail": False,
    }


def set_casadi_blas_threads(threads: int) -> bool:
    """Set the thread count of the OpenBLAS bundled with casadi (qpOASES' dense algebra).

    Process-wide. Returns False when this casadi build has no bundled OpenBLAS.
    """
    folder = Path(casadi.__file__).parent
    for path in sorted(folder.glob("libcasadi-tp-openblas*")):
        try:
            lib = ctypes.CDLL(str(path))
            lib.openblas_set_num_threads(int(threads))
        except (OSError, AttributeError):
            continue
        return True
    return False


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence a library banner, then restore: what C code writes to file descriptor 1 and
    what casadi passes on to ``sys.stdout`` (its messages go there when stdout is not the
    terminal's, e.g. under doctest)."""
    try:
        fd = sys.stdout.fileno()
        sys.stdout.flush()
    except (AttributeError, OSError, ValueError):  # stdout captured in memory: C writes to 1
        fd = 1
    saved = os.dup(fd)
    try:
        with open(os.devnull, "wb") as devnull, contextlib.redirect_stdout(io.StringIO()):
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                with contextlib.suppress(OSError, AttributeError):
                    ctypes.CDLL(None).fflush(None)  # C stdio buffers go to /dev/null too
                os.dup2(saved, fd)
    finally:
        os.close(saved)


#: Condensed QPs a backend keeps for models it may see again (oldest dropped first).
RECENT_QPS = 32


class QpBackend:
    """Solves :class:`MpcProblem` s with ``settings.qp_solver``: DAQP on a workspace per
    model's matrices, or one casadi conic solver kept between calls.

    The condensed matrices (and DAQP's workspace) are rebuilt only when the model's ``A``,
    ``B`` or ``C_level`` or the settings change.
    """

    name = "qp"

    def __init__(self, settings: MpcSettings) -> None:
        self.settings = settings
        self._solver: Any = None
        if settings.qp_solver != "daqp":
            if settings.blas_threads is not None:
                set_casadi_blas_threads(settings.blas_threads)
            n_var = settings.horizon + (settings.level_band_mm is not None)
            n_con = settings.horizon * (3 if settings.level_band_mm is not None else 1)
            dense_h = casadi.Sparsity.dense(n_var, n_var)
            dense_a = casadi.Sparsity.dense(n_con, n_var)
            with _quiet_stdout():  # qpOASES prints its licence banner when it is created
                self._solver = casadi.conic(
                    "mpc_qp",
                    settings.qp_solver,
                    {"h": dense_h, "a": dense_a},
                    _solver_options(settings.qp_solver),
                )
        self._qp: CondensedQp | None = None
        self._recent: dict[bytes, CondensedQp] = {}
        self._x0: np.ndarray | None = None

    def condensed(self, model: DiscreteModel, settings: MpcSettings | None = None) -> CondensedQp:
        settings = settings or self.settings
        if self._qp is not None and self._qp.serves(model, settings):
            return self._qp
        # a re-linearised model often comes back to matrices it had a few samples ago
        # (the gate dithering by its resolution): those are kept, a few dozen at most
        key = b"".join(v.tobytes() for v in (model.a, model.b, model.c_level))
        key += repr(settings).encode()  # the horizon, band and weights shape H and A too
        qp = self._recent.get(key)
        if qp is None:
            if len(self._recent) >= RECENT_QPS:
                self._recent.pop(next(iter(self._recent)))
            qp = self._recent[key] = CondensedQp(model, settings)
        self._qp = qp
        return qp

    def solve(self, problem: MpcProblem) -> MpcSolution:
        qp = self.condensed(problem.model, problem.settings)
        if self._solver is None:
            return self._solve_daqp(qp, problem)
        args = qp.data(problem).as_casadi_args()
        args["h"], args["a"] = qp.casadi_matrices()  # converted once per model, not per call
        if self._x0 is not None:
            args["x0"] = self._x0
        start = time.perf_counter()
        res = self._solver(**args)
        solve_s = time.perf_counter() - start
        stats = self._solver.stats()
        x = np.asarray(res["x"], dtype=float).ravel()
        if not np.all(np.isfinite(x)):
            raise ControlError(f"{self.settings.qp_solver}: returned a non-finite solution")
        return self._solution(qp, problem, x, solve_s, bool(stats.get("success", False)),
                              str(stats.get("return_status", "")))  # fmt: skip

    def _solve_daqp(self, qp: CondensedQp, problem: MpcProblem) -> MpcSolution:
        """DAQP on the workspace of ``qp``'s matrices (set up on its first problem)."""
        data = qp.data(problem)
        upper = np.concatenate([data.ubx, data.uba])
        lower = np.concatenate([data.lbx, data.lba])
        start = time.perf_counter()
        if qp.workspace is None:
            workspace = _daqp().Model()
            workspace.settings = {**workspace.settings, "primal_tol": DAQP_PRIMAL_TOL_MM}
            flag = workspace.setup(data.h, data.g, data.a, upper, lower,
                                   np.zeros(upper.size, dtype=ctypes.c_int))[0]  # fmt: skip
            if flag < 0:  # no workspace kept: the next sample sets one up again
                return self._failed(qp, problem, flag, time.perf_counter() - start)
            qp.workspace = workspace
        elif (flag := qp.workspace.update(f=data.g, bupper=upper, blower=lower)) < 0:
            return self._failed(qp, problem, flag, time.perf_counter() - start)
        x, _, flag, _ = qp.workspace.solve()
        solve_s = time.perf_counter() - start
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)):
            raise ControlError(f"daqp: returned a non-finite solution (exit flag {flag})")
        return self._solution(qp, problem, x, solve_s, flag in DAQP_SOLVED,
                              DAQP_STATUS.get(flag, f"exit flag {flag}"))  # fmt: skip

    def _failed(self, qp: CondensedQp, problem: MpcProblem, flag: int, solve_s: float
                ) -> MpcSolution:  # fmt: skip
        """No solution (DAQP refused the data): the moves held at 0, reported as failed."""
        x = np.zeros(self.settings.horizon + qp.has_band)
        return self._solution(qp, problem, x, solve_s, False,
                              DAQP_STATUS.get(flag, f"exit flag {flag}"))  # fmt: skip

    def _solution(self, qp: CondensedQp, problem: MpcProblem, x: np.ndarray, solve_s: float,
                  success: bool, status: str) -> MpcSolution:  # fmt: skip
        self._x0 = x
        openings = qp.openings(problem, x)
        return MpcSolution(
            openings_mm=openings,
            slack_mm=float(x[self.settings.horizon]) if qp.has_band else 0.0,
            predicted_level_mm=qp.predicted_levels(problem, openings),
            solve_s=solve_s,
            success=success,
            status=status,
        )


#: DAQP's bound on a constraint's violation, mm of opening or level (its default, 1e-6, is
#: looser than the 1e-9 mm the C controller FMU and the Python loop are held to).
DAQP_PRIMAL_TOL_MM = 1e-9
#: DAQP's exit flags that mean a solution (optimal; optimal with soft constraints relaxed).
DAQP_SOLVED = (1, 2)
#: DAQP's exit flags by meaning (its documentation's table).
DAQP_STATUS = {1: "optimal", 2: "soft optimal", -1: "infeasible", -2: "cycling",
               -3: "unbounded", -4: "iteration limit", -5: "non-convex",
               -6: "initial point infeasible"}  # fmt: skip


def _daqp() -> Any:
    """The ``daqp`` package (a dependency of gatetwin; a one-line error if it is missing)."""
    try:
        import daqp
    except ImportError:
        raise ControlError("qp_solver daqp needs the daqp package: pip install daqp") from None
    return daqp


__all__ = [
    "CondensedQp",
    "MpcProblem",
    "MpcSolution",
    "QpBackend",
    "QpData",
    "free_response",
    "free_response_maps",
    "markov_parameters",
    "prediction_matrix",
    "qp_matrices",
    "qp_vectors",
    "qrqp_options",
    "set_casadi_blas_threads",
]
