"""The twin beside the gate: the MPC's disturbance observer run online on measured data.

:class:`OnlineObserver` feeds the measured level, opening and discharge of every sample to
:class:`~gatetwin.mpc.observer.DisturbanceObserver` on the scheduled FOPDT (no effect
blocks; the envelope, if any, is not used: the schedule's ``K``, ``T``, ``L`` are) and
reports per sample (:class:`OnlineEstimate`): the filtered level, the estimated input
disturbance, the innovation and the innovation over its predicted standard deviation, the
level predicted ``horizon_s`` ahead with the inputs held, and an anomaly flag.

The anomaly flag (:class:`AnomalySettings`, :func:`monitor_sample`) has two rules on the
innovation, both read against its own recent scale (``innovation_scale``: the RMS of the
normalised innovation over the last ``scale_window_samples``, never below 1), so that a
record the linear schedule fits loosely (wide moves, discharge changes) does not raise it
by its ordinary mismatch:

* **fast** (``anomaly_kind = 1``): the normalised innovation has stayed outside
  ``±band_sigma`` scales for ``run_samples`` consecutive samples. A fault that moves the level
  faster than the filter expects (a stuck or slowed gate on a large move, a lagging gauge on
  a fast move) does it before the disturbance has absorbed it;
* **persistent** (``anomaly_kind = 2``): a two-sided CUSUM of the innovation has passed
  ``cusum_threshold``. Its increments are the innovation over its predicted SD widened by
  ``move_uncertainty`` times the move the model predicted over the sample (the gain and lag
  of a linear schedule are a few tens of per cent off on wide moves; on a hold the widening
  vanishes), over the scale, less ``cusum_slack_sigma``. An unseen inflow or a level that
  goes on moving where the model says it holds pushes the innovation one way for tens of
  samples, each of them inside the band.

A slow sensor drift is absorbed into ``disturbance_mm`` almost entirely (the random-walk
disturbance follows a ramp of 0.01 mm/s with an innovation bias of about 0.01 SD): no rule on
the innovation sees it, and the flume's own model mismatch moves ``disturbance_mm`` more
than such a drift does within a record.

**Envelope observer.** A plant that holds across the gate's range (a ``physical`` plant, or
an envelope FOPDT with ``linearisation="envelope"``) is re-linearised at every sample around
the measured discharge and the opening applied over the next sample
(:func:`gatetwin.mpc.envelope.linearised_model`, as the envelope MPC does), the disturbance
rescaled to keep its level effect when the tangent's gain changes. Its mismatch on the
flume's wide-range records is a few mm instead of tens, which allows a third rule:

* **slow** (``anomaly_kind = 3``): a second filter on the same models with a disturbance
  that barely moves (:data:`SLOW_MONITORING`) and the persistent rule's CUSUM on its
  innovation, slack ``slow_slack_sigma``, threshold ``slow_threshold``. An unseen inflow
  leaves this filter's innovation biased for minutes where the monitoring filter has
  absorbed it into ``disturbance_mm`` within one.

Both renderings have a C FMU (:mod:`gatetwin.fmu.observer_fmu`, ``gatetwin export-observer``)
that equals this class to round-off.

The per-sample arithmetic (:func:`monitor_sample`, :func:`slow_sample`,
:func:`with_slow_rule`, :func:`forecast_level`, and the envelope's tangent,
:func:`gatetwin.mpc.envelope.tangent_model`) runs on numbers and on casadi symbols alike;
:mod:`gatetwin.mpc.observer_codegen` builds the observer FMUs' C from it. This module does
not identify, control or diagnose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from gatetwin.errors import ControlError
from gatetwin.mpc.discrete import DELAY_SPLIT_RTOL, SAMPLE_PERIOD_S, discretise
from gatetwin.mpc.envelope import has_envelope, linearised_model
from gatetwin.mpc.observer import DisturbanceObserver
from gatetwin.mpc.online_rules import (
    MONITOR,
    SCALE_CLIP_SIGMA,
    advance,
    correct_sample,
    forecast_level,
    innovation_variance,
    monitor_sample,
    slow_sample,
    start_monitor,
    with_slow_rule,
)
from gatetwin.mpc.settings import ObserverSettings
from gatetwin.mpc.statespace import DiscreteModel
from gatetwin.plant.model import FLOW_RANGE_M3H, FopdtPlant, PhysicalPlant

#: Default forecast horizon, s: about one time constant of the flume's pools (40-75 s).
DEFAULT_HORIZON_S = 60.0
#: Longest forecast horizon, s (one hour of samples, each a step of the model).
MAX_HORIZON_S = 3600.0
#: Default band of the scaled normalised innovation: 3.5 σ (4.7e-4 of white Gaussian
#: innovations). At 3 σ the flume's wide-range records (Eboth, Erandom60) hold runs of 5
#: samples outside the band by the linear schedule's mismatch alone; at 3.5 σ of the scale none
#: is longer than 2.
ANOMALY_BAND_SIGMA = 3.5
#: Default run length: 4 samples (4.8 s at 1.2 s). Longer than a logger spike; shorter than
#: half the period of the flume's seiche (11.5 s / 2 = 4.8 samples), so an oscillation beyond
#: the band can raise the flag between its zero crossings; four white exceedances in a row
#: have probability (4.7e-4)⁴ ≈ 5e-14 per sample.
ANOMALY_RUN_SAMPLES = 4
#: Default slack of the CUSUM: 1 SD. The CUSUM looks for a bias of about twice the slack (2 SD
#: held for several samples, what 5 m³/h of unseen inflow leaves in the first minute on a
#: record the model explains); white innovations drift it down by 1 per sample.
CUSUM_SLACK_SIGMA = 1.0
#: Default CUSUM threshold: 12. The largest CUSUM over the fifteen clean bundled records
#: (5.2 h) is 10.1 (Eboth, where the discharge steps across the schedule); 12 keeps a fifth
#: above it (``benchmarks/bench_observer.py`` prints both). For white unit innovations
#: Siegmund's approximation gives an in-control run length of exp(2 (12 + 1.166)) / 2 ≈ 1e11
#: samples per side, no false alarm in any record's lifetime: the threshold is set by the
#: model mismatch of real records, not by noise.
CUSUM_THRESHOLD = 12.0
#: Relative uncertainty of the model's predicted move over one sample: 0.5. The schedule's gain
#: and time constant are off by up to a few tens of per cent on moves across the envelope
#: (fopdt_3F's fit records vs Emoves75/Erandom60); half the predicted move widens the CUSUM's
#: innovation SD at moves, where mismatch shows, and not on holds, where inflow and drift do.
MOVE_UNCERTAINTY = 0.5
#: Window of the innovation's scale: 250 samples (300 s, five time constants of the pools). Long
#: enough that a fault of a minute or two does not hide itself in the scale; short enough to
#: follow the mismatch of the record's operating range.
SCALE_WINDOW_SAMPLES = 250
#: The observer's noise levels for monitoring (the MPC's, :class:`ObserverSettings`' defaults,
#: track faster). ``measurement_sd_mm = 1.0`` makes the normalised innovation of unit standard
#: deviation on the step records the bundled models are identified from (0.91-1.06 on
#: Q40-Q85 with fopdt_3F); level and disturbance noise at half and a third of the MPC's, so a
#: fault shows in the innovation for several samples before the disturbance takes it up (the
#: MPC's tuning takes a fault into the disturbance so fast that its innovation rarely leaves
#: the band).
MONITORING = ObserverSettings(measurement_sd_mm=1.0, level_sd_mm=0.5, disturbance_sd_mm=0.1)
#: The slow rule's filter (envelope observer only): the disturbance's random walk at 2 µm of
#: opening per sample (about 0.02-0.06 mm of level on the flume's gains) and the level's at
#: 0.1 mm, so that what the envelope model does not explain stays in the innovation for
#: minutes instead of entering ``disturbance_mm`` within one.
SLOW_MONITORING = ObserverSettings(measurement_sd_mm=1.0, level_sd_mm=0.1,
                                   disturbance_sd_mm=0.002)  # fmt: skip
#: Default slack of the slow rule's CUSUM: 0.5 SD (a bias of 1 SD in the slow filter's
#: innovation, what 5 m³/h of unseen inflow leaves there for minutes, gains 0.5 per sample).
SLOW_CUSUM_SLACK_SIGMA = 0.5
#: Default threshold of the slow rule's CUSUM: 75. Calibrated on 3.6 h of clean records of the
#: virtual flume that are not bundled (``benchmarks/calibrate_observer.py``: the largest value
#: over them is 59.4, on discharge steps with the gate fixed; 75 is a quarter above); the
#: bundled clean records are then the independent check of false alarms
#: (``benchmarks/bench_observer.py``). The envelope's own mismatch, not noise, sets it (white
#: unit innovations would take it past 15 about once in 1e5 samples).
SLOW_CUSUM_THRESHOLD = 75.0
#: Run length of the envelope observer's fast rule: 9 samples. On the calibration records a
#: move of 38 mm at 65 m³/h (150 mm of level) holds runs of 7 outside the band: the tangent at
#: the new opening gives the right end but not the path of so large a fall; 9 is a quarter
#: above 7.
ENVELOPE_RUN_SAMPLES = 9
#: The envelope observer's move uncertainty: 2 (the predicted move's path on wide moves, see
#: :data:`ENVELOPE_RUN_SAMPLES`, is off by up to about twice the move over a sample; at 0.5
#: the persistent CUSUM reached 38.6 on the calibration records, at 2 it stays below 8.2).
ENVELOPE_MOVE_UNCERTAINTY = 2.0
#: How the observer renders the plant: ``auto`` (the envelope for a physical plant, the
#: schedule for an FOPDT), ``envelope`` (re-linearised at every sample), ``schedule``.
LINEARISATIONS = ("auto", "envelope", "schedule")


@dataclass(frozen=True)
class AnomalySettings:
    """When the observer calls the innovations an anomaly (see the module).

    Attributes
    ----------
    band_sigma : float
        Band of the normalised innovation (> 0), in its standard deviations times its scale.
    run_samples : int
        Consecutive samples outside the band that raise the flag (>= 1).
    cusum_slack_sigma : float
        Slack of the two-sided CUSUM (>= 0), standard deviations per sample.
    cusum_threshold : float
        CUSUM value that raises the flag (> 0).
    move_uncertainty : float
        Relative uncertainty of the move the model predicts over a sample (>= 0).
    scale_window_samples : int
        Window of the innovation's scale, samples (>= 1).
    slow_slack_sigma : float
        Slack of the slow rule's CUSUM (>= 0), SD per sample (envelope observer only).
    slow_threshold : float
        CUSUM value of the slow rule that raises the flag (> 0; envelope observer only).
    """

    band_sigma: float = ANOMALY_BAND_SIGMA
    run_samples: int = ANOMALY_RUN_SAMPLES
    cusum_slack_sigma: float = CUSUM_SLACK_SIGMA
    cusum_threshold: float = CUSUM_THRESHOLD
    move_uncertainty: float = MOVE_UNCERTAINTY
    scale_window_samples: int = SCALE_WINDOW_SAMPLES
    slow_slack_sigma: float = SLOW_CUSUM_SLACK_SIGMA
    slow_threshold: float = SLOW_CUSUM_THRESHOLD

    def __post_init__(self) -> None:
        if not (isinstance(self.band_sigma, (int, float)) and 0 < self.band_sigma < math.inf):
            raise ControlError(f"anomaly band_sigma must be finite and > 0 (got "
                               f"{self.band_sigma!r})")  # fmt: skip
        for name in ("run_samples", "scale_window_samples"):
            value = getattr(self, name)
            if not (isinstance(value, int) and 1 <= value <= 1_000_000):
                raise ControlError(f"anomaly {name} must be an integer in [1, 1000000] (got "
                                   f"{value!r})")  # fmt: skip
        for name, low in (("cusum_slack_sigma", 0.0), ("move_uncertainty", 0.0),
                          ("slow_slack_sigma", 0.0)):  # fmt: skip
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and low <= value < math.inf):
                raise ControlError(f"anomaly {name} must be finite and >= {low:g} (got "
                                   f"{value!r})")  # fmt: skip
        for name in ("cusum_threshold", "slow_threshold"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value < math.inf):
                raise ControlError(f"anomaly {name} must be finite and > 0 (got {value!r})")

    def limits(self) -> tuple[float, float, float, float]:
        """``(band_sigma, run_samples, cusum_slack_sigma, cusum_threshold)``: the settings the
        observer FMU takes as parameters (the others are built into its code)."""
        return (float(self.band_sigma), float(self.run_samples),
                float(self.cusum_slack_sigma), float(self.cusum_threshold))  # fmt: skip

    def slow_limits(self) -> tuple[float, float, float, float]:
        """The slow rule's limits in :func:`monitor_sample`'s order: its band never flags."""
        return (math.inf, 1.0, float(self.slow_slack_sigma), float(self.slow_threshold))


#: The envelope observer's anomaly settings (see :data:`ENVELOPE_RUN_SAMPLES`,
#: :data:`ENVELOPE_MOVE_UNCERTAINTY`); band and persistent CUSUM as the FMU's.
ENVELOPE_ANOMALY = AnomalySettings(run_samples=ENVELOPE_RUN_SAMPLES,
                                   move_uncertainty=ENVELOPE_MOVE_UNCERTAINTY)  # fmt: skip


@dataclass(frozen=True)
class OnlineEstimate:
    """What the observer says after one sample (the observer FMU's outputs, same names).

    Attributes
    ----------
    filtered_level_mm : float
        Estimate of the level now, mm.
    disturbance_mm : float
        Estimated input disturbance, mm of opening.
    innovation_mm : float
        Measured minus predicted level, mm (0 at the start).
    innovation_normalised : float
        The innovation over its predicted standard deviation.
    predicted_level_mm : float
        Level predicted ``horizon_s`` ahead with opening, discharge and disturbance held, mm.
    anomaly : float
        1 while either rule holds (``anomaly_kind`` > 0), else 0.
    anomaly_samples : float
        The present run of samples outside the band.
    anomaly_kind : float
        0 none; 1 fast (the run of samples outside the band); 2 persistent (the CUSUM);
        3 slow (the envelope observer's slow filter).
    cusum_high : float
        The CUSUM of a level above what the model predicts.
    cusum_low : float
        The CUSUM of a level below what the model predicts.
    innovation_scale : float
        The scale the normalised innovation was read against at this sample (>= 1).
    """

    filtered_level_mm: float
    disturbance_mm: float
    innovation_mm: float
    innovation_normalised: float
    predicted_level_mm: float
    anomaly: float
    anomaly_samples: float
    anomaly_kind: float
    cusum_high: float
    cusum_low: float
    innovation_scale: float

    def values(self) -> tuple[float, ...]:
        return tuple(getattr(self, f.name) for f in fields(self))


#: Output names, in :class:`OnlineEstimate`'s order.
OUTPUTS = tuple(f.name for f in fields(OnlineEstimate))


def default_horizon_s(sample_period_s: float) -> float:
    """The default forecast horizon at ``sample_period_s``, s: :data:`DEFAULT_HORIZON_S` where
    it is a whole number of samples, else the nearest whole number of them (halves up; at
    least one). The observer's other windows (:data:`SCALE_WINDOW_SAMPLES`, the run of the
    fast rule, the gauge-drift window) count samples whatever the period."""
    try:
        forecast_samples(DEFAULT_HORIZON_S, sample_period_s)
        return DEFAULT_HORIZON_S
    except ControlError:
        samples = max(1, math.floor(DEFAULT_HORIZON_S / sample_period_s + 0.5))
        return samples * float(sample_period_s)


def forecast_samples(horizon_s: float, sample_period_s: float) -> int:
    """``horizon_s`` in samples; refused unless a whole multiple in ``[0, MAX_HORIZON_S]``."""
    if not (isinstance(horizon_s, (int, float)) and 0.0 <= horizon_s <= MAX_HORIZON_S):
        raise ControlError(f"forecast horizon {horizon_s!r} s must lie in [0, {MAX_HORIZON_S:g}] s")
    n = round(horizon_s / sample_period_s)
    if abs(n * sample_period_s - horizon_s) > DELAY_SPLIT_RTOL * max(1.0, horizon_s):
        raise ControlError(f"forecast horizon {horizon_s:g} s must be a whole multiple of the "
                           f"sample period {sample_period_s:g} s")  # fmt: skip
    return int(n)


def checked_plant(
    plant: Any, who: str = "online observer", *, envelope: bool = False
) -> FopdtPlant | PhysicalPlant:
    """``plant`` if the observer covers it: a scheduled FOPDT without effect blocks or, with
    ``envelope``, an envelope FOPDT or a physical plant without them."""
    if envelope:
        if not (isinstance(plant, (FopdtPlant, PhysicalPlant)) and has_envelope(plant)):
            kind = getattr(plant, "kind", type(plant).__name__)
            raise ControlError(f"{who}: the envelope observer needs an envelope FOPDT or a "
                               f"physical plant (got {kind} without an envelope)")  # fmt: skip
    elif not isinstance(plant, FopdtPlant):
        kind = getattr(plant, "kind", type(plant).__name__)
        hint = ("; observe a physical plant with the envelope observer (linearisation "
                "envelope or auto)" if isinstance(plant, PhysicalPlant) else "")  # fmt: skip
        raise ControlError(f"{who}: needs a scheduled FOPDT plant (got {kind}){hint}")
    if plant.effects:
        kinds = ", ".join(e["kind"] for e in plant.effects)
        raise ControlError(f"{who}: effect blocks are not covered (plant has {kinds}); observe "
                           "with the plant without them (without_effects, "
                           "gatetwin export-observer --without-effects)")  # fmt: skip
    return plant


def observer_linearisation(plant: Any, linearisation: str = "auto", who: str = "online observer"
                           ) -> str:  # fmt: skip
    """The rendering ``linearisation`` names for ``plant``: ``auto`` is ``envelope`` for a
    physical plant and ``schedule`` otherwise (the one rule :class:`OnlineObserver`, the
    observer FMU and the observer-on-a-record SSP follow); :class:`ControlError` for a name
    not in :data:`LINEARISATIONS`."""
    if linearisation not in LINEARISATIONS:
        raise ControlError(f"{who}: linearisation {linearisation!r} is not one of "
                           f"{', '.join(LINEARISATIONS)}")  # fmt: skip
    if linearisation == "auto":
        return "envelope" if isinstance(plant, PhysicalPlant) else "schedule"
    return linearisation


@dataclass
class OnlineObserver:
    """The observer on measured data, one sample at a time (the observer FMU in Python).

    Parameters
    ----------
    plant : FopdtPlant or PhysicalPlant
        Without effect blocks (see :func:`checked_plant`).
    horizon_s : float, optional
        Forecast horizon of ``predicted_level_mm``, s: a whole multiple of the sample period
        (default :func:`default_horizon_s`).
    settings : ObserverSettings
        Noise levels of the Kalman filter (:data:`MONITORING` by default).
    anomaly : AnomalySettings or None
        Band and run length of the anomaly flag; ``None``: :class:`AnomalySettings`' defaults
        (:data:`ENVELOPE_ANOMALY` for the envelope observer).
    sample_period_s : float
        The observer's sample period, s.
    linearisation : str
        One of :data:`LINEARISATIONS`; ``auto`` takes the envelope for a physical plant.
    slow_settings : ObserverSettings
        Noise levels of the slow rule's filter (envelope observer only).

    Examples
    --------
    >>> from gatetwin.plant.model import FopdtPlant, Schedule
    >>> plant = FopdtPlant("3F", 25.0, Schedule((55.0,), {
    ...     "gain_mm_per_mm": (-12.0,), "time_constant_s": (55.0,), "dead_time_s": (0.0,),
    ...     "level_ref_mm": (300.0,)}))
    >>> obs = OnlineObserver(plant, horizon_s=60.0)
    >>> rest = obs.reset(opening_mm=25.0, level_mm=300.0, flow_m3h=55.0)
    >>> round(rest.predicted_level_mm, 6)
    300.0
    >>> now = obs.step(level_mm=300.0, opening_mm=30.0, flow_m3h=55.0)  # gate opened 5 mm
    >>> now.anomaly, round(now.predicted_level_mm - now.filtered_level_mm, 1)  # K·5·(1−e^-60/55)
    (0.0, -39.8)
    """

    plant: FopdtPlant
    horizon_s: float | None = None
    settings: ObserverSettings = MONITORING
    anomaly: AnomalySettings | None = None
    sample_period_s: float = SAMPLE_PERIOD_S
    linearisation: str = "auto"
    slow_settings: ObserverSettings = SLOW_MONITORING

    def __post_init__(self) -> None:
        self.linearisation = observer_linearisation(self.plant, self.linearisation)
        self.envelope = self.linearisation == "envelope"
        if self.anomaly is None:
            self.anomaly = ENVELOPE_ANOMALY if self.envelope else AnomalySettings()
        self.plant = checked_plant(self.plant, envelope=self.envelope)
        if not (isinstance(self.sample_period_s, (int, float)) and self.sample_period_s > 0
                and math.isfinite(self.sample_period_s)):  # fmt: skip
            raise ControlError(f"sample period {self.sample_period_s!r} s must be finite, > 0")
        if self.horizon_s is None:
            self.horizon_s = default_horizon_s(self.sample_period_s)
        self.samples_ahead = forecast_samples(self.horizon_s, self.sample_period_s)
        self.observer = DisturbanceObserver(self.settings)
        #: The slow rule's filter (envelope observer only).
        self.slow_observer = DisturbanceObserver(self.slow_settings)
        self._model: DiscreteModel | None = None
        self._monitor: tuple[float, ...] = ()
        self._slow: tuple[float, ...] = ()
        #: The slow rule's CUSUM after the last sample, ``max(high, low)`` (0 when off).
        self.slow_cusum = 0.0

    def model_at(self, flow_m3h: float, opening_mm: float = math.nan) -> DiscreteModel:
        """The plant's discrete model at ``flow_m3h`` (the envelope observer's: the tangent at
        ``flow_m3h`` and ``opening_mm``)."""
        if self.envelope:
            return linearised_model(self.plant, flow_m3h, opening_mm, self.sample_period_s)
        return discretise(self.plant, flow_m3h, self.sample_period_s)

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> OnlineEstimate:
        """At rest: ``opening_mm`` held, ``level_mm`` measured at ``flow_m3h``."""
        _check_inputs(level_mm, opening_mm, flow_m3h)
        model = self.model_at(flow_m3h, opening_mm)
        self.observer.reset(model, opening_mm, level_mm)
        obs = self.observer
        filtered = model.level_mm(obs.state)
        self._model, self._monitor = model, start_monitor(filtered)
        if self.envelope:
            self.slow_observer.reset(model, opening_mm, level_mm)
            self._slow, self.slow_cusum = start_monitor(filtered), 0.0
        ahead = forecast_level(model, obs.state, obs.disturbance_mm, opening_mm,
                               self.samples_ahead)  # fmt: skip
        return OnlineEstimate(filtered, obs.disturbance_mm, 0.0, 0.0, ahead, 0.0, 0.0, 0.0, 0.0,
                              0.0, 1.0)  # fmt: skip

    def step(self, level_mm: float, opening_mm: float, flow_m3h: float) -> OnlineEstimate:
        """Take the sample measured now; ``opening_mm`` and ``flow_m3h`` hold over the next.

        The first call after construction starts at rest on this sample (:meth:`reset`).
        """
        if self._model is None:
            self.reset(opening_mm, level_mm, flow_m3h)
        _check_inputs(level_mm, opening_mm, flow_m3h)
        obs, model = self.observer, self.model_at(flow_m3h, opening_mm)
        estimate, self._monitor = monitor_sample(obs, self._model, level_mm, self._monitor,
                                                 self.anomaly.limits(), self.anomaly)  # fmt: skip
        filtered, d, innovation, normalised, run, flag, kind, high, low, scale = estimate
        if self.envelope:
            kind = self._slow_rule(model, level_mm, opening_mm, kind)
            flag = 1.0 if kind > 0.0 else 0.0
            obs.rescale_disturbance(self._model.dc_gain_mm_per_mm(), model.dc_gain_mm_per_mm())
            d = obs.disturbance_mm
        ahead = forecast_level(model, obs.state, d, opening_mm, self.samples_ahead)
        obs.predict(model, opening_mm)
        self._model = model
        return OnlineEstimate(filtered, d, innovation, normalised, ahead, flag, run, kind, high,
                              low, scale)  # fmt: skip

    def _slow_rule(
        self, model: DiscreteModel, level_mm: float, opening_mm: float, kind: float
    ) -> float:
        """Correct and predict the slow filter; ``kind``, or 3 when only the slow rule holds."""
        estimate, self._slow = slow_sample(self.slow_observer, self._model, model, level_mm,
                                           opening_mm, self._slow, self.anomaly)  # fmt: skip
        kind, self.slow_cusum = with_slow_rule(kind, estimate)
        return kind

    def run(
        self, level_mm: np.ndarray, opening_mm: np.ndarray, flow_m3h: np.ndarray
    ) -> dict[str, np.ndarray]:
        """:meth:`reset` at the first sample, then :meth:`step` on every sample; the
        estimates as arrays named as :data:`OUTPUTS` (the envelope observer adds
        ``slow_cusum``, :attr:`slow_cusum` after each sample)."""
        y, e, q = (np.asarray(v, dtype=float) for v in (level_mm, opening_mm, flow_m3h))
        if not (y.ndim == 1 and y.shape == e.shape == q.shape and y.size >= 1):
            raise ControlError("online observer: level, opening and flow must be 1-D arrays of "
                               "one length")  # fmt: skip
        self.reset(e[0], y[0], q[0])
        rows, slow = [], []
        for i in range(y.size):
            rows.append(self.step(y[i], e[i], q[i]).values())
            slow.append(self.slow_cusum)
        table = np.array(rows)
        out = {name: table[:, k] for k, name in enumerate(OUTPUTS)}
        if self.envelope:
            out["slow_cusum"] = np.array(slow)
        return out


def measured_inputs(record: Any, gauge: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A record's level at ``gauge``, opening and discharge, as the observer takes them.

    The logger leaves the opening empty while the gate moves; such a sample gets the opening
    of the next sample that has one (the command the gate is moving to, reached within the
    sample), and empty ones at the end the last known opening.
    """
    if gauge not in record.levels_mm:
        raise ControlError(f"{record.path or 'record'}: no level column for gauge {gauge}")
    opening = np.array(record.opening_mm, dtype=float)
    known = np.flatnonzero(np.isfinite(opening))
    if known.size == 0:
        raise ControlError(f"{record.path or 'record'}: no opening is logged")
    after = np.searchsorted(known, np.arange(opening.size))
    opening = opening[known[np.minimum(after, known.size - 1)]]
    return (np.array(record.levels_mm[gauge], dtype=float), opening,
            np.array(record.flow_m3h, dtype=float))  # fmt: skip


def _check_inputs(level_mm: float, opening_mm: float, flow_m3h: float) -> None:
    if not (math.isfinite(level_mm) and math.isfinite(opening_mm)):
        raise ControlError(f"online observer: level {level_mm} mm and opening {opening_mm} mm "
                           "must be finite")  # fmt: skip
    lo, hi = FLOW_RANGE_M3H
    if not lo <= flow_m3h <= hi:
        raise ControlError(f"online observer: flow_m3h = {flow_m3h} is outside [{lo:g}, {hi:g}]")


__all__ = [
    "ANOMALY_BAND_SIGMA",
    "ANOMALY_RUN_SAMPLES",
    "CUSUM_SLACK_SIGMA",
    "CUSUM_THRESHOLD",
    "DEFAULT_HORIZON_S",
    "default_horizon_s",
    "ENVELOPE_ANOMALY",
    "ENVELOPE_MOVE_UNCERTAINTY",
    "ENVELOPE_RUN_SAMPLES",
    "MAX_HORIZON_S",
    "MONITOR",
    "MONITORING",
    "LINEARISATIONS",
    "MOVE_UNCERTAINTY",
    "OUTPUTS",
    "SCALE_CLIP_SIGMA",
    "SCALE_WINDOW_SAMPLES",
    "SLOW_CUSUM_SLACK_SIGMA",
    "SLOW_CUSUM_THRESHOLD",
    "SLOW_MONITORING",
    "AnomalySettings",
    "OnlineEstimate",
    "OnlineObserver",
    "advance",
    "checked_plant",
    "correct_sample",
    "forecast_level",
    "forecast_samples",
    "innovation_variance",
    "measured_inputs",
    "observer_linearisation",
    "monitor_sample",
    "slow_sample",
    "start_monitor",
    "with_slow_rule",
]
