"""Settings of the MPC and its disturbance observer (documented, frozen dataclasses)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from gatetwin.errors import ControlError
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S

#: QP solvers the MPC accepts: DAQP through its own package, the others casadi ``conic``
#: plugins reachable from PyPI's casadi.
QP_SOLVERS = ("qpoases", "daqp", "osqp", "qrqp")

#: The gain magnitude of the default settings, mm/mm (gauge 3F of the bundled flume at
#: 50 m³/h).
REFERENCE_GAIN_MM_PER_MM = 12.5


def gate_move_weight(gain_mm_per_mm: float) -> float:
    """The MPC's weight of a gate move for a plant of steady gain ``K``: ``K²`` (1/mm² of
    level per mm² of move), so that a move costs what its whole steady effect on the level
    would cost as a level error for one sample.

    The rule in every place an MPC is tuned (the flume's defaults, the controller FMUs, the
    SWMM loops). A lighter weight (``(K/4)²`` before) made the MPC answer the gauge's noise
    and a pool's first resonance, which no FOPDT twin carries: on a canal pool it pumped
    that resonance into a limit cycle, and on the flume the gate reversed about three times
    as often for a few per cent less IAE."""
    return max(gain_mm_per_mm**2, 1e-9)


@dataclass(frozen=True)
class ObserverSettings:
    """Kalman filter on the model state and an input disturbance (offset-free MPC).

    The disturbance ``d`` (mm of opening) is a random walk added to the gate opening; with
    it in the model, any constant mismatch (gain, level, the actuator's rounding) is
    absorbed by ``d`` and leaves no steady error. The defaults were chosen on the demo's
    scenarios (30 min, both plants, several noise seeds): a slower ``d`` (0.03–0.1 mm)
    leaves the flume's 8 mm opening mismatch at 60 m³/h to be integrated out over
    minutes; a faster one (> 0.3 mm) mostly adds gate travel.

    Attributes
    ----------
    measurement_sd_mm : float
        Standard deviation of the level measurement noise, mm (the demo's gauge: 0.7 mm).
    level_sd_mm : float
        Process noise on the level state per sample, mm (1 mm): how far the level may
        wander from the model in one sample — the flume's waves and its own response to an
        inflow change.
    disturbance_sd_mm : float
        Random-walk step of the input disturbance per sample, mm of opening (0.3 mm): sets
        how fast a mismatch is integrated out.
    """

    measurement_sd_mm: float = 0.7
    level_sd_mm: float = 1.0
    disturbance_sd_mm: float = 0.3

    def __post_init__(self) -> None:
        values = (self.measurement_sd_mm, self.level_sd_mm, self.disturbance_sd_mm)
        if not all(v > 0 and math.isfinite(v) for v in values):
            raise ControlError("observer: standard deviations must be finite and > 0")


@dataclass(frozen=True)
class MpcSettings:
    """Horizon, constraints, weights and solver of the level MPC.

    Cost over the horizon ``j = 1..N`` (levels in mm, openings in mm)::

        Σ level_weight (level_j − setpoint)² + Σ move_weight (e_j − e_{j−1})²
          + slack_weight_quadratic s² + slack_weight_linear s

    subject to ``opening_range_mm``, ``|e_j − e_{j−1}| <= opening_rate_mm_s · Ts`` and the
    soft band ``level_band_mm[0] − s <= level_j <= level_band_mm[1] + s``, ``s >= 0``. The
    linear slack weight makes the softening exact: the band holds whenever it can.

    Attributes
    ----------
    horizon : int
        Prediction (and control) horizon, samples (100 × 1.2 s = 2 min ≈ 2–3 T).
    sample_period_s : float
        Control period, s.
    opening_range_mm : tuple[float, float]
        Allowed gate opening, mm.
    opening_rate_mm_s : float
        Largest gate speed the MPC plans with, mm/s: 0.6 mm/s, a conservative loaded speed
        (the flume's actuator runs at ~1.2 mm/s at 0.24 m depth and ~0.66 mm/s at
        0.35 m, :func:`gatetwin.flume.solver.leaf_speed`), i.e. 0.72 mm per sample.
    level_band_mm : tuple[float, float] or None
        Soft level band, mm; ``None`` drops it (and the slack). (100, 360): the flume's
        wall is 400 mm high (40 mm freeboard), and below 100 mm the gate would run nearly
        free at the demo's openings.
    level_weight : float
        Weight of the squared level error, 1/mm².
    move_weight : float
        Weight of the squared gate move, 1/mm²: :func:`gate_move_weight` of the reference
        gain (12.5² = 156.25; a 1 mm move costs what 12.5 mm of level error costs for one
        sample).
    slack_weight_quadratic, slack_weight_linear : float
        Penalties of the band slack, 1/mm² and 1/mm.
    qp_solver : str
        ``"daqp"`` (default: the daqp package, one workspace per model kept from sample to
        sample; fastest measured), or a casadi conic plugin: ``"qpoases"`` (hot-started),
        ``"osqp"`` or ``"qrqp"`` (casadi's own active-set solver); see
        ``benchmarks/bench_mpc.py``.
    blas_threads : int or None
        Threads of the OpenBLAS bundled with casadi, which qpOASES' dense algebra uses
        (process-wide, set when a casadi solver is made; ``None`` leaves it alone). 1: at
        N = 100–200 the matrices are too small to gain from threads, and on a busy 2-core
        machine OpenBLAS' threads made single solves take 40–50 ms instead of 0.5 ms.
    backlash_hold_mm : float
        For a plant with an ``actuator_backlash``: the smallest gate reversal the MPC makes,
        mm (1e-6: a reversal below a micrometre is round-off in the plan, and each one
        costs a crossing of the dead band; :class:`gatetwin.mpc.actuation.CommandShaper`).
        Larger values do not stop the plan's small reversals near a set-point: they trade
        them for a steady error of up to ``|K|`` × the hold.
    tangent_grid_rel : float
        For the envelope linearisation: the tangent's ``K`` and ``T`` are kept on a
        geometric grid of this relative step (0.01), so the QP's matrices are rebuilt only
        when the gain or time constant has moved by ~1 % (a gain error of 0.5 % at most,
        far inside what the offset-free observer absorbs), not at every sample
        (:func:`gatetwin.mpc.envelope.linearised_model`). 0: the exact tangent each time.
    move_weight_gain_mm_per_mm : float
        The gain magnitude ``move_weight`` was tuned for, mm/mm (12.5: gauge 3F at
        50 m³/h). With the envelope linearisation, where the tangent's ``|K|`` is larger
        (a nearly closed gate: −28 mm/mm at 20 mm and 50 m³/h), the move weight grows with
        ``(K / this)²``, so that a move costs what a move of the same effect on the level
        cost at the tuning point; it never shrinks below ``move_weight``.
    observer : ObserverSettings
        The disturbance observer's tuning.
    """

    horizon: int = 100
    sample_period_s: float = SAMPLE_PERIOD_S
    opening_range_mm: tuple[float, float] = (5.0, 100.0)
    opening_rate_mm_s: float = 0.6
    level_band_mm: tuple[float, float] | None = (100.0, 360.0)
    level_weight: float = 1.0
    move_weight: float = gate_move_weight(REFERENCE_GAIN_MM_PER_MM)
    slack_weight_quadratic: float = 1.0e3
    slack_weight_linear: float = 1.0e3
    qp_solver: str = "daqp"
    blas_threads: int | None = 1
    backlash_hold_mm: float = 1e-6
    tangent_grid_rel: float = 0.01
    move_weight_gain_mm_per_mm: float = REFERENCE_GAIN_MM_PER_MM
    observer: ObserverSettings = field(default_factory=ObserverSettings)

    def __post_init__(self) -> None:
        lo, hi = self.opening_range_mm
        checks = {
            "horizon": isinstance(self.horizon, int) and 1 <= self.horizon <= 2000,
            "sample_period_s": self.sample_period_s > 0,
            "opening_range_mm": 0 <= lo < hi < math.inf,
            "opening_rate_mm_s": 0 < self.opening_rate_mm_s < math.inf,
            "weights": self.level_weight > 0
            and self.move_weight > 0
            and self.slack_weight_quadratic > 0
            and self.slack_weight_linear >= 0,
            "qp_solver": self.qp_solver in QP_SOLVERS,
            "blas_threads": self.blas_threads is None or self.blas_threads >= 1,
            "backlash_hold_mm": 0 <= self.backlash_hold_mm < math.inf,
            "tangent_grid_rel": 0 <= self.tangent_grid_rel < 1,
            "move_weight_gain_mm_per_mm": 0 < self.move_weight_gain_mm_per_mm < math.inf,
        }
        if self.level_band_mm is not None:
            checks["level_band_mm"] = self.level_band_mm[0] < self.level_band_mm[1]
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ControlError(f"mpc settings: invalid {', '.join(bad)}")

    @property
    def max_move_mm(self) -> float:
        """Largest opening change per sample, mm."""
        return self.opening_rate_mm_s * self.sample_period_s


__all__ = [
    "QP_SOLVERS",
    "REFERENCE_GAIN_MM_PER_MM",
    "MpcSettings",
    "ObserverSettings",
    "gate_move_weight",
]
