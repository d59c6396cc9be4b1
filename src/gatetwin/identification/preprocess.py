"""Preprocessing shared by the identification methods: segments, spikes, missing input.

Everything here works on plain numpy arrays and on *segments*: a sequence of
``(start, stop)`` sample-index pairs, ``stop`` exclusive, in time order and not
overlapping -- for a :class:`~gatetwin.records.Record` that is
``[(h.start, h.stop) for h in record.holds]`` (see :func:`record_segments`).

What is done, and how:

* **Missing samples.** :func:`split_segments` cuts every segment at each sample where any
  of the given arrays is not finite; the bad sample itself is excluded. A regression row
  whose lags would reach such a sample is then never formed (it lies in the first samples
  of a new, shorter segment).
* **Spikes.** :func:`hampel_filter` is a Hampel filter applied inside each segment
  separately (windows never reach into the neighbouring segment).
* **Opening during actuator motion.** :func:`reconstructed_opening` fills the opening of
  ``open`` samples by linear interpolation in time between hold openings, i.e. it models
  the actuator as moving at constant speed.
* **Hold-out split.** :func:`holdout_split` cuts the segments into an estimation part and
  a validation part (the last fraction of the record by time).

Nothing here fits a model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from gatetwin.errors import IdentificationError

__all__ = [
    "MAD_TO_SD",
    "Segments",
    "SpikeCorrection",
    "as_segments",
    "clean_segments",
    "constant_within_segments",
    "continuous_segments",
    "hampel_filter",
    "holdout_split",
    "reconstructed_opening",
    "record_segments",
    "segment_mask",
    "split_segments",
]

#: Segments as accepted by the identification functions.
Segments = Sequence[tuple[int, int]] | np.ndarray

#: Scale factor turning a median absolute deviation into a Gaussian standard deviation.
MAD_TO_SD = 1.4826


def as_segments(segments: Segments, n_samples: int) -> np.ndarray:
    """Check segments and return them as an ``(n, 2)`` int64 array.

    Parameters
    ----------
    segments : sequence of (int, int) or ndarray
        ``(start, stop)`` sample-index pairs, ``stop`` exclusive.
    n_samples : int
        Length of the arrays the segments index.

    Returns
    -------
    ndarray of shape (n, 2)
        The segments, empty ones removed.

    Raises
    ------
    IdentificationError
        If a segment lies outside ``[0, n_samples]``, has ``stop < start``, or the segments
        are not in time order or overlap.
    """
    seg = np.asarray(segments, dtype=np.int64)
    if seg.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if seg.ndim != 2 or seg.shape[1] != 2:
        raise IdentificationError("segments must be (start, stop) index pairs")
    seg = seg[seg[:, 1] > seg[:, 0]]
    if seg.size and (seg[0, 0] < 0 or seg[-1, 1] > n_samples):
        raise IdentificationError(f"segments must lie within the {n_samples} samples")
    if np.any(seg[1:, 0] < seg[:-1, 1]):
        raise IdentificationError("segments must be in time order and must not overlap")
    return seg


def segment_mask(segments: np.ndarray, n_samples: int) -> np.ndarray:
    """Boolean mask of the samples that lie in any of the (checked) ``segments``."""
    if segments.size == 0:
        return np.zeros(n_samples, dtype=bool)
    gaps = segments[:, 0] - np.concatenate(([0], segments[:-1, 1]))
    runs = np.column_stack((gaps, segments[:, 1] - segments[:, 0])).ravel()
    runs = np.append(runs, n_samples - segments[-1, 1])
    flags = np.zeros(runs.size, dtype=bool)
    flags[1::2] = True
    return np.repeat(flags, runs)


def clean_segments(segments: np.ndarray, finite: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cut checked segments at the samples where ``finite`` is False.

    Returns
    -------
    segments : ndarray of shape (n, 2)
        Maximal runs of finite samples inside the segments (touching segments stay
        separate).
    mask : ndarray of bool
        The samples inside the returned segments.
    """
    n = finite.size
    inside = segment_mask(segments, n)
    good = inside & finite
    if np.array_equal(good, inside):
        return segments, inside
    first = np.zeros(n, dtype=bool)
    first[segments[:, 0]] = True
    last = np.zeros(n, dtype=bool)
    last[segments[:, 1] - 1] = True
    prev_good = np.concatenate(([False], good[:-1]))
    next_good = np.concatenate((good[1:], [False]))
    starts = np.flatnonzero(good & (first | ~prev_good))
    stops = np.flatnonzero(good & (last | ~next_good)) + 1
    return np.column_stack((starts, stops)), good


def split_segments(segments: Segments, *arrays: np.ndarray) -> np.ndarray:
    """Cut segments at every sample where any of ``arrays`` is NaN or infinite.

    Parameters
    ----------
    segments : sequence of (int, int) or ndarray
        ``(start, stop)`` pairs, ``stop`` exclusive.
    *arrays : ndarray
        Arrays of equal length (e.g. opening in mm and level in mm).

    Returns
    -------
    ndarray of shape (n, 2)
        Maximal runs of finite samples inside the segments. Neighbouring segments stay
        separate even when they touch.
    """
    n = int(np.asarray(arrays[0]).size)
    finite = np.ones(n, dtype=bool)
    for arr in arrays:
        finite &= np.isfinite(np.asarray(arr, dtype=float))
    return clean_segments(as_segments(segments, n), finite)[0]


def continuous_segments(
    time_s: np.ndarray, sample_period_s: float, *, gap_factor: float = 1.5
) -> np.ndarray:
    """Runs of samples without a time gap: the whole record, cut where ``dt > 1.5 Ts``.

    These are the segments of an ARX fit on *all* samples (hold and actuator motion, the
    opening reconstructed by :func:`reconstructed_opening`); the regression must still
    not bridge a gap in the time grid.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s, increasing.
    sample_period_s : float
        Nominal sample period, s.
    gap_factor : float, optional
        A step longer than ``gap_factor * sample_period_s`` is a gap (default 1.5).

    Returns
    -------
    ndarray of shape (n, 2)
    """
    t = np.asarray(time_s, dtype=float)
    cuts = np.flatnonzero(np.diff(t) > gap_factor * sample_period_s) + 1
    edges = np.concatenate(([0], cuts, [t.size]))
    return np.column_stack((edges[:-1], edges[1:])).astype(np.int64)


def constant_within_segments(
    values: np.ndarray, segments: np.ndarray, mask: np.ndarray | None = None
) -> bool:
    """True when ``values`` does not change inside any of the (clean) ``segments``.

    A hold segment has, by definition, one gate opening; an ARX fit on hold rows only
    then sees ``u(k-nk) = u(k-nk-1) = ...`` on every row, and only ``b1 + ... + b_nb`` is
    identifiable. ``mask`` (the samples inside ``segments``) is computed when not given.
    """
    x = np.asarray(values, dtype=float)
    if segments.size == 0:
        return True
    inside = segment_mask(segments, x.size) if mask is None else mask
    first = np.zeros(x.size, dtype=bool)
    first[segments[:, 0]] = True
    change = x[1:] != x[:-1]
    change &= inside[1:]
    change &= ~first[1:]
    return not bool(np.any(change))


def record_segments(record: Any) -> np.ndarray:
    """The hold segments of a :class:`~gatetwin.records.Record` as an ``(n, 2)`` array."""
    return as_segments([(h.start, h.stop) for h in record.holds], record.n_samples)


def reconstructed_opening(
    time_s: np.ndarray, opening_mm: np.ndarray, hold: np.ndarray
) -> np.ndarray:
    """Gate opening with the actuator-motion samples filled in.

    The opening is taken as logged on ``hold`` samples. On every other sample (``open``:
    the actuator is moving and the logged value, if any, is not trusted) and on hold
    samples whose opening is missing, it is linearly interpolated *in time* between the
    last hold opening before and the first hold opening after, i.e. the actuator is
    modelled as moving at constant speed between two hold positions. Before the first
    and after the last hold opening the nearest hold opening is held.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s, increasing.
    opening_mm : ndarray
        Logged gate opening, mm (NaN where missing).
    hold : ndarray of bool
        True where the actuator is still.

    Returns
    -------
    ndarray
        Opening, mm, finite everywhere.

    Raises
    ------
    IdentificationError
        If no hold sample carries an opening.
    """
    t = np.asarray(time_s, dtype=float)
    e = np.asarray(opening_mm, dtype=float)
    knots = np.asarray(hold, dtype=bool) & np.isfinite(e)
    if not np.any(knots):
        raise IdentificationError("no hold sample carries a gate opening")
    return np.interp(t, t[knots], e[knots])


@dataclass(frozen=True)
class SpikeCorrection:
    """Result of :func:`hampel_filter`.

    Attributes
    ----------
    values : ndarray
        The corrected series (same unit as the input); samples outside the segments and
        NaN samples are passed through unchanged.
    replaced_index : ndarray of int
        Indices of the samples that were replaced by their window median.
    """

    values: np.ndarray
    replaced_index: np.ndarray

    @property
    def n_replaced(self) -> int:
        return int(self.replaced_index.size)


def hampel_filter(
    values: np.ndarray,
    segments: Segments,
    *,
    half_window: int = 3,
    n_sigma: float = 4.0,
    floor: float = 0.0,
) -> SpikeCorrection:
    """Replace spikes by the local median, inside each segment separately.

    For every finite sample ``x`` in a segment, the window is the samples at most
    ``half_window`` away *in the same segment* that are finite (the window is truncated at
    segment edges, never reaching into a neighbouring segment). With ``m`` the window
    median and ``MAD`` the window's median absolute deviation from ``m``, ``x`` is a spike
    when ``|x - m| > max(n_sigma * 1.4826 * MAD, floor)`` and is replaced by ``m``.

    Parameters
    ----------
    values : ndarray
        Series to clean (e.g. level in mm); NaN allowed and left alone.
    segments : sequence of (int, int) or ndarray
        Segments, ``stop`` exclusive.
    half_window : int, optional
        Window half width, samples (default 3, i.e. 7-sample windows).
    n_sigma : float, optional
        Threshold in robust standard deviations (default 4).
    floor : float, optional
        Smallest deviation that can count as a spike, in the unit of ``values``
        (default 0; set it to a few sensor resolution steps for quantized data whose
        windows often have ``MAD = 0``).

    Returns
    -------
    SpikeCorrection
        Corrected copy and the indices replaced.
    """
    x = np.asarray(values, dtype=float)
    n = x.size
    seg = as_segments(segments, n)
    label = np.full(n + 2 * half_window, -1, dtype=np.int64)
    inside = segment_mask(seg, n)
    starts = np.zeros(n, dtype=np.int64)
    starts[seg[:, 0]] = 1
    label[half_window : half_window + n][inside] = np.cumsum(starts)[inside] - 1
    padded = np.concatenate((np.full(half_window, np.nan), x, np.full(half_window, np.nan)))
    centre = np.flatnonzero(inside & np.isfinite(x))
    out = x.copy()
    if centre.size == 0:
        return SpikeCorrection(out, np.zeros(0, dtype=np.int64))
    win = sliding_window_view(padded, 2 * half_window + 1)[centre].copy()
    lab = sliding_window_view(label, 2 * half_window + 1)[centre]
    win[lab != label[centre + half_window][:, None]] = np.nan
    med = np.nanmedian(win, axis=1)
    mad = np.nanmedian(np.abs(win - med[:, None]), axis=1)
    spike = np.abs(x[centre] - med) > np.maximum(n_sigma * MAD_TO_SD * mad, floor)
    idx = centre[spike]
    out[idx] = med[spike]
    return SpikeCorrection(out, idx)


def holdout_split(
    segments: Segments,
    n_samples: int,
    *,
    fraction: float = 0.3,
    time_s: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Split segments into an estimation part and a hold-out (validation) part.

    The hold-out part is the last ``fraction`` of the record *by time* (by sample index
    when ``time_s`` is not given). A segment that straddles the split time is cut there.

    Parameters
    ----------
    segments : sequence of (int, int) or ndarray
        Segments, ``stop`` exclusive.
    n_samples : int
        Record length.
    fraction : float, optional
        Hold-out share of the record duration, in (0, 1) (default 0.3).
    time_s : ndarray, optional
        Sample times, s.

    Returns
    -------
    estimation, validation : ndarray of shape (n, 2)

    Raises
    ------
    IdentificationError
        If ``fraction`` is outside (0, 1) or either part ends up without samples.
    """
    if not 0.0 < fraction < 1.0:
        raise IdentificationError(f"hold-out fraction must be in (0, 1), got {fraction}")
    seg = as_segments(segments, n_samples)
    t = np.arange(n_samples, dtype=float) if time_s is None else np.asarray(time_s, float)
    t_split = t[0] + (1.0 - fraction) * (t[-1] - t[0])
    k = int(np.searchsorted(t, t_split, side="left"))
    est = np.column_stack((seg[:, 0], np.minimum(seg[:, 1], k)))
    val = np.column_stack((np.maximum(seg[:, 0], k), seg[:, 1]))
    est = est[est[:, 1] > est[:, 0]]
    val = val[val[:, 1] > val[:, 0]]
    if est.size == 0 or val.size == 0:
        raise IdentificationError("hold-out split leaves no segment in one of the two parts")
    return est, val
