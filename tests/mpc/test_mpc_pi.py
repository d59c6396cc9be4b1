"""PI baseline: SIMC formulas against hand calculation, python-control margins, limits and
anti-windup."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gatetwin.mpc import (
    ControlError,
    PiController,
    PiSettings,
    loop_margins,
    simc_pi,
    simc_pi_for_plant,
)
from gatetwin.plant import FopdtPlant, Schedule


def test_simc_matches_hand_calculation():
    # K = -13.6 mm/mm, T = 62 s, L = 2 s, Ts = 1.2 s: theta = 2 + 0.6 = 2.6 s, tau_c = 2.6 s
    # Kc = 62 / (-13.6 * 5.2) = -0.876697 mm/mm; Ti = min(62, 4 * 5.2) = 20.8 s
    t = simc_pi(-13.6, 62.0, 2.0, sample_period_s=1.2)
    assert t.effective_delay_s == pytest.approx(2.6)
    assert t.closed_loop_time_constant_s == pytest.approx(2.6)
    assert t.gain_mm_per_mm == pytest.approx(-0.876697, abs=1e-6)
    assert t.integral_time_s == pytest.approx(20.8)
    # a slow loop (tau_c = 10 s, continuous): Kc = 40 / (-10.6 * 12.5) = -0.301887; Ti = T = 40 s
    slow = simc_pi(-10.6, 40.0, 2.5, closed_loop_time_constant_s=10.0, sample_period_s=0.0)
    assert slow.gain_mm_per_mm == pytest.approx(-0.301887, abs=1e-6)
    assert slow.integral_time_s == pytest.approx(40.0)


def test_simc_tunes_for_the_measurement_filter_by_the_half_rule():
    # K = -13.6, T = 62 s, L = 2 s, Ts = 1.2 s, Tf = 6 s: half of the smaller lag (Tf) goes to
    # the delay, half to T: theta = 2.6 + 3 = 5.6 s, T' = 65 s, tau_c = 5.6 s;
    # Kc = 65 / (-13.6 * 11.2) = -0.426733 mm/mm, Ti = min(65, 44.8) = 44.8 s
    t = simc_pi(-13.6, 62.0, 2.0, sample_period_s=1.2, filter_time_s=6.0)
    assert t.effective_delay_s == pytest.approx(5.6)
    assert t.gain_mm_per_mm == pytest.approx(-0.426733, abs=1e-6)
    assert t.integral_time_s == pytest.approx(44.8)
    assert t.filter_time_s == 6.0 and t.to_dict()["filter_time_s"] == 6.0
    # a filter slower than the plant is the larger lag: T' = 80 + 31 = 111 s, theta = 33.6 s
    slow = simc_pi(-13.6, 62.0, 2.0, sample_period_s=1.2, filter_time_s=80.0)
    assert slow.effective_delay_s == pytest.approx(33.6)
    assert slow.gain_mm_per_mm == pytest.approx(111.0 / (-13.6 * 67.2))
    # the margins see the filter as a lag of its own, and SIMC keeps them near its design
    # (tau_c = theta: GM ~ 3, PM ~ 47 degrees, Skogestad 2003) within the half rule's
    # approximation of the second lag
    margins = loop_margins(t)
    assert margins.gain_margin > 2.7 and 45.0 < margins.phase_margin_deg < 70.0
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ControlError):
            simc_pi(-13.6, 62.0, 2.0, filter_time_s=bad)
        with pytest.raises(ControlError):
            PiSettings(filter_time_s=bad)


def test_the_level_filter_passes_white_noise_as_a_first_order_filter_does():
    """Level = set-point + white noise N(0, 1) and a loop held open (no rate or range limit
    reached): the filtered level's SD is sqrt(a / (2 - a)) of the noise's, a = Ts / (Tf + Ts)
    (the backward-Euler filter's variance ratio). With Tf = 5 Ts, a = 1/6 and the filtered
    samples are AR(1) with rho = 5/6, so for their variance 40,000 samples are worth 40,000
    (1 - rho²) / (1 + rho²) = 7,213 independent ones: the SD's standard error is 1/sqrt(2 *
    7213) = 0.83 %; the tolerance is four of those."""
    ts, tf = 1.2, 6.0
    pi = PiController(simc_pi(-13.6, 62.0, 2.0, sample_period_s=ts, filter_time_s=tf),
                      PiSettings(opening_range_mm=(0.0, 1e9), opening_rate_mm_s=1e9,
                                 sample_period_s=ts, filter_time_s=tf))  # fmt: skip
    pi.reset(25.0, 185.0, 40.0)
    noise = np.random.default_rng(7).standard_normal(40_000)
    filtered = []
    for n in noise:
        pi.step(185.0 + n, 40.0, 185.0)
        filtered.append(pi.filtered_mm - 185.0)
    a = ts / (tf + ts)
    assert np.std(filtered[100:]) == pytest.approx(math.sqrt(a / (2 - a)), rel=4 * 0.0083)
    # and a step of the level reaches 1 - (1 - a)^k of it after k samples
    pi.reset(25.0, 185.0, 40.0)
    steps = []
    for _ in range(10):
        pi.step(186.0, 40.0, 185.0)
        steps.append(pi.filtered_mm - 185.0)
    assert steps == pytest.approx([1 - (1 - a) ** k for k in range(1, 11)], abs=1e-12)
    # a tuning made for another filter than the settings' is refused
    with pytest.raises(ControlError, match="level filter"):
        PiController(simc_pi(-13.6, 62.0, 2.0, filter_time_s=tf), PiSettings())


def test_simc_for_a_scheduled_plant_uses_the_operating_discharge():
    plant = FopdtPlant("3F", 25.0, Schedule((30.0, 50.0), {
        "gain_mm_per_mm": (-15.0, -11.0), "time_constant_s": (70.0, 50.0),
        "dead_time_s": (2.0, 3.0), "level_ref_mm": (120.0, 250.0)}))  # fmt: skip
    t = simc_pi_for_plant(plant, 40.0)  # K = -13, T = 60, L = 2.5 halfway
    assert (t.plant_gain_mm_per_mm, t.plant_time_constant_s, t.plant_dead_time_s) == (
        pytest.approx(-13.0), pytest.approx(60.0), pytest.approx(2.5))  # fmt: skip
    assert t.gain_mm_per_mm == pytest.approx(60.0 / (-13.0 * 2 * 3.1))
    assert t.flow_m3h == 40.0


def test_margins_are_positive_and_those_of_simc():
    margins = loop_margins(simc_pi(-13.6, 62.0, 2.0, sample_period_s=1.2))
    assert margins.gain_margin_db > 0 and margins.phase_margin_deg > 0
    # SIMC with tau_c = theta and Ti = 8 theta: GM ~ 3, PM ~ 47-52 degrees (Skogestad 2003)
    assert 2.7 < margins.gain_margin < 3.3
    assert 45.0 < margins.phase_margin_deg < 60.0
    assert margins.gain_crossover_rad_s < margins.phase_crossover_rad_s


def test_pi_respects_rate_and_range_and_does_not_wind_up():
    pi = PiController(simc_pi(-13.6, 62.0, 2.0), PiSettings(opening_range_mm=(5.0, 40.0)))
    pi.reset(25.0, 185.0, 40.0)
    openings = [pi.step(185.0 + 200.0, 40.0, 185.0) for _ in range(200)]  # far too high
    steps = np.abs(np.diff(np.concatenate([[25.0], openings])))
    assert np.max(steps) <= 0.6 * 1.2 + 1e-12
    assert max(openings) == 40.0
    # back-calculation holds the integral where Kc*Ts/Ti*e + Ts/Tt*(u - Kc*e - I) = 0, i.e.
    # I = u - Kc*e*(1 - Tt/Ti) with Tt = Ti/2 (a pure integral would have run to ~2000 mm)
    kc = pi.tuning.gain_mm_per_mm
    assert pi.integral_mm == pytest.approx(40.0 - kc * -200.0 * 0.5, abs=1e-6)
    back = pi.step(185.0 - 5.0, 40.0, 185.0)  # recovery starts at once
    assert back == pytest.approx(40.0 - 0.72)


def test_pi_refuses_bad_input():
    with pytest.raises(ControlError):
        simc_pi(0.0, 62.0, 2.0)
    with pytest.raises(ControlError):
        simc_pi(-13.6, math.nan, 2.0)
    with pytest.raises(ControlError):
        PiController(simc_pi(-13.6, 62.0, 2.0)).step(185.0, 40.0, 185.0)
