"""PI baseline: SIMC tuning from the FOPDT, loop margins, and a rate-limited PI controller.

SIMC (Skogestad 2003) for ``G(s) = K e^{−θs}/(T s + 1)``::

    Kc = T / (K (τc + θ)),        Ti = min(T, 4 (τc + θ)),

with ``τc = θ`` by default ("tight" control). For a sampled loop the zero-order hold adds
about half a sample of delay, so ``θ = L + Ts/2`` (Skogestad's rule for digital control).

**The measurement filter** (``PiSettings.filter_time_s``, off by default). A gauge reads
with noise, and the proportional term passes it to the gate: a pool sampled fast has
``|Kc K| = T / 2θ`` in the tens, and the gate chases every reading. The PI can read the
level through a first-order filter of time constant ``Tf``, which SIMC then treats as a
second lag of the plant (Skogestad's half rule: half of the smaller lag goes to the delay,
half to the larger one), so ``Kc`` and ``Ti`` come out for the filtered loop.

Gain and phase margins come from python-control on the continuous loop ``C(s) G(s)`` with
the filter's lag, where — for the margins only — the delay ``e^{−θs}`` is replaced by a Padé
approximation (:func:`control.pade`); the controller itself never uses it.

The controller is positional, with back-calculation anti-windup (the integral tracks
the opening actually commanded after the opening-range and rate limits, with tracking
time ``Tt``), and the same rate limit as the MPC. The arithmetic of one sample is
:func:`gatetwin.mpc.pi_law.pi_step`, from which the C controller FMU's is generated.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import control

from gatetwin.errors import ControlError
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.mpc.pi_law import pi_step
from gatetwin.plant.model import FopdtPlant


@dataclass(frozen=True)
class PiTuning:
    """SIMC PI tuning of one FOPDT operating point.

    Attributes
    ----------
    gain_mm_per_mm : float
        ``Kc``: opening change per mm of level error (``error = set-point − level``), mm/mm.
        Negative, as the plant gain is: opening the gate lowers the level.
    integral_time_s : float
        ``Ti``, s.
    closed_loop_time_constant_s : float
        ``τc`` used, s.
    effective_delay_s : float
        ``θ = L + Ts/2`` plus the delay share of the filter (half of the smaller of ``Tf``
        and ``T``), s.
    plant_gain_mm_per_mm, plant_time_constant_s, plant_dead_time_s : float
        The FOPDT ``K``, ``T``, ``L`` tuned for.
    flow_m3h : float
        Discharge at which ``K``, ``T``, ``L`` were evaluated (NaN if given directly), m³/h.
    filter_time_s : float
        ``Tf`` of the level's measurement filter, s (0: none).
    """

    gain_mm_per_mm: float
    integral_time_s: float
    closed_loop_time_constant_s: float
    effective_delay_s: float
    plant_gain_mm_per_mm: float
    plant_time_constant_s: float
    plant_dead_time_s: float
    flow_m3h: float = math.nan
    filter_time_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in out.items()
        }


def simc_pi(
    gain_mm_per_mm: float,
    time_constant_s: float,
    dead_time_s: float,
    *,
    closed_loop_time_constant_s: float | None = None,
    sample_period_s: float = SAMPLE_PERIOD_S,
    filter_time_s: float = 0.0,
) -> PiTuning:
    """SIMC PI settings for ``K e^{−Ls}/(T s + 1)`` sampled every ``sample_period_s``.

    Parameters
    ----------
    gain_mm_per_mm : float
        Plant gain ``K``, mm/mm (non-zero).
    time_constant_s, dead_time_s : float
        ``T > 0`` and ``L >= 0``, s.
    closed_loop_time_constant_s : float, optional
        ``τc``, s; default ``θ`` (SIMC's "tight control").
    sample_period_s : float
        ``Ts``, s; half of it is added to the delay for the zero-order hold (0 for a
        continuous controller).
    filter_time_s : float
        ``Tf`` of the level's measurement filter, s (0: none). SIMC tunes for the plant with
        the filter as its second lag.
    """
    if not (gain_mm_per_mm != 0 and math.isfinite(gain_mm_per_mm)):
        raise ControlError(f"simc: plant gain must be finite and non-zero (got {gain_mm_per_mm})")
    if not (time_constant_s > 0 and dead_time_s >= 0 and sample_period_s >= 0):
        raise ControlError("simc: need T > 0, L >= 0 and Ts >= 0")
    if not (filter_time_s >= 0 and math.isfinite(filter_time_s)):
        raise ControlError(f"simc: filter time constant must be finite and >= 0 "
                           f"(got {filter_time_s})")  # fmt: skip
    tau, theta = _half_rule(time_constant_s, dead_time_s + 0.5 * sample_period_s, filter_time_s)
    tau_c = theta if closed_loop_time_constant_s is None else float(closed_loop_time_constant_s)
    if not tau_c > 0 or tau_c + theta <= 0:
        raise ControlError(f"simc: closed-loop time constant must be > 0 (got {tau_c})")
    kc = tau / (gain_mm_per_mm * (tau_c + theta))
    ti = min(tau, 4.0 * (tau_c + theta))
    return PiTuning(kc, ti, tau_c, theta, gain_mm_per_mm, time_constant_s, dead_time_s,
                    filter_time_s=float(filter_time_s))  # fmt: skip


def _half_rule(time_constant_s: float, delay_s: float, filter_time_s: float
               ) -> tuple[float, float]:  # fmt: skip
    """``(T, θ)`` of the FOPDT that stands for the plant's lag, the filter's lag and the delay:
    half of the smaller lag goes to the larger, half to the delay (Skogestad's half rule)."""
    big, small = max(time_constant_s, filter_time_s), min(time_constant_s, filter_time_s)
    return big + 0.5 * small, delay_s + 0.5 * small


def simc_pi_for_plant(
    plant: FopdtPlant,
    flow_m3h: float,
    *,
    closed_loop_time_constant_s: float | None = None,
    sample_period_s: float = SAMPLE_PERIOD_S,
    filter_time_s: float = 0.0,
) -> PiTuning:
    """SIMC settings from the scheduled FOPDT evaluated at the operating discharge
    (``filter_time_s`` as in :func:`simc_pi`)."""
    if not isinstance(plant, FopdtPlant):
        raise ControlError(f"simc needs an FOPDT plant (got {type(plant).__name__})")
    s = plant.schedule
    tuning = simc_pi(
        s.at("gain_mm_per_mm", flow_m3h),
        s.at("time_constant_s", flow_m3h),
        s.at("dead_time_s", flow_m3h),
        closed_loop_time_constant_s=closed_loop_time_constant_s,
        sample_period_s=sample_period_s,
        filter_time_s=filter_time_s,
    )
    return PiTuning(**{**asdict(tuning), "flow_m3h": float(flow_m3h)})


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of ``C(s) G(s)`` (delay by Padé, for the margins only).

    Attributes
    ----------
    gain_margin : float
        Factor by which the loop gain may grow, dimensionless (``inf`` if unbounded).
    gain_margin_db : float
        The same in dB.
    phase_margin_deg : float
        Phase margin, degrees.
    phase_crossover_rad_s, gain_crossover_rad_s : float
        Frequencies where the phase is −180° and where ``|L| = 1``, rad/s.
    pade_order : int
        Order of the Padé approximation of ``e^{−θs}``.
    """

    gain_margin: float
    gain_margin_db: float
    phase_margin_deg: float
    phase_crossover_rad_s: float
    gain_crossover_rad_s: float
    pade_order: int

    def to_dict(self) -> dict[str, Any]:
        return {
            k: (v if not isinstance(v, float) or math.isfinite(v) else None)
            for k, v in asdict(self).items()
        }


def loop_margins(tuning: PiTuning, *, pade_order: int = 8) -> LoopMargins:
    """Gain and phase margins of the PI loop on the FOPDT with delay ``L + Ts/2`` and the
    measurement filter's lag."""
    kc, ti = tuning.gain_mm_per_mm, tuning.integral_time_s
    pi_tf = control.tf([kc * ti, kc], [ti, 0.0])
    lag = control.tf([tuning.plant_gain_mm_per_mm], [tuning.plant_time_constant_s, 1.0])
    filt = control.tf([1.0], [tuning.filter_time_s, 1.0])
    # the delay without the filter's share, which the filter's own lag stands for here
    share = _half_rule(tuning.plant_time_constant_s, 0.0, tuning.filter_time_s)[1]
    num, den = control.pade(tuning.effective_delay_s - share, pade_order)
    loop = pi_tf * lag * filt * control.tf(num, den)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(loop)
    gm_db = 20.0 * math.log10(gm) if gm > 0 and math.isfinite(gm) else math.inf
    return LoopMargins(float(gm), gm_db, float(pm), float(wpc), float(wgc), pade_order)


@dataclass(frozen=True)
class PiSettings:
    """Limits and anti-windup of the PI controller (the MPC's limits, for a fair match).

    Attributes
    ----------
    opening_range_mm : tuple[float, float]
        Allowed opening, mm.
    opening_rate_mm_s : float
        Largest gate speed, mm/s (0.6 mm/s, as the MPC).
    sample_period_s : float
        Control period, s.
    tracking_time_s : float or None
        Back-calculation time ``Tt``, s; default ``Ti / 2`` (between the sample period and
        ``Ti``, as Åström & Hägglund recommend).
    filter_time_s : float
        ``Tf`` of the level's measurement filter, s; 0 (default): none. The demo's SIMC
        tuning is made for it (:func:`gatetwin.mpc.demo.pi_controller`), and a
        :class:`PiController` refuses a tuning made for another.
    """

    opening_range_mm: tuple[float, float] = (5.0, 100.0)
    opening_rate_mm_s: float = 0.6
    sample_period_s: float = SAMPLE_PERIOD_S
    tracking_time_s: float | None = None
    filter_time_s: float = 0.0

    def __post_init__(self) -> None:
        lo, hi = self.opening_range_mm
        ok = 0 <= lo < hi and self.opening_rate_mm_s > 0 and self.sample_period_s > 0
        ok = ok and 0 <= self.filter_time_s < math.inf
        if not ok or (self.tracking_time_s is not None and not self.tracking_time_s > 0):
            raise ControlError("pi settings: invalid range, rate, period, tracking time or "
                               "filter time")  # fmt: skip


class PiController:
    """Positional PI on the level error with range and rate limits and anti-windup.

    Same step interface as :class:`~gatetwin.mpc.controller.MpcController`.
    """

    name = "pi"

    def __init__(self, tuning: PiTuning, settings: PiSettings | None = None) -> None:
        self.tuning = tuning
        self.settings = settings or PiSettings()
        if self.settings.filter_time_s != tuning.filter_time_s:
            raise ControlError(f"pi: the settings' level filter ({self.settings.filter_time_s} "
                               f"s) is not the one the tuning was made for "
                               f"({tuning.filter_time_s} s)")  # fmt: skip
        self.integral_mm = math.nan
        self.previous_opening_mm = math.nan
        self.filtered_mm = math.nan
        self.last_solve_s = 0.0

    def reset(self, opening_mm: float, level_mm: float, flow_m3h: float) -> None:
        """Start at rest at ``opening_mm`` (bumpless: the integral holds the opening, the
        filter the level)."""
        lo, hi = self.settings.opening_range_mm
        if not lo <= opening_mm <= hi:
            raise ControlError(f"pi: start opening {opening_mm} mm outside [{lo}, {hi}] mm")
        if not math.isfinite(level_mm):
            raise ControlError(f"pi: start level {level_mm} mm is not finite")
        self.integral_mm = float(opening_mm)
        self.previous_opening_mm = float(opening_mm)
        self.filtered_mm = float(level_mm)

    @property
    def tracking_time_s(self) -> float:
        """Back-calculation time ``Tt`` in force, s (the settings', default ``Ti / 2``)."""
        return self.settings.tracking_time_s or 0.5 * self.tuning.integral_time_s

    def step(self, level_mm: float, flow_m3h: float, setpoint_mm: float) -> float:
        """Opening (mm) to hold over the next sample (``flow_m3h`` is not used).

        The arithmetic is :func:`gatetwin.mpc.pi_law.pi_step`, the same the C controller FMU
        runs.
        """
        if math.isnan(self.integral_mm):
            raise ControlError("pi: call reset() before step()")
        s, t = self.settings, self.tuning
        lo, hi = s.opening_range_mm
        opening, self.integral_mm, self.filtered_mm = pi_step(
            float(level_mm), float(setpoint_mm), self.integral_mm, self.previous_opening_mm,
            self.filtered_mm, t.gain_mm_per_mm, t.integral_time_s, self.tracking_time_s,
            float(lo), float(hi), s.opening_rate_mm_s, s.sample_period_s, t.filter_time_s,
        )  # fmt: skip
        self.previous_opening_mm = opening
        return opening


__all__ = [
    "LoopMargins",
    "PiController",
    "PiSettings",
    "PiTuning",
    "loop_margins",
    "simc_pi",
    "simc_pi_for_plant",
]
