"""The online observer's per-sample arithmetic: the correction, the anomaly rules, the slow
filter's sample and the forecast (:mod:`gatetwin.mpc.online`'s :class:`~gatetwin.mpc.online.
OnlineObserver` runs them on numbers, :mod:`gatetwin.mpc.observer_codegen` on casadi symbols
to generate the observer FMUs' C). What each rule means is in :mod:`gatetwin.mpc.online`'s
docstring; this module holds no settings of its own but the scale's clip and does not run a
record.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from gatetwin.mpc import symbolic as sym
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.statespace import DiscreteModel

if TYPE_CHECKING:
    from gatetwin.mpc.online import AnomalySettings

#: A normalised innovation enters the scale clipped at 5 SD (a logger spike moves it by at
#: most 25 / 250 of a unit variance).
SCALE_CLIP_SIGMA = 5.0

#: What the anomaly rules carry from one sample to the next, in order: the run outside the
#: band, the two CUSUMs, the innovation's mean square over its window (the scale squared) and
#: the filtered level of the last sample, mm.
MONITOR = ("anomaly_samples", "cusum_high", "cusum_low", "scale_squared", "filtered_level_mm")


def innovation_variance(observer: DisturbanceObserver, model: DiscreteModel) -> Any:
    """Predicted variance of the next innovation, ``c P cᵀ + σ²``, mm²."""
    c = np.append(model.c, 0.0)
    return sym.scalar(c @ (observer.covariance @ c) + observer.settings.measurement_sd_mm**2)


def correct_sample(
    observer: DisturbanceObserver,
    model: DiscreteModel,
    level_mm: Any,
    previous_run: Any,
    band_sigma: Any,
    run_samples: Any,
) -> tuple[Any, ...]:
    """Correct ``observer`` with the level measured now; ``model`` is the last prediction's.

    The fast rule alone, on the unscaled normalised innovation (:func:`monitor_sample` is
    the observer's own, with the scale and the CUSUM). Returns ``(filtered_level_mm,
    disturbance_mm, innovation_mm, innovation_normalised, anomaly_samples, anomaly)``;
    numbers or casadi symbols.
    """
    variance = innovation_variance(observer, model)
    innovation = observer.correct(model, level_mm)
    normalised = innovation / sym.sqrt(variance)
    outside = sym.fabs(normalised) > band_sigma
    run = sym.where(outside, previous_run + 1.0, 0.0)
    anomaly = sym.where(run >= run_samples, 1.0, 0.0)
    filtered = model.level_mm(observer.state)
    return filtered, observer.disturbance_mm, innovation, normalised, run, anomaly


def start_monitor(filtered_level_mm: Any) -> tuple[Any, ...]:
    """The anomaly rules' state at rest (:data:`MONITOR`)."""
    return (0.0, 0.0, 0.0, 1.0, filtered_level_mm)


def monitor_sample(
    observer: DisturbanceObserver,
    model: DiscreteModel,
    level_mm: Any,
    monitor: tuple[Any, ...],
    limits: tuple[Any, ...],
    anomaly: AnomalySettings,
) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
    """Correct ``observer`` with the level measured now and apply the anomaly rules.

    ``model`` is the last prediction's; ``monitor`` the rules' state (:data:`MONITOR`);
    ``limits`` ``(band_sigma, run_samples, cusum_slack_sigma, cusum_threshold)`` (numbers or
    symbols: the FMU's parameters); ``anomaly`` gives ``move_uncertainty`` and
    ``scale_window_samples``. Returns the estimate ``(filtered_level_mm, disturbance_mm,
    innovation_mm, innovation_normalised, anomaly_samples, anomaly, anomaly_kind, cusum_high,
    cusum_low, innovation_scale)`` and the next ``monitor``; numbers or casadi symbols.
    """
    run, high, low, scale_sq, last_level = monitor
    band, n_run, slack, threshold = limits
    variance = innovation_variance(observer, model)
    move = model.level_mm(observer.state) - last_level
    innovation = observer.correct(model, level_mm)
    normalised = innovation / sym.sqrt(variance)
    scale = sym.sqrt(scale_sq)
    run = sym.where(sym.fabs(normalised) > band * scale, run + 1.0, 0.0)
    widened = innovation / sym.sqrt(variance + (anomaly.move_uncertainty * move) ** 2) / scale
    high = sym.fmax(0.0, high + widened - slack)
    low = sym.fmax(0.0, low - widened - slack)
    kind = sym.where(run >= n_run, 1.0, sym.where(sym.fmax(high, low) >= threshold, 2.0, 0.0))
    flag = sym.where(kind > 0.0, 1.0, 0.0)
    weight = 1.0 / anomaly.scale_window_samples
    clipped = sym.clip(normalised, -SCALE_CLIP_SIGMA, SCALE_CLIP_SIGMA)
    scale_sq = sym.fmax(1.0, (1.0 - weight) * scale_sq + weight * clipped * clipped)
    filtered = model.level_mm(observer.state)
    estimate = (filtered, observer.disturbance_mm, innovation, normalised, run, flag, kind,
                high, low, scale)  # fmt: skip
    return estimate, (run, high, low, scale_sq, filtered)


def slow_sample(
    slow: DisturbanceObserver,
    last: DiscreteModel,
    model: DiscreteModel,
    level_mm: Any,
    opening_mm: Any,
    monitor: tuple[Any, ...],
    anomaly: AnomalySettings,
) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
    """One sample of the envelope observer's slow filter: :func:`monitor_sample` with the slow
    limits on ``last`` (the last prediction's model), the disturbance rescaled to ``model``'s
    gain, the prediction with ``opening_mm`` on ``model``. Numbers or casadi symbols."""
    estimate, monitor = monitor_sample(slow, last, level_mm, monitor, anomaly.slow_limits(),
                                       anomaly)  # fmt: skip
    slow.rescale_disturbance(last.dc_gain_mm_per_mm(), model.dc_gain_mm_per_mm())
    slow.predict(model, opening_mm)
    return estimate, monitor


def with_slow_rule(kind: Any, slow_estimate: tuple[Any, ...]) -> tuple[Any, Any]:
    """The anomaly kind with the slow rule (3 when only it holds) and the slow CUSUM,
    ``max(high, low)`` of the slow filter's estimate (:func:`monitor_sample`'s)."""
    combined = sym.where(kind > 0.0, kind, sym.where(slow_estimate[6] == 0.0, kind, 3.0))
    return combined, sym.fmax(slow_estimate[7], slow_estimate[8])


def forecast_level(
    model: DiscreteModel, state: np.ndarray, disturbance_mm: Any, opening_mm: Any, samples: int
) -> Any:
    """Level ``samples`` samples ahead from ``state`` with the opening and ``d`` held, mm."""
    z = state
    for _ in range(samples):
        z = advance(model, z, disturbance_mm, opening_mm)
    return model.level_mm(z)


def advance(model: DiscreteModel, state: np.ndarray, disturbance_mm: Any, opening_mm: Any) -> Any:
    """One sample of the model with the opening and the disturbance held."""
    return model.step(state, opening_mm, disturbance_mm)


__all__ = [
    "MONITOR",
    "SCALE_CLIP_SIGMA",
    "advance",
    "correct_sample",
    "forecast_level",
    "innovation_variance",
    "monitor_sample",
    "slow_sample",
    "start_monitor",
    "with_slow_rule",
]
