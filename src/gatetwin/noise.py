"""The level noise of a record, estimated from its steady holds (the noise floor).

``sigma`` is the standard deviation of the level around a quadratic in time, fitted to the
*last half* of every steady stretch (hold samples at one opening with no step of the
discharge and no logging gap, at least :data:`MIN_STRETCH_SAMPLES` long), pooled over the
stretches (sum of squares over degrees of freedom), stretches more than three times the median
SD dropped. Why this one: the last half of a long hold is past the transient of the move that
began it, the quadratic takes out what is left of it and any slow drift, and unlike the SD of
first differences it keeps correlated noise (the surface waves of a flume are correlated over
seconds; first differences see only their fast part). What it cannot separate is an
oscillation still ringing in the second half of a hold (a slowly decaying seiche): that raises
``sigma``. Without any such stretch it falls back to the robust SD of first differences of
hold samples divided by ``sqrt(2)``, and says so.

Plain functions on arrays, used by the diagnosis (:mod:`gatetwin.diagnose.noise`) and by the
validation harness (:mod:`gatetwin.validate.harness`); :func:`record_noise_floor` applies them
to a :class:`~gatetwin.records.Record`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.records import Record

MIN_STRETCH_SAMPLES = 24
MAD_TO_SD = 1.4826
#: A time step longer than this many nominal periods ends a steady stretch (a logging gap).
STRETCH_GAP_FACTOR = 1.5

METHOD_HOLDS = "SD around a quadratic over the last half of steady holds"
METHOD_DIFFERENCES = ("robust SD of first differences of hold samples / sqrt(2) "
                      "(no steady stretch long enough)")  # fmt: skip


@dataclass(frozen=True)
class NoiseFloor:
    """The record's noise floor.

    Attributes
    ----------
    sigma_mm : float
        Noise SD, mm (NaN when the record has no two consecutive hold levels).
    method : str
        How it was obtained (module docstring).
    n_stretches, n_samples : int
        Steady stretches and samples it rests on.
    """

    sigma_mm: float
    method: str
    n_stretches: int
    n_samples: int

    def to_dict(self) -> dict[str, Any]:
        return {"sigma_mm": self.sigma_mm, "method": self.method,
                "n_stretches": self.n_stretches, "n_samples": self.n_samples}  # fmt: skip


def flow_steps(flow_m3h: np.ndarray) -> np.ndarray:
    """Indices ``i`` where the discharge steps between samples ``i - 1`` and ``i``."""
    dq = np.diff(flow_m3h)
    sd = MAD_TO_SD * float(np.median(np.abs(dq - np.median(dq)))) if dq.size else 0.0
    return np.flatnonzero(np.abs(dq) > max(6.0 * sd, 0.5)) + 1


def steady_stretches(
    time_s: np.ndarray,
    hold: np.ndarray,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
    sample_period_s: float,
) -> list[tuple[int, int]]:
    """``(start, stop)`` runs of hold samples at one opening with no discharge step.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    hold : ndarray of bool
        The logger's actuator flag.
    opening_mm : ndarray
        The opening of every hold sample, mm (other samples are not looked at).
    flow_m3h : ndarray
        Discharge, m³/h, finite.
    sample_period_s : float
        Nominal sample period, s.
    """
    n = time_s.size
    cut = np.zeros(n, dtype=bool)
    cut[flow_steps(flow_m3h)] = True
    cut[1:] |= opening_mm[1:] != opening_mm[:-1]
    cut[1:] |= np.diff(time_s) > STRETCH_GAP_FACTOR * sample_period_s
    out, start = [], None
    for i in range(n):
        if start is not None and (cut[i] or not hold[i]):
            out.append((start, i))
            start = None
        if start is None and hold[i]:
            start = i
    if start is not None:
        out.append((start, n))
    return [(a, b) for a, b in out if b - a >= MIN_STRETCH_SAMPLES]


def noise_floor(
    time_s: np.ndarray, level_mm: np.ndarray, hold: np.ndarray, stretches: list[tuple[int, int]]
) -> NoiseFloor:
    """The level's noise floor from its steady stretches (see the module docstring).

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    level_mm : ndarray
        Level, mm (NaN where missing).
    hold : ndarray of bool
        The logger's actuator flag (for the fallback).
    stretches : list of (int, int)
        From :func:`steady_stretches`.
    """
    sums, dofs = [], []
    for start, stop in stretches:
        idx = np.arange(start + (stop - start) // 2, stop)
        idx = idx[np.isfinite(level_mm[idx])]
        if idx.size < 8:
            continue
        t = time_s[idx] - time_s[idx].mean()
        coef = np.polyfit(t, level_mm[idx], 2)
        resid = level_mm[idx] - np.polyval(coef, t)
        sums.append(float(resid @ resid))
        dofs.append(idx.size - 3)
    if sums:
        ss, dof = np.array(sums), np.array(dofs)
        keep = np.sqrt(ss / dof) <= 3.0 * np.median(np.sqrt(ss / dof))
        sigma = float(np.sqrt(np.sum(ss[keep]) / np.sum(dof[keep])))
        used = int(np.sum(dof[keep]) + 3 * np.count_nonzero(keep))
        return NoiseFloor(sigma, METHOD_HOLDS, int(np.count_nonzero(keep)), used)
    y = np.where(hold, level_mm, np.nan)
    d = np.diff(y)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return NoiseFloor(math.nan, METHOD_DIFFERENCES, 0, 0)
    sigma = MAD_TO_SD * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0)
    return NoiseFloor(sigma, METHOD_DIFFERENCES, 0, int(d.size))


def hold_openings(record: Record) -> np.ndarray:
    """The opening of every hold sample (its segment's), NaN on the others, mm."""
    opening = np.full(record.n_samples, np.nan)
    for seg in record.holds:
        opening[seg.slice] = seg.opening_mm
    return opening


def record_noise_floor(record: Record, gauge: str) -> NoiseFloor:
    """The noise floor of ``record``'s level at ``gauge`` (module docstring).

    Steady stretches run over hold segments (one opening each) and are cut at discharge steps
    and logging gaps, exactly as the diagnosis cuts them; missing discharges are interpolated
    in time.
    """
    t = np.asarray(record.time_s, dtype=float)
    q = np.asarray(record.flow_m3h, dtype=float)
    ok = np.isfinite(q)
    if np.any(ok) and not np.all(ok):
        q = np.interp(t, t[ok], q[ok])
    hold = np.asarray(record.hold, dtype=bool)
    stretches = steady_stretches(t, hold, hold_openings(record), q, record.sample_period_s)
    level = np.asarray(record.levels_mm[gauge], dtype=float)
    return noise_floor(t, level, hold, stretches)
