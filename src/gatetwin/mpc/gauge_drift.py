"""A gauge's drift told by the pool's other gauges: the redundancy rule beside the observer.

Every gauge upstream of the gate reads the same pool. Their differences change with the
water surface's slope (discharge, opening) and the waves a move sets off, but not with what
changes the pool as a whole (an unseen inflow, a stuck gate, the model's own mismatch). A
gauge whose zero drifts makes its difference to the others' mean ramp at the drift's rate.
The model-based rules of :class:`gatetwin.mpc.online.OnlineObserver` cannot see a slow
drift: the envelope model's own steady-level error (tens of mm across the gate's range)
moves its disturbance estimate faster than a drift of 0.01 mm/s does
(``benchmarks/drift_detectability.py``).

:class:`GaugeDriftMonitor` fits a straight line to the difference over the last
:data:`WINDOW_SAMPLES` samples and raises its flag when the slope's size exceeds
:data:`THRESHOLD_MM_PER_S`. Both are set on clean virtual-flume records that are not
bundled (the calibration set of ``benchmarks/calibrate_observer.py``, seeds 901-909):

    PYTHONPATH=src python benchmarks/drift_detectability.py

printed a largest clean slope of 0.0041 mm/s over 480 s windows (0.0094 over 300 s, 0.0202
over 180 s); the threshold is 1.25 times it, as for the observer's other thresholds. For
white gauge noise of SD ``s`` the slope's own SD over ``N`` samples ``Ts`` apart is
``s / (Ts sqrt(N (N^2 - 1) / 12))``: 0.0005 mm/s for ``s`` = 1.5 mm and ``N`` = 400, so the
window is long enough for a 0.01 mm/s drift to stand ten SDs above noise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S

__all__ = [
    "DRIFT_KIND",
    "THRESHOLD_MM_PER_S",
    "WINDOW_SAMPLES",
    "GaugeDriftMonitor",
    "drift_sample",
    "gauge_difference",
    "slope_weights",
    "with_drift_rule",
    "with_gauge_rule",
]

#: Samples the slope is fitted over: 480 s of 1.2 s samples.
WINDOW_SAMPLES = 400
#: |slope| of the gauge's difference to the others' mean that raises the flag, mm/s: 1.25
#: times the largest the calibration records gave (0.0041 mm/s, see the module).
THRESHOLD_MM_PER_S = 0.0051


def gauge_difference(level_mm: np.ndarray, others_mm: Sequence[np.ndarray]) -> np.ndarray:
    """The observed gauge's level minus the mean of the other gauges' levels, per sample."""
    y = np.asarray(level_mm, dtype=float)
    if not others_mm:
        raise ControlError("gauge drift: at least one other gauge is needed")
    rest = np.asarray([np.asarray(o, dtype=float) for o in others_mm])
    if rest.shape[1:] != y.shape or y.ndim != 1:
        raise ControlError("gauge drift: the gauges' levels must be 1-D arrays of one length")
    return y - rest.mean(axis=0)


def slope_weights(window: int, sample_period_s: float) -> np.ndarray:
    """Weights whose dot product with ``window`` equally spaced values is their
    least-squares slope per second."""
    x = np.arange(window) * sample_period_s
    x -= x.mean()
    return x / (x @ x)


#: ``anomaly_kind`` where the redundancy rule alone holds (the observer's own rules give 1-3).
DRIFT_KIND = 4


def drift_sample(
    window: Sequence[Any],
    count: Any,
    level_mm: Any,
    others_mm: Sequence[Any],
    weights: Sequence[float],
    threshold_mm_per_s: Any,
) -> tuple[tuple[Any, ...], Any, Any, Any]:
    """One sample of the rule, on numbers or on symbols (:mod:`gatetwin.mpc.symbolic`; the
    observer FMUs' C is generated from this).

    ``window`` holds the last ``len(weights)`` differences of the level to the others' mean,
    oldest first, ``count`` how many samples it has seen (at most its length). Returns the
    window and count after the sample, the slope (mm/s; 0 until the window is full) and the
    flag (1.0 where the slope's size exceeds ``threshold_mm_per_s``, else 0.0).
    """
    n = len(weights)
    window = (*window[1:], level_mm - sum(others_mm) / len(others_mm))
    count = sym.where(count >= n, float(n), count + 1.0)
    fitted = sum(w * v for w, v in zip(weights, window, strict=True))
    slope = sym.where(count >= n, fitted, 0.0)
    return window, count, slope, sym.where(sym.fabs(slope) > threshold_mm_per_s, 1.0, 0.0)


def with_drift_rule(kind: Any, flag: Any) -> Any:
    """``anomaly_kind`` with the redundancy rule: :data:`DRIFT_KIND` where its ``flag`` alone
    holds, the observer's own kind otherwise (on numbers or symbols)."""
    return sym.where(kind > 0.0, kind, sym.where(flag > 0.0, float(DRIFT_KIND), 0.0))


@dataclass
class GaugeDriftMonitor:
    """The redundancy rule, one sample at a time (:meth:`step`) or over a record (:meth:`run`).

    Parameters
    ----------
    window_samples : int
        Samples the slope is fitted over (>= 3).
    threshold_mm_per_s : float
        |slope| that raises the flag (> 0).
    sample_period_s : float
        Spacing of the samples, s.
    """

    window_samples: int = WINDOW_SAMPLES
    threshold_mm_per_s: float = THRESHOLD_MM_PER_S
    sample_period_s: float = SAMPLE_PERIOD_S
    _window: tuple[float, ...] = field(default=(), init=False, repr=False)
    _count: float = field(default=0.0, init=False, repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.window_samples, int) and self.window_samples >= 3):
            raise ControlError(f"gauge drift: window_samples {self.window_samples!r} must be an "
                               "integer >= 3")  # fmt: skip
        if not self.threshold_mm_per_s > 0.0 or not self.sample_period_s > 0.0:
            raise ControlError("gauge drift: the threshold and the sample period must be > 0")
        self._weights = slope_weights(self.window_samples, self.sample_period_s)
        self._weights_list = [float(w) for w in self._weights]
        self._window = (0.0,) * self.window_samples

    def step(self, level_mm: float, others_mm: Sequence[float]) -> tuple[float, bool]:
        """The slope (mm/s; NaN until the window is full or while a level in it is missing)
        and the flag after the sample ``level_mm`` with the other gauges' ``others_mm``
        (:func:`drift_sample`)."""
        if not others_mm:
            raise ControlError("gauge drift: at least one other gauge is needed")
        others = [float(o) for o in others_mm]
        self._window, self._count, slope, flag = drift_sample(
            self._window, self._count, float(level_mm), others, self._weights_list,
            self.threshold_mm_per_s)  # fmt: skip
        if self._count < self.window_samples:
            return float("nan"), False
        return slope, flag > 0.5

    def run(self, level_mm: np.ndarray, others_mm: Sequence[np.ndarray]) -> dict[str, np.ndarray]:
        """``gauge_slope_mm_per_s`` and ``gauge_drift`` (1.0 flagged, 0.0 not) per sample of a
        record, as :meth:`step` gives them from a fresh monitor."""
        d = gauge_difference(level_mm, others_mm)
        slope = np.full(d.size, np.nan)
        if d.size >= self.window_samples:
            windows = np.lib.stride_tricks.sliding_window_view(d, self.window_samples)
            slope[self.window_samples - 1 :] = windows @ self._weights
        with np.errstate(invalid="ignore"):
            flag = (np.abs(slope) > self.threshold_mm_per_s).astype(float)
        return {"gauge_slope_mm_per_s": slope, "gauge_drift": flag}


def with_gauge_rule(
    estimate: dict[str, np.ndarray],
    level_mm: np.ndarray,
    others_mm: Sequence[np.ndarray],
    monitor: GaugeDriftMonitor | None = None,
) -> dict[str, np.ndarray]:
    """An observer's outputs over a record (:meth:`gatetwin.mpc.online.OnlineObserver.run`)
    with the redundancy rule added, as the observer FMU with reference gauges gives them:
    ``gauge_slope_mm_per_s`` and ``gauge_drift`` (:meth:`GaugeDriftMonitor.run`), and
    ``anomaly_kind`` and ``anomaly`` through :func:`with_drift_rule`."""
    rule = (monitor or GaugeDriftMonitor()).run(level_mm, others_mm)
    kind = [with_drift_rule(k, f) for k, f in zip(estimate["anomaly_kind"], rule["gauge_drift"],
                                                  strict=True)]  # fmt: skip
    out = {**estimate, **rule, "anomaly_kind": np.asarray(kind, dtype=float)}
    out["anomaly"] = (out["anomaly_kind"] > 0.0).astype(float)
    return out
