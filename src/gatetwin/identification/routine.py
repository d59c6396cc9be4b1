"""FOPDT identification from a routine operation history (a SCADA log, no designed test).

A history of days to months holds many gate moves, most of them useless for
identification. This module finds the informative *windows* — a gate move (or a burst of
moves close together) with a steady level before it, a hold long enough after it for the
level to settle, no logging gap and no real inflow change inside, and a level response
well above the noise — fits the input-driven FOPDT
(:func:`~gatetwin.identification.fopdt_driven.fit_fopdt_driven`, the only fitter used) on each,
and combines the windows by discharge into a schedule and an overall estimate.

Closed loop: when a level controller moves the gate, its moves answer the disturbances
(an inflow change raises the level, the controller opens), and the disturbance's effect
inside a window is attributed to the move: the estimate is biased. A window whose level
trends before the move, against the move's effect, is flagged; a sidecar that names a
level controller (``level_control``) flags every window. Flagged windows are reported and
warned about; the overall estimate uses the unflagged ones when there are any.

What this is not: a closed-loop identification method (no instrumental variables, no
disturbance model) and not a detector of sensor faults.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError, NoWindowError
from gatetwin.identification.fopdt_driven import fit_fopdt_driven
from gatetwin.identification.preprocess import hampel_filter, reconstructed_opening
from gatetwin.identification.serial import finite_or_none
from gatetwin.records import Record
from gatetwin.records.segments import StepOnset, is_gap

__all__ = [
    "RoutineIdentification",
    "RoutineWindow",
    "ScheduleBin",
    "WindowCriteria",
    "assemble",
    "gauge_of",
    "has_level_controller",
    "identify_routine",
    "move_events",
    "no_window_message",
    "schedule_bins",
    "tally_event",
]


@dataclass(frozen=True)
class WindowCriteria:
    """What makes a window informative (defaults suit pools with T of 30–150 s).

    Attributes
    ----------
    pre_s : float
        Steady hold needed before the first move, s; the window starts this long before it.
    post_min_s : float
        Hold needed after the last move, s (over 3 T of the slowest pool: the level has
        settled to within 5 % of its final value). Moves separated by a shorter hold form
        one window.
    post_max_s : float
        The window ends at most this long after the last move, s.
    max_flow_change : float
        Largest change of the inflow's median between the pre window and the window's
        last third, fraction of the inflow: an orifice's level goes as Q², so 0.3 % of Q
        moves it by 0.6 % — a few per cent of a typical move's response.
    steady_fraction : float
        Largest level drift over the pre window (its linear trend × ``pre_s``), as a
        fraction of the move's level response.
    closed_loop_fraction : float
        A significant pre-window drift against the move's effect larger than this fraction
        of the response flags the window as a closed-loop move.
    min_response_snr : float
        Smallest level response in standard deviations of the pre window's level noise.
    max_gain_rse, max_time_constant_rse : float
        Largest relative standard errors of K and T for a fit to be kept.
    bin_fraction : float
        Width of a schedule bin, fraction of the median inflow of the used windows.
    spike_floor_mm : float
        Smallest deviation from the local median that counts as a level spike, mm.
    """

    pre_s: float = 300.0
    post_min_s: float = 480.0
    post_max_s: float = 1200.0
    max_flow_change: float = 0.003
    steady_fraction: float = 0.10
    closed_loop_fraction: float = 0.03
    min_response_snr: float = 5.0
    max_gain_rse: float = 0.05
    max_time_constant_rse: float = 0.15
    bin_fraction: float = 0.05
    spike_floor_mm: float = 3.0

    def __post_init__(self) -> None:
        if not (0 < self.pre_s and 0 < self.post_min_s <= self.post_max_s
                and 0 < self.max_flow_change and 0 < self.bin_fraction):  # fmt: skip
            raise IdentificationError("routine window criteria: durations and fractions "
                                      "must be > 0 and post_min_s <= post_max_s")  # fmt: skip


@dataclass(frozen=True)
class RoutineWindow:
    """One informative window and its FOPDT fit (± one standard error)."""

    start_time_s: float
    onset_time_s: float
    end_time_s: float
    n_moves: int
    flow_m3h: float
    opening_before_mm: float
    opening_after_mm: float
    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    gain_se_mm_per_mm: float
    time_constant_se_s: float
    rmse_mm: float
    pre_drift_mm: float
    response_mm: float
    closed_loop: bool

    def to_dict(self) -> dict[str, Any]:
        return {k: (round(v, 4) if isinstance(v, float) else v)
                for k, v in asdict(self).items()}  # fmt: skip


@dataclass(frozen=True)
class ScheduleBin:
    """Windows grouped by inflow: medians of their fits."""

    flow_m3h: float
    flow_range_m3h: tuple[float, float]
    n_windows: int
    opening_mm: float
    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["flow_range_m3h"] = [round(v, 3) for v in self.flow_range_m3h]
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in d.items()}


@dataclass(frozen=True)
class RoutineIdentification:
    """FOPDT from a routine history: windows, schedule on Q, overall medians, warnings."""

    record: str
    gauge: str
    n_moves: int
    unobserved_moves: int
    windows: tuple[RoutineWindow, ...]
    rejected: dict[str, int]
    schedule: tuple[ScheduleBin, ...]
    overall: dict[str, float]
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def to_dict(self) -> dict[str, Any]:
        return {
            "test": "routine", "record": self.record, "gauge": self.gauge,
            "n_moves": self.n_moves, "unobserved_moves": self.unobserved_moves,
            "n_windows": len(self.windows),
            "n_closed_loop_windows": sum(w.closed_loop for w in self.windows),
            "rejected": dict(self.rejected),
            "overall": {k: finite_or_none(round(v, 4)) for k, v in self.overall.items()},
            "schedule": [b.to_dict() for b in self.schedule],
            "windows": [w.to_dict() for w in self.windows],
            "warnings": list(self.warnings),
        }  # fmt: skip


def _hold_s(record: Record, start: int, stop: int) -> float:
    return float(record.time_s[stop - 1] - record.time_s[start]) if stop > start else 0.0


def move_events(record: Record, post_min_s: float) -> list[tuple[StepOnset, ...]]:
    """The record's observed steps grouped: a step whose preceding hold is shorter than
    ``post_min_s`` and directly follows the previous step joins its event."""
    events: list[list[StepOnset]] = []
    for step in record.steps:
        prev = events[-1][-1] if events else None
        short = _hold_s(record, step.before.start, step.before.stop) < post_min_s
        joined = prev is not None and prev.after == step.before and short
        if joined:
            events[-1].append(step)
        else:
            events.append([step])
    return [tuple(e) for e in events]


@dataclass(frozen=True)
class _Candidate:
    first: StepOnset
    last: StepOnset
    n_moves: int
    start: int  # window sample range, stop exclusive
    onset: int
    stop: int


def _candidate(record: Record, event: tuple[StepOnset, ...],
               crit: WindowCriteria) -> _Candidate | str:  # fmt: skip
    """The window of an event, or why it has none."""
    first, last = event[0], event[-1]
    t = record.time_s
    if _hold_s(record, first.before.start, first.before.stop) < crit.pre_s:
        return "short hold before the move"
    if _hold_s(record, last.after.start, last.after.stop) < crit.post_min_s:
        return "short hold after the move"
    if abs(last.after.opening_mm - first.before.opening_mm) < 1.0:
        return "no net move"
    start = int(np.searchsorted(t, t[first.before.stop - 1] - crit.pre_s))
    stop = int(np.searchsorted(t, last.time_s + crit.post_max_s, side="right"))
    stop = min(stop, last.after.stop)
    if np.any(is_gap(t[start:stop], record.sample_period_s)):
        return "logging gap inside"
    return _Candidate(first, last, len(event), start, first.index, stop)


@dataclass(frozen=True)
class _Screen:
    level: np.ndarray
    drift_mm: float
    drift_se_mm: float
    response_mm: float
    noise_sd_mm: float


def _screen(record: Record, cand: _Candidate, gauge: str, crit: WindowCriteria) -> _Screen | str:
    """Level cleaned of spikes and the window's pre-drift and response, or why it fails."""
    sl = slice(cand.start, cand.stop)
    t, q = record.time_s[sl], record.flow_m3h[sl]
    level = hampel_filter(record.levels_mm[gauge][sl], [(0, cand.stop - cand.start)],
                          floor=crit.spike_floor_mm).values  # fmt: skip
    n_pre = cand.first.before.stop - cand.start
    tail = slice(-max(10, (cand.stop - cand.start) // 3), None)
    q_pre, q_end = np.nanmedian(q[:n_pre]), np.nanmedian(q[tail])
    if not abs(q_end - q_pre) <= crit.max_flow_change * q_pre:
        return "inflow change inside"
    ok = np.isfinite(level[:n_pre])
    if ok.sum() < 20:
        return "too few levels before the move"
    tp, yp = t[:n_pre][ok], level[:n_pre][ok]
    coef, cov = np.polyfit(tp - tp[0], yp, 1, cov=True)
    noise = float(np.std(yp - np.polyval(coef, tp - tp[0]), ddof=2))
    span = float(tp[-1] - tp[0])
    drift, drift_se = float(coef[0]) * span, float(np.sqrt(cov[0, 0])) * span
    end_level = np.nanmedian(level[tail][-max(10, round(60.0 / record.sample_period_s)) :])
    response = float(end_level - np.nanmedian(yp[-max(10, yp.size // 3) :]))
    if not abs(response) >= crit.min_response_snr * max(noise, 1e-9):
        return "level response too small"
    if abs(drift) > crit.steady_fraction * abs(response):
        return "level not steady before the move"
    return _Screen(level, drift, drift_se, response, noise)


def _closed_loop(scr: _Screen, crit: WindowCriteria, controller: bool) -> bool:
    """A controller's move answers a trend: significant drift against the move's effect."""
    against = np.sign(scr.drift_mm) != np.sign(scr.response_mm)
    significant = abs(scr.drift_mm) > max(
        3.0 * scr.drift_se_mm, crit.closed_loop_fraction * abs(scr.response_mm)
    )
    return controller or bool(against and significant)


def _fit_window(record: Record, cand: _Candidate, scr: _Screen, crit: WindowCriteria,
                controller: bool) -> RoutineWindow | str:  # fmt: skip
    sl = slice(cand.start, cand.stop)
    t = record.time_s[sl]
    opening = reconstructed_opening(t, record.opening_mm[sl], record.hold[sl])
    delta = float(opening[-1] - opening[0])
    try:
        fit = fit_fopdt_driven(t - t[0], opening, scr.level,
                               initial=(scr.response_mm / delta, 60.0, 1.0))  # fmt: skip
    except (IdentificationError, ValueError, np.linalg.LinAlgError):
        return "fit failed"
    k_rse = fit.gain_se_mm_per_mm / abs(fit.gain_mm_per_mm) if fit.gain_mm_per_mm else np.inf
    if not (
        k_rse <= crit.max_gain_rse
        and fit.time_constant_se_s <= crit.max_time_constant_rse * fit.time_constant_s
    ):
        return "fit too uncertain"  # fmt: skip
    return RoutineWindow(
        start_time_s=float(t[0]), onset_time_s=float(cand.first.time_s),
        end_time_s=float(t[-1]), n_moves=cand.n_moves,
        flow_m3h=float(np.nanmedian(record.flow_m3h[sl])),
        opening_before_mm=float(cand.first.before.opening_mm),
        opening_after_mm=float(cand.last.after.opening_mm),
        gain_mm_per_mm=fit.gain_mm_per_mm, time_constant_s=fit.time_constant_s,
        dead_time_s=fit.dead_time_s, gain_se_mm_per_mm=fit.gain_se_mm_per_mm,
        time_constant_se_s=fit.time_constant_se_s, rmse_mm=fit.rmse_mm,
        pre_drift_mm=scr.drift_mm, response_mm=scr.response_mm,
        closed_loop=_closed_loop(scr, crit, controller),
    )  # fmt: skip


def schedule_bins(windows: list[RoutineWindow], bin_fraction: float) -> tuple[ScheduleBin, ...]:
    """Windows grouped by inflow in bins ``bin_fraction`` × the median inflow wide."""
    flows = np.array([w.flow_m3h for w in windows])
    width = bin_fraction * float(np.median(flows))
    keys = np.floor(flows / width).astype(int)
    bins = []
    for key in np.unique(keys):
        group = [w for w, k in zip(windows, keys, strict=True) if k == key]
        bins.append(ScheduleBin(
            flow_m3h=float(np.median([w.flow_m3h for w in group])),
            flow_range_m3h=(float(key * width), float((key + 1) * width)),
            n_windows=len(group),
            opening_mm=float(np.median([w.opening_before_mm for w in group])),
            gain_mm_per_mm=float(np.median([w.gain_mm_per_mm for w in group])),
            time_constant_s=float(np.median([w.time_constant_s for w in group])),
            dead_time_s=float(np.median([w.dead_time_s for w in group])),
        ))  # fmt: skip
    return tuple(bins)


def _overall(windows: list[RoutineWindow]) -> dict[str, float]:
    k = np.array([w.gain_mm_per_mm for w in windows])
    tau = np.array([w.time_constant_s for w in windows])
    return {
        "gain_mm_per_mm": float(np.median(k)), "time_constant_s": float(np.median(tau)),
        "dead_time_s": float(np.median([w.dead_time_s for w in windows])),
        "gain_iqr_mm_per_mm": float(np.subtract(*np.percentile(k, [75, 25]))),
        "time_constant_iqr_s": float(np.subtract(*np.percentile(tau, [75, 25]))),
        "flow_min_m3h": float(min(w.flow_m3h for w in windows)),
        "flow_max_m3h": float(max(w.flow_m3h for w in windows)),
        "n_windows_used": float(len(windows)),
    }  # fmt: skip


def gauge_of(record: Record, gauge: str | None) -> str:
    """The gauge to identify: ``gauge`` checked, else the record's only one."""
    where = record.path or "record"
    if gauge is None:
        if len(record.gauges) != 1:
            raise IdentificationError(f"{where}: {len(record.gauges)} gauges "
                                      f"({', '.join(record.gauges)}); choose one")  # fmt: skip
        return record.gauges[0]
    if gauge not in record.levels_mm:
        raise IdentificationError(f"{where}: no gauge {gauge}; it has "
                                  f"{', '.join(record.gauges)}")  # fmt: skip
    return gauge


def no_window_message(where: str, n: int, unobserved: int, rejected: dict[str, int]) -> str:
    """Why a history of ``n`` observed moves has no informative window (one line)."""
    if n == 0:
        hidden = (f" ({unobserved} opening change(s) fall inside logging gaps)"
                  if unobserved else "")  # fmt: skip
        return f"{where}: no informative window: the gate never moves while logged{hidden}"
    why = ", ".join(f"{reason} {count}" for reason, count in sorted(rejected.items()))
    return (
        f"{where}: no informative window among {n} observed gate move(s) "
        f"(rejected: {why}); no model is estimated"
    )


def identify_routine(record: Record, gauge: str | None = None,
                     criteria: WindowCriteria | None = None) -> RoutineIdentification:  # fmt: skip
    """FOPDT windows, schedule on Q and overall medians from a routine history.

    Parameters
    ----------
    record : Record
        A read record (any test type; its steps are the gate moves the logger saw).
    gauge : str, optional
        Gauge to identify (default the record's only gauge).
    criteria : WindowCriteria, optional
        What makes a window informative.

    Returns
    -------
    RoutineIdentification

    Raises
    ------
    IdentificationError
        No such gauge, or no informative window (the message says why the moves failed).
    """
    crit = criteria or WindowCriteria()
    name = gauge_of(record, gauge)
    controller = has_level_controller(record)
    rejected: dict[str, int] = {}
    windows: list[RoutineWindow] = []
    for event in move_events(record, crit.post_min_s):
        tally_event(record, event, name, crit, controller, windows, rejected)
    where = record.path or "record"
    if not windows:
        raise NoWindowError(no_window_message(where, len(record.steps),
                                                    record.unobserved_steps, rejected))  # fmt: skip
    return assemble(record.path, len(record.steps), record.unobserved_steps, name, windows,
                    rejected, crit, controller)  # fmt: skip


def has_level_controller(record: Record) -> bool:
    """Whether the record's sidecar names a level controller (``level_control``)."""
    return isinstance(record.metadata.get("level_control"), dict)


def tally_event(record: Record, event: tuple[StepOnset, ...], gauge: str, crit: WindowCriteria,
                controller: bool, windows: list[RoutineWindow],
                rejected: dict[str, int]) -> None:  # fmt: skip
    """Screen and fit one move event: its window joins ``windows``, or its moves are counted
    in ``rejected`` under the reason."""
    outcome: Any = _candidate(record, event, crit)
    if isinstance(outcome, _Candidate):
        scr = _screen(record, outcome, gauge, crit)
        outcome = scr if isinstance(scr, str) else _fit_window(record, outcome, scr,
                                                                 crit, controller)  # fmt: skip
    if isinstance(outcome, str):
        rejected[outcome] = rejected.get(outcome, 0) + len(event)
    else:
        windows.append(outcome)


def assemble(path: str, n_moves: int, unobserved: int, gauge: str,
             windows: list[RoutineWindow], rejected: dict[str, int], crit: WindowCriteria,
             controller: bool) -> RoutineIdentification:  # fmt: skip
    """The identification from its windows (at least one) and the history's move counts."""
    open_loop = [w for w in windows if not w.closed_loop]
    used = open_loop or windows
    warnings = []
    n_closed = len(windows) - len(open_loop)
    if controller:
        warnings.append("the sidecar names a level controller (level_control): every window "
                        "is a closed-loop move; K and T may be biased by the disturbances "
                        "the controller answered")  # fmt: skip
    elif n_closed:
        use = (
            "left out of the overall estimate"
            if open_loop
            else "the overall estimate uses them and may be biased"
        )
        warnings.append(f"{n_closed} of {len(windows)} windows move against a level trend "
                        f"before the move (closed-loop moves): {use}")  # fmt: skip
    return RoutineIdentification(
        record=path, gauge=gauge, n_moves=n_moves,
        unobserved_moves=unobserved, windows=tuple(windows),
        rejected=rejected, schedule=schedule_bins(used, crit.bin_fraction),
        overall=_overall(used), warnings=tuple(warnings),
    )  # fmt: skip
