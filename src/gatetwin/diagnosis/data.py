"""What the diagnosis reads from a record: the commanded opening, its moves, the split.

**Input convention.** A logger shows the *commanded* opening on ``hold`` samples and leaves it
empty (or untrusted) while the actuator moves (``open``). The diagnosis drives every model with
the command a controller would send: on ``hold`` samples the hold's opening, from the first
``open`` sample of a move on the opening of the hold the gate is moving to. A plant therefore
has to explain how the gate gets there (an ``actuator_rate_limit`` block, say), exactly as it
must when an MPC drives it. (:func:`gatetwin.identification.reconstructed_opening` instead fills the
move with a constant-speed ramp -- an actuator model in the input; ``input="reconstructed"``
selects it, and the rate-limit candidate is then not offered.)

Samples are split by time: the first ``1 - holdout_fraction`` of the record is fitted, the rest
held out. Nothing here fits a model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gatetwin.diagnosis.grid_sim import GridInputs, grid_inputs
from gatetwin.errors import IdentificationError
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.noise import flow_steps
from gatetwin.records import Record

__all__ = ["INPUTS", "DiagnosisData", "Move", "commanded_opening", "prepare"]

INPUTS = ("command", "reconstructed")


@dataclass(frozen=True)
class Move:
    """One change of the commanded opening.

    Attributes
    ----------
    index : int
        First sample with the new command (the record's step onset).
    time_s : float
        Its time, s.
    opening_before_mm, opening_after_mm : float
        Command before and after, mm.
    flow_m3h : float
        Discharge at the move, m³/h.
    open_samples : int
        Consecutive ``open`` samples the logger flagged from ``index`` on (0 if none).
    reversal : bool
        The move goes the other way than the previous one (False for the first move).
    """

    index: int
    time_s: float
    opening_before_mm: float
    opening_after_mm: float
    flow_m3h: float
    open_samples: int
    reversal: bool

    @property
    def delta_mm(self) -> float:
        return self.opening_after_mm - self.opening_before_mm


@dataclass(frozen=True)
class DiagnosisData:
    """A record prepared for the diagnosis of one gauge.

    Attributes
    ----------
    gauge : str
        The gauge diagnosed.
    time_s, level_mm, flow_m3h, command_mm : ndarray
        Per sample; ``level_mm`` NaN where missing.
    hold : ndarray of bool
        The logger's actuator flag.
    input_kind : str
        ``"command"`` or ``"reconstructed"`` (module docstring).
    grid : GridInputs
        The inputs on the uniform grid of the sample period.
    sample_period_s : float
        Nominal sample period, s.
    fit_mask, holdout_mask : ndarray of bool
        Samples with a finite level in the fitted and in the held-out part.
    moves : tuple of Move
        The command's changes.
    """

    gauge: str
    time_s: np.ndarray
    level_mm: np.ndarray
    flow_m3h: np.ndarray
    command_mm: np.ndarray
    hold: np.ndarray
    input_kind: str
    grid: GridInputs
    sample_period_s: float
    fit_mask: np.ndarray
    holdout_mask: np.ndarray
    moves: tuple[Move, ...]

    @property
    def valid(self) -> np.ndarray:
        return self.fit_mask | self.holdout_mask

    @property
    def split_time_s(self) -> float:
        return float(self.time_s[np.flatnonzero(self.holdout_mask)[0]])

    @property
    def flow_range_m3h(self) -> tuple[float, float]:
        return float(np.min(self.flow_m3h)), float(np.max(self.flow_m3h))


def commanded_opening(record: Record) -> np.ndarray:
    """Hold openings on hold samples, the next hold's opening on the samples before it."""
    n = record.n_samples
    command = np.full(n, np.nan)
    for seg in record.holds:
        command[seg.start : seg.stop] = seg.opening_mm
    known = np.flatnonzero(np.isfinite(command))
    if known.size == 0:
        raise IdentificationError(f"{record.path or 'record'}: no hold sample carries an opening")
    after = np.searchsorted(known, np.arange(n), side="left")
    return command[known[np.minimum(after, known.size - 1)]]


def _moves(record: Record, command: np.ndarray) -> tuple[Move, ...]:
    changes = np.flatnonzero(np.diff(command) != 0.0) + 1
    hold = np.asarray(record.hold, dtype=bool)
    out: list[Move] = []
    previous = 0.0
    for i in changes:
        stop = i
        while stop < hold.size and not hold[stop]:
            stop += 1
        delta = float(command[i] - command[i - 1])
        out.append(Move(int(i), float(record.time_s[i]), float(command[i - 1]), float(command[i]),
                        float(record.flow_m3h[i]), int(stop - i),
                        bool(previous != 0.0 and np.sign(delta) != np.sign(previous))))  # fmt: skip
        previous = delta
    return tuple(out)


def _filled_flow(record: Record) -> np.ndarray:
    q = np.asarray(record.flow_m3h, dtype=float)
    ok = np.isfinite(q)
    if not np.any(ok):
        raise IdentificationError(f"{record.path or 'record'}: no discharge logged")
    return np.interp(record.time_s, record.time_s[ok], q[ok])


def prepare(
    record: Record, gauge: str, *, input_kind: str = "command", holdout_fraction: float = 0.3
) -> DiagnosisData:
    """Prepare ``record`` for diagnosing ``gauge``.

    Raises
    ------
    IdentificationError
        Unknown gauge or input kind, no move, a split leaving a part without samples.
    """
    where = record.path or "record"
    if gauge not in record.levels_mm:
        raise IdentificationError(f"{where}: no gauge {gauge}; it has {', '.join(record.gauges)}")
    if input_kind not in INPUTS:
        raise IdentificationError(f"input must be one of {', '.join(INPUTS)}, got {input_kind!r}")
    if not 0.05 <= holdout_fraction <= 0.6:
        raise IdentificationError(
            f"hold-out fraction must be in [0.05, 0.6], got {holdout_fraction}"
        )
    t = np.asarray(record.time_s, dtype=float)
    command = commanded_opening(record)
    moves = _moves(record, command)
    flow = _filled_flow(record)
    if not moves and not np.any(flow_steps(flow)):
        raise IdentificationError(
            f"{where}: neither the opening nor the discharge changes; nothing to diagnose"
        )
    driven = command
    if input_kind == "reconstructed":
        driven = reconstructed_opening(t, record.opening_mm, record.hold)
    level = np.asarray(record.levels_mm[gauge], dtype=float)
    finite = np.isfinite(level)
    split = t[0] + (1.0 - holdout_fraction) * (t[-1] - t[0])
    fit, holdout = finite & (t < split), finite & (t >= split)
    if np.count_nonzero(fit) < 50 or np.count_nonzero(holdout) < 20:
        raise IdentificationError(f"{where}: too few samples to fit and to hold out")
    return DiagnosisData(
        gauge=gauge, time_s=t, level_mm=level, flow_m3h=flow, command_mm=command,
        hold=np.asarray(record.hold, dtype=bool), input_kind=input_kind,
        grid=grid_inputs(t, driven, flow, record.sample_period_s),
        sample_period_s=float(record.sample_period_s), fit_mask=fit, holdout_mask=holdout,
        moves=moves,
    )  # fmt: skip
