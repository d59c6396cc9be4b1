"""Hold segments, step onsets, test-type detection and method sufficiency checks.

Works on plain arrays (segment boundaries as index arrays) so it can be vectorised for
records of a million samples; :mod:`gatetwin.records.record` wraps the results in its
frozen classes. The rules are those of :func:`~gatetwin.records.read_record`:

* a hold segment is a maximal run of ``hold`` samples, split where the time step exceeds
  ``GAP_FACTOR`` nominal periods (segments never bridge a logging gap) and where the
  opening moves by at least the actuator resolution from the segment's first opening;
* a step is an opening change of at least the resolution between consecutive hold
  segments, observed only when no logging gap lies between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gatetwin.errors import RecordError
from gatetwin.records.checks import Origin
from gatetwin.records.sidecar import TEST_TYPES

__all__ = [
    "GAP_FACTOR",
    "MIN_FLOW_SAMPLES",
    "PRBS_DETECT_MIN_STEPS",
    "PRBS_DROPPED_PER_SEGMENT",
    "PRBS_MIN_STEPS",
    "PRBS_MIN_USABLE_SAMPLES",
    "RESOLUTION_MM",
    "STEP_DETECT_MAX_STEPS",
    "STEP_WINDOW_SAMPLES",
    "HoldSegment",
    "Segmentation",
    "Segmented",
    "StepOnset",
    "check_median_step",
    "check_method",
    "choose_test",
    "detect_test",
    "find_steps",
    "held_after",
    "is_gap",
    "same_inflow",
    "segment_holds",
]

#: Actuator position resolution, mm: smaller opening differences are not steps.
RESOLUTION_MM = 1.0
#: A time step longer than this many nominal sample periods is a logging gap.
GAP_FACTOR = 1.5
#: Valid hold samples needed before and after the first step (the paper's 40-sample windows).
STEP_WINDOW_SAMPLES = 40
#: Steps and usable hold samples a PRBS test needs; ARX(2,2,1) drops 2 samples per segment.
PRBS_MIN_STEPS = 2
PRBS_MIN_USABLE_SAMPLES = 30
PRBS_DROPPED_PER_SEGMENT = 2
#: Detection: at most this many steps between long hold segments make a step test ...
STEP_DETECT_MAX_STEPS = 3
#: ... and at least this many steps a PRBS test.
PRBS_DETECT_MIN_STEPS = 4

_TOL = 1e-9
_SOURCE_WORDS = {
    "option": "from the test option",
    "sidecar": "from the sidecar",
    "detected": "detected from the data",
}


@dataclass(frozen=True)
class HoldSegment:
    """A run of consecutive ``hold`` samples at one constant opening.

    Attributes
    ----------
    start, stop : int
        Sample indices, ``stop`` exclusive (Python slice convention).
    opening_mm : float
        The (median) opening over the segment, mm.
    """

    start: int
    stop: int
    opening_mm: float

    @property
    def n_samples(self) -> int:
        return self.stop - self.start

    @property
    def slice(self) -> slice:
        """The segment as a slice into the record's arrays."""
        return slice(self.start, self.stop)


@dataclass(frozen=True)
class StepOnset:
    """A change of gate opening between two hold segments.

    Attributes
    ----------
    index : int
        Index of the first sample after the last sample of the previous hold segment
        (the first ``open`` sample when the logger saw the motion).
    time_s : float
        Onset time, s: the time of that sample (start of gate motion as logged).
    before, after : HoldSegment
        The hold segments on either side of the step.
    held : HoldSegment or None
        ``after`` run on to where the gate next moved or the inflow changed
        (:func:`held_after`): past its end when the gate held through a logging gap; None:
        ``after``.
    """

    index: int
    time_s: float
    before: HoldSegment
    after: HoldSegment
    held: HoldSegment | None = None

    @property
    def delta_e_mm(self) -> float:
        return self.after.opening_mm - self.before.opening_mm

    @property
    def held_after(self) -> HoldSegment:
        """The hold after the step, to where the gate next moved or the inflow changed
        (``held``, else ``after``)."""
        return self.held if self.held is not None else self.after


@dataclass(frozen=True)
class Segmented:
    """What the method checks look at: a record's test type, segments and levels.

    Attributes
    ----------
    test, test_source : str
        Test type and where it came from (``"option"``, ``"sidecar"``, ``"detected"``).
    holds, steps : tuple
        Hold segments and observed steps.
    unobserved_steps : int
        Opening changes inside logging gaps.
    levels_mm : dict[str, ndarray]
        Level per gauge, mm, NaN where missing.
    """

    test: str
    test_source: str
    holds: tuple[HoldSegment, ...]
    steps: tuple[StepOnset, ...]
    unobserved_steps: int
    levels_mm: dict[str, np.ndarray]

    @property
    def gauges(self) -> tuple[str, ...]:
        return tuple(self.levels_mm)

    def valid_samples(self, segment: HoldSegment, gauge: str) -> int:
        """Number of samples of ``segment`` with a finite level at ``gauge``."""
        return int(np.count_nonzero(np.isfinite(self.levels_mm[gauge][segment.slice])))


@dataclass(frozen=True)
class Segmentation:
    """Hold segments as index arrays, and the opening with hold gaps filled.

    Attributes
    ----------
    starts, stops : ndarray of int
        Segment bounds, ``stops`` exclusive.
    openings_mm : ndarray
        Median opening of each segment, mm.
    opening_mm : ndarray
        The opening per sample, with empty hold openings filled by their segment median.
    filled : ndarray of bool
        True where an empty hold opening was filled.
    """

    starts: np.ndarray
    stops: np.ndarray
    openings_mm: np.ndarray
    opening_mm: np.ndarray
    filled: np.ndarray


def check_median_step(name: str, period_s: float, median_s: float) -> None:
    """Refuse a sidecar's ``sample_period_s`` the time steps do not keep: their median more
    than :data:`GAP_FACTOR` times longer (a record of gaps) or shorter (a logger twice as
    fast as its sidecar says: every time constant and horizon sized from the period would be
    off by as much). ``name`` labels the message."""
    if not period_s / GAP_FACTOR <= median_s <= GAP_FACTOR * period_s:
        raise RecordError(
            f"{name}: sample period {period_s:g} s (sidecar field 'sample_period_s') but the "
            f"median time step is {median_s:g} s; expected the nominal sample period"
        )


def is_gap(time_s: np.ndarray, period_s: float) -> np.ndarray:
    """For each time step, whether it is a logging gap (length ``n - 1``)."""
    return np.diff(time_s) > GAP_FACTOR * period_s


def segment_holds(
    origin: Origin,
    time_s: np.ndarray,
    opening_mm: np.ndarray,
    hold: np.ndarray,
    period_s: float,
) -> Segmentation:
    """Find the hold segments and fill empty hold openings.

    Raises
    ------
    RecordError
        If a hold segment has no opening value at all.
    """
    starts, stops = _hold_runs(hold, is_gap(time_s, period_s))
    starts, stops = _split_on_opening_change(opening_mm, starts, stops)
    index, segment = _expand(starts, stops)
    medians = _segment_medians(opening_mm[index], segment, starts.size)
    empty = np.flatnonzero(np.isnan(medians))
    if empty.size:
        k = empty[0]
        raise origin.error(
            f"{origin.row(starts[k])} to {origin.row(stops[k] - 1)}",
            origin.column("opening_mm"),
            "hold samples without any opening value; expected the opening of the held gate",
        )
    opening = np.array(opening_mm, dtype=np.float64, copy=True)
    missing = np.isnan(opening[index])
    opening[index[missing]] = medians[segment[missing]]
    filled = np.zeros(opening.size, dtype=bool)
    filled[index[missing]] = True
    return Segmentation(starts, stops, medians, opening, filled)


def _hold_runs(hold: np.ndarray, gap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    starts_here = np.concatenate(([True], gap | ~hold[:-1]))
    ends_here = np.concatenate((gap | ~hold[1:], [True]))
    return np.flatnonzero(hold & starts_here), np.flatnonzero(hold & ends_here) + 1


def _split_on_opening_change(
    opening_mm: np.ndarray, starts: np.ndarray, stops: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    bounds = np.column_stack((starts, stops)).ravel()
    padded = np.concatenate((opening_mm, [np.nan]))
    low = np.fmin.reduceat(padded, bounds)[::2]
    high = np.fmax.reduceat(padded, bounds)[::2]
    moving = np.flatnonzero(high - low >= RESOLUTION_MM - _TOL)
    if not moving.size:
        return starts, stops
    cuts = np.concatenate([_cuts(opening_mm, starts[k], stops[k]) for k in moving], dtype=np.int64)
    return np.sort(np.concatenate((starts, cuts))), np.sort(np.concatenate((stops, cuts)))


def _cuts(opening_mm: np.ndarray, start: int, stop: int) -> list[int]:
    """Sample indices inside ``[start, stop)`` where the opening leaves the resolution."""
    cuts: list[int] = []
    values = opening_mm[start:stop]
    reference = None
    for i in np.flatnonzero(np.isfinite(values)):
        value = float(values[i])
        if reference is None:
            reference = value
        elif abs(value - reference) >= RESOLUTION_MM - _TOL:
            cuts.append(start + int(i))
            reference = value
    return cuts


def _expand(starts: np.ndarray, stops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices of all segments, and the segment number of each."""
    lengths = stops - starts
    offsets = np.concatenate(([0], np.cumsum(lengths)[:-1]))
    index = np.repeat(starts - offsets, lengths) + np.arange(int(lengths.sum()))
    return index, np.repeat(np.arange(starts.size), lengths)


def _segment_medians(values: np.ndarray, segment: np.ndarray, n_segments: int) -> np.ndarray:
    """Median of the finite ``values`` per segment (NaN for a segment without any)."""
    ok = np.isfinite(values)
    values, segment = values[ok], segment[ok]
    order = np.lexsort((values, segment))
    values = values[order]
    counts = np.bincount(segment, minlength=n_segments)
    offsets = np.concatenate(([0], np.cumsum(counts)[:-1]))
    medians = np.full(n_segments, np.nan)
    has = counts > 0
    low = offsets[has] + (counts[has] - 1) // 2
    high = offsets[has] + counts[has] // 2
    medians[has] = 0.5 * (values[low] + values[high])
    return medians


def find_steps(seg: Segmentation, time_s: np.ndarray, period_s: float) -> tuple[np.ndarray, int]:
    """Steps between consecutive hold segments.

    Returns
    -------
    pairs : ndarray of int
        ``k`` for each observed step between segments ``k`` and ``k + 1``.
    unobserved : int
        Opening changes whose two segments are separated by a logging gap.
    """
    if seg.starts.size < 2:
        return np.zeros(0, dtype=np.int64), 0
    change = np.abs(np.diff(seg.openings_mm)) >= RESOLUTION_MM - _TOL
    gaps_before = np.concatenate(([0], np.cumsum(is_gap(time_s, period_s))))
    gapped = gaps_before[seg.starts[1:]] - gaps_before[seg.stops[:-1] - 1] > 0
    return np.flatnonzero(change & ~gapped), int(np.count_nonzero(change & gapped))


#: Logged discharges a side needs before :func:`held_after` tells two inflows apart.
MIN_FLOW_SAMPLES = 5


def held_after(holds: Sequence[HoldSegment], k: int,
               flow_m3h: np.ndarray | None = None) -> HoldSegment:  # fmt: skip
    """Hold segment ``k`` run on through the segments that follow it sample after sample with
    no step between them (as :func:`find_steps` tells one: the openings within
    :data:`RESOLUTION_MM`) and, given the logged discharge ``flow_m3h`` (NaN where not
    logged), at the same inflow (:func:`same_inflow` against the span so far): a logging
    gap, or a drift the actuator's resolution does not call a move, ends a hold segment but
    not the gate's hold. Ends where samples not on hold (the gate moving), an opening change
    (observed or inside a gap) or an inflow change come."""
    stop = holds[k].stop
    for before, segment in zip(holds[k:], holds[k + 1 :], strict=False):
        if segment.start != stop or not (
            abs(segment.opening_mm - before.opening_mm) < RESOLUTION_MM - _TOL
        ):
            break
        if flow_m3h is not None and not same_inflow(flow_m3h[holds[k].start : stop],
                                                    flow_m3h[segment.slice]):  # fmt: skip
            break
        stop = segment.stop
    return HoldSegment(holds[k].start, stop, holds[k].opening_mm)


def same_inflow(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two runs of logged discharges (NaN where not logged) are one inflow: their
    medians within three robust standard deviations (the normal-scaled MAD,
    :func:`scipy.stats.median_abs_deviation`) of the discharges about their own run's
    median, pooled over both. A side with fewer than
    :data:`MIN_FLOW_SAMPLES` logged values cannot tell them apart (one inflow)."""
    from scipy.stats import median_abs_deviation  # scipy only when a step is read

    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if min(a.size, b.size) < MIN_FLOW_SAMPLES:
        return True
    centre_a, centre_b = float(np.median(a)), float(np.median(b))
    deviations = np.concatenate((a - centre_a, b - centre_b))
    # each side is about its own median already: the deviations' spread about zero
    spread = 3.0 * float(median_abs_deviation(deviations, center=lambda x, axis: 0.0,
                                              scale="normal"))  # fmt: skip
    return abs(centre_a - centre_b) <= spread + _TOL * max(abs(centre_a), abs(centre_b))


def choose_test(
    origin: Origin, option: str | None, sidecar: str | None, steps: Sequence[StepOnset]
) -> tuple[str, str]:
    """The test type and where it came from (option, then sidecar, then detection)."""
    if option is not None:
        if option not in TEST_TYPES:
            raise origin.error(f"test {option!r}", "expected 'step', 'prbs', 'free' or 'routine'")
        return option, "option"
    if sidecar is not None:
        return sidecar, "sidecar"
    return detect_test(steps), "detected"


def detect_test(steps: Sequence[StepOnset]) -> str:
    """``"free"`` without steps, ``"step"`` for 1–3 steps between long holds, else
    ``"prbs"`` for 4 or more steps (and ``"free"`` for a few short ones)."""
    if not steps:
        return "free"
    long_holds = all(
        min(s.before.n_samples, s.held_after.n_samples) >= STEP_WINDOW_SAMPLES for s in steps
    )
    if len(steps) <= STEP_DETECT_MAX_STEPS and long_holds:
        return "step"
    if len(steps) >= PRBS_DETECT_MIN_STEPS:
        return "prbs"
    return "free"


def check_method(origin: Origin, record: Segmented) -> None:
    """Refuse a record too short (or without steps) for its test type's method."""
    if record.test == "step":
        _check_step_test(origin, record)
    elif record.test == "prbs":
        _check_prbs_test(origin, record)


def _test_words(record: Segmented) -> str:
    return f"test '{record.test}' ({_SOURCE_WORDS[record.test_source]})"


def _check_step_test(origin: Origin, record: Segmented) -> None:
    if not record.steps:
        openings = sorted({round(h.opening_mm, 1) for h in record.holds})
        shown = ", ".join(f"{e:g}" for e in openings[:5])
        hidden = (
            f" ({record.unobserved_steps} opening change(s) fall inside logging gaps)"
            if record.unobserved_steps
            else ""
        )
        raise origin.error(
            origin.column("opening_mm"),
            f"{_test_words(record)} but no step: hold openings {shown} mm{hidden}; expected "
            f"an opening change of ≥ {RESOLUTION_MM:g} mm between two hold segments",
        )
    first = record.steps[0]
    for side, segment in (("before", first.before), ("after", first.held_after)):
        count, gauge = min((record.valid_samples(segment, g), g) for g in record.gauges)
        if count < STEP_WINDOW_SAMPLES:
            raise origin.error(
                origin.row(first.index),
                f"step at {first.time_s:g} s: the hold segment {side} it has {count} valid "
                f"samples at gauge {gauge}; {_test_words(record)} needs ≥ "
                f"{STEP_WINDOW_SAMPLES} before and ≥ {STEP_WINDOW_SAMPLES} after the step",
            )


def _check_prbs_test(origin: Origin, record: Segmented) -> None:
    usable, gauge = _fewest_usable(record)
    n_steps = len(record.steps)
    if n_steps >= PRBS_MIN_STEPS and usable >= PRBS_MIN_USABLE_SAMPLES:
        return
    raise origin.error(
        origin.column("opening_mm"),
        f"{_test_words(record)} needs ≥ {PRBS_MIN_STEPS} steps and ≥ "
        f"{PRBS_MIN_USABLE_SAMPLES} usable hold samples; found {n_steps} step(s) and "
        f"{usable} usable samples at gauge {gauge} (the first {PRBS_DROPPED_PER_SEGMENT} "
        "samples of each hold segment are not usable)",
    )


def _fewest_usable(record: Segmented) -> tuple[int, str]:
    starts = np.array([h.start for h in record.holds], dtype=np.int64)
    stops = np.array([h.stop for h in record.holds], dtype=np.int64)
    counts = []
    for gauge, level in record.levels_mm.items():
        finite = np.concatenate(([0], np.cumsum(np.isfinite(level))))
        valid = finite[stops] - finite[starts]
        counts.append((int(np.maximum(valid - PRBS_DROPPED_PER_SEGMENT, 0).sum()), gauge))
    return min(counts)
