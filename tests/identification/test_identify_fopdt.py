"""Known-truth tests of the FOPDT step methods (gatetwin.identification.fopdt / .step)."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np
import pytest

from gatetwin.errors import IdentificationError
from gatetwin.identification.fopdt import FopdtFit, PaperStepResult, fit_fopdt, paper_step_method
from gatetwin.identification.step import StepIdentification, identify_step
from gatetwin.records import record_from_arrays

TS = 1.2


@dataclass(frozen=True)
class Step:
    """A synthetic step record of one gauge and its truth."""

    t: np.ndarray
    h: np.ndarray
    hold: np.ndarray
    opening: np.ndarray
    gain: float
    time_constant: float
    dead_time: float
    delta_e: float
    true_onset: float  # start of gate motion, between two samples
    logged_onset: float  # time of the first open sample (what a record reports)
    k_open: int
    n_open: int

    @property
    def n(self) -> int:
        return self.t.size


def make_step(
    seed: int,
    *,
    noise_sd: float | None = None,
    up: bool = True,
    log_motion: bool = False,
    gain: float | None = None,
    dead_time: float | None = None,
    time_constant: float | None = None,
) -> Step:
    """Sampled FOPDT step response, onset at a random phase between samples."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(-16, -8) if gain is None else gain
    tc = rng.uniform(30, 80) if time_constant is None else time_constant
    dead = rng.uniform(1, 10) if dead_time is None else dead_time
    sd = rng.uniform(0.1, 1.0) if noise_sd is None else noise_sd
    de = 5.0 if up else -5.0
    n_pre, n_open = 100, int(rng.integers(1, 4))
    n = n_pre + n_open + int(np.ceil(8 * tc / TS)) + 40
    t = 500.0 + TS * np.arange(n) + rng.uniform(0, TS)
    true_onset = t[n_pre] - rng.uniform(0.0, 1.0) * TS
    level = 230.0 + k * de * -np.expm1(-np.maximum(t - true_onset - dead, 0.0) / tc)
    level = level + rng.normal(0.0, sd, n) if sd > 0 else level
    hold = np.ones(n, dtype=bool)
    hold[n_pre : n_pre + n_open] = False
    opening = np.where(np.arange(n) < n_pre, 20.0, 20.0 + de)
    if log_motion:
        opening[~hold] = 20.0 + de * np.arange(1, n_open + 1) / (n_open + 1)
    else:
        opening[~hold] = np.nan
    return Step(t, level, hold, opening, k, tc, dead, de, true_onset, t[n_pre], n_pre, n_open)


def fit_step(s: Step, onset: float) -> FopdtFit:
    mask = s.hold & (np.arange(s.n) >= s.k_open - 40)
    return fit_fopdt(
        s.t, s.h, mask, onset, s.delta_e, float(np.mean(s.h[s.k_open - 40 : s.k_open]))
    )


SEEDS = range(40)


@pytest.fixture(scope="module")
def fits() -> list[tuple[Step, FopdtFit]]:
    out = []
    for seed in SEEDS:
        s = make_step(seed, up=seed % 2 == 0)
        out.append((s, fit_step(s, s.true_onset)))
    return out


def test_least_squares_recovers_truth_in_every_seed(fits: list[tuple[Step, FopdtFit]]) -> None:
    assert {s.delta_e for s, _ in fits} == {5.0, -5.0}
    for s, f in fits:
        assert f.converged
        assert abs(f.gain_mm_per_mm / s.gain - 1) < 0.03
        assert abs(f.time_constant_s / s.time_constant - 1) < 0.10
        assert abs(f.dead_time_s - s.dead_time) < 1.5


def test_standard_errors_are_honest(fits: list[tuple[Step, FopdtFit]]) -> None:
    pairs = {
        "K": [(f.gain_mm_per_mm - s.gain, f.gain_se_mm_per_mm) for s, f in fits],
        "T": [(f.time_constant_s - s.time_constant, f.time_constant_se_s) for s, f in fits],
        "L": [(f.dead_time_s - s.dead_time, f.dead_time_se_s) for s, f in fits],
    }
    for name, rows in pairs.items():
        err, se = np.array(rows).T
        assert np.all(se > 0), name
        inside = np.mean(np.abs(err) < 2.576 * se)
        assert inside >= 0.9, f"{name}: only {inside:.0%} of errors inside 2.576 se"
        # and not wildly pessimistic: the typical error is a sizeable part of the se
        assert np.sqrt(np.mean((err / se) ** 2)) > 0.5, name


def test_dead_time_is_measured_from_the_onset_given() -> None:
    # A record's logged onset is the first open sample, after the true start of motion:
    # the fitted L is then shorter by that lag.
    s = make_step(3, noise_sd=0.3)
    f = fit_step(s, s.logged_onset)
    apparent = s.dead_time - (s.logged_onset - s.true_onset)
    assert abs(f.dead_time_s - apparent) < 3 * f.dead_time_se_s + 0.05


def test_fit_curve_and_dict_round_trip(fits: list[tuple[Step, FopdtFit]]) -> None:
    s, f = fits[0]
    tau = s.t - f.onset_time_s - f.dead_time_s
    expected = f.baseline_mm + f.gain_mm_per_mm * f.delta_e_mm * (
        1 - np.exp(-np.maximum(tau, 0) / f.time_constant_s)
    )
    np.testing.assert_allclose(f.curve(s.t), expected, rtol=0, atol=1e-9)
    assert np.sqrt(np.mean((f.curve(s.t) - s.h)[s.hold] ** 2)) == pytest.approx(f.rmse_mm, 0.05)
    d = json.loads(json.dumps(f.to_dict(), allow_nan=False))
    assert FopdtFit.from_dict(d) == f
    assert {"K", "L_s", "T_s", "K_se", "L_se", "T_se"} <= set(d)


def test_fit_continuous_dead_time_noise_free() -> None:
    s = make_step(11, noise_sd=0.0, dead_time=4.37, time_constant=55.0, gain=-12.3)
    f = fit_step(s, s.true_onset)
    assert f.dead_time_s == pytest.approx(4.37, abs=1e-4)
    assert f.time_constant_s == pytest.approx(55.0, rel=1e-5)
    assert f.gain_mm_per_mm == pytest.approx(-12.3, rel=1e-6)


@pytest.mark.parametrize("seed", range(12))
def test_paper_method_noise_free_within_one_sample(seed: int) -> None:
    # With the motion samples logged (valid per the paper), sigma_pre = 0 and the first
    # sample past the true delay is detected: L in (L_true, L_true + Ts]. T is counted
    # from that sample to the interpolated 63.2 % crossing: T in [T_true - Ts, T_true].
    s = make_step(seed, noise_sd=0.0, up=seed % 2 == 1, log_motion=True)
    p = paper_step_method(s.t, s.h, s.hold, s.true_onset, s.n, s.delta_e, opening_mm=s.opening)
    assert p.pre_sd_mm == 0.0
    assert 0.0 < p.dead_time_s - s.dead_time <= TS + 1e-9
    assert -TS - 1e-6 <= p.time_constant_s - s.time_constant <= 1e-3
    assert p.gain_mm_per_mm == pytest.approx(s.gain, rel=1e-3)
    assert (p.n_pre, p.n_post) == (40, 40)


def test_paper_method_skips_motion_samples_without_opening() -> None:
    # Motion samples with a missing opening are removed: the detection falls on the first
    # hold sample after the motion when the level already moved during it.
    s = make_step(5, noise_sd=0.0, dead_time=1.0, log_motion=False)
    p = paper_step_method(s.t, s.h, s.hold, s.logged_onset, s.n, s.delta_e, opening_mm=s.opening)
    assert p.detect_index == s.k_open + s.n_open
    assert p.dead_time_s == pytest.approx(s.t[s.k_open + s.n_open] - s.logged_onset)


def test_paper_method_windows_and_statistics() -> None:
    s = make_step(8, noise_sd=0.7)
    p = paper_step_method(s.t, s.h, s.hold, s.logged_onset, s.n, s.delta_e)
    pre = s.h[s.k_open - 40 : s.k_open]
    post = s.h[s.n - 40 :]
    assert p.pre_mean_mm == pytest.approx(pre.mean())
    assert p.pre_sd_mm == pytest.approx(pre.std(ddof=1))
    assert p.post_mean_mm == pytest.approx(post.mean())
    assert p.post_sd_mm == pytest.approx(post.std(ddof=1))
    assert p.delta_level_mm == pytest.approx(post.mean() - pre.mean())
    assert p.gain_mm_per_mm == pytest.approx(p.delta_level_mm / s.delta_e)
    assert p.threshold_mm == pytest.approx(3 * pre.std(ddof=1))
    assert (p.pre_start_index, p.post_start_index) == (s.k_open - 40, s.n - 40)
    # detection sample: first valid sample after onset beyond 3 sigma
    dev = np.abs(s.h - pre.mean())
    first = next(k for k in range(s.k_open, s.n) if s.hold[k] and dev[k] > p.threshold_mm)
    assert p.detect_index == first
    assert PaperStepResult.from_dict(json.loads(json.dumps(p.to_dict()))) == p


def test_paper_method_refuses_small_step() -> None:
    s = make_step(2, noise_sd=1.0, gain=-0.3)  # dH_ss = 1.5 mm < 3 sigma
    with pytest.raises(IdentificationError, match="too small"):
        paper_step_method(s.t, s.h, s.hold, s.logged_onset, s.n, s.delta_e)


def test_paper_method_refuses_response_that_never_crosses() -> None:
    # A flat response never crosses 3 sigma; a post mean beyond 3 sigma always has a
    # sample beyond it, so the refusal is "too small".
    s = make_step(2, noise_sd=0.5, gain=0.0)
    with pytest.raises(IdentificationError, match="too small"):
        paper_step_method(s.t, s.h, s.hold, s.logged_onset, s.n, s.delta_e)


@pytest.mark.parametrize("where", ["pre", "post"])
def test_paper_method_refuses_short_windows(where: str) -> None:
    s = make_step(4, noise_sd=0.5)
    if where == "pre":
        with pytest.raises(IdentificationError, match="40 valid hold samples before"):
            paper_step_method(
                s.t, s.h, s.hold, s.logged_onset, s.n, s.delta_e, pre_start_index=s.k_open - 39
            )
    else:
        with pytest.raises(IdentificationError, match="40 valid hold samples in the hold"):
            paper_step_method(s.t, s.h, s.hold, s.logged_onset, s.k_open + s.n_open + 39, s.delta_e)


def test_fit_refuses_bad_input() -> None:
    s = make_step(1, noise_sd=0.5)
    with pytest.raises(IdentificationError, match="non-zero"):
        fit_fopdt(s.t, s.h, s.hold, s.logged_onset, 0.0, 230.0)
    with pytest.raises(IdentificationError, match="before and 6 after"):
        fit_fopdt(s.t, s.h, s.t < s.logged_onset, s.logged_onset, 5.0, 230.0)


GAUGES = {"1D": 3.0, "2E": 2.1, "3F": 1.1, "4G": 0.7, "5H": 0.2}


def test_identify_step_on_record() -> None:
    levels, truths = {}, {}
    rng = np.random.default_rng(100)
    for i, name in enumerate(GAUGES):
        # same seed: same time grid and motion; gauges differ in delay, datum and noise
        s = make_step(100, noise_sd=0.0, gain=-15.4, time_constant=71.0, dead_time=2.0 + i)
        levels[name] = s.h + 2.0 * i + rng.normal(0.0, 0.4, s.n)
        truths[name] = s
    s = truths["1D"]
    flow = np.full(s.n, 29.5)
    rec = record_from_arrays(s.t, s.opening, s.hold, flow, levels, gauges_m=GAUGES)
    assert len(rec.steps) == 1 and rec.steps[0].index == s.k_open
    ident = identify_step(rec)
    d = json.loads(json.dumps(ident.to_dict(), allow_nan=False))
    assert d["test"] == "step"
    assert d["delta_e_mm"] == pytest.approx(5.0)
    assert d["flow_m3h"] == pytest.approx(29.5)
    assert list(d["gauges"]) == list(GAUGES)
    for name, g in d["gauges"].items():
        assert {"pre_mean_mm", "pre_sd_mm", "post_mean_mm", "post_sd_mm", "dH_mm"} <= set(g)
        assert {"K", "L_s", "T_s"} <= set(g["paper"])
        assert {"K", "L_s", "T_s", "K_se", "L_se", "T_se"} <= set(g["fit"])
        truth = truths[name]
        apparent = truth.dead_time - (truth.logged_onset - truth.true_onset)
        assert g["fit"]["K"] == pytest.approx(-15.4, rel=0.03)
        assert g["fit"]["T_s"] == pytest.approx(71.0, rel=0.1)
        assert g["fit"]["L_s"] == pytest.approx(apparent, abs=1.5)
        assert g["paper"]["K"] == pytest.approx(-15.4, rel=0.03)
    assert StepIdentification.from_dict(d) == ident
    one = identify_step(rec, gauge="3F")
    assert list(one.gauges) == ["3F"]


def _with_logging_gap(s: Step, after_onset_s: float, rows: int, opening_after_mm: float,
                      flow_after_m3h: float = 30.0, flow_sd_m3h: float = 0.0):  # fmt: skip
    """``s`` as a record with ``rows`` samples missing from ``after_onset_s`` after the onset
    (a logging gap), the opening logged as ``opening_after_mm`` and the inflow as
    ``flow_after_m3h`` after it (30 m³/h before), with a meter's noise of ``flow_sd_m3h``."""
    first = int(np.searchsorted(s.t, s.logged_onset + after_onset_s))
    keep = np.ones(s.n, dtype=bool)
    keep[first : first + rows] = False
    later = np.arange(s.n) >= first + rows
    opening = np.where(later, opening_after_mm, s.opening)
    flow = np.where(later, flow_after_m3h, 30.0)
    flow = flow + np.random.default_rng(5).normal(0.0, flow_sd_m3h, s.n)
    return first, record_from_arrays(s.t[keep], opening[keep], s.hold[keep], flow[keep],
                                     {"3F": s.h[keep]})  # fmt: skip


def test_a_logging_gap_inside_the_response_does_not_end_the_fit() -> None:
    """A gap of 25 samples half a time constant after the onset, the gate held through it:
    the record is still a step test (40 samples after the step, counted across the gap),
    and the fit runs on to the end of the record (every valid sample) and finds the truth
    within three of its standard errors. Where the opening changed by the actuator's
    resolution inside a gap (an unobserved step; openings 8.1 and 9.1 mm, whose difference
    rounds below 1), or the inflow did (30 to 36 m³/h), the response ends at the gap; a flow
    meter's noise (0.3 m³/h) does not end it."""
    s = make_step(11, noise_sd=0.3, time_constant=60.0)
    first, rec = _with_logging_gap(s, 30.0, 25, s.opening[-1])
    assert len(rec.holds) == 3 and len(rec.steps) == 1  # the gap splits the hold after it
    assert rec.test == "step" and rec.test_source == "detected"
    fit = identify_step(rec).gauges["3F"].fit
    assert fit.n == s.n - 25 - s.n_open - (s.k_open - 40)  # pre window to the record's end
    for value, se, truth in (
        (fit.gain_mm_per_mm, fit.gain_se_mm_per_mm, s.gain),
        (fit.time_constant_s, fit.time_constant_se_s, s.time_constant),
    ):
        assert abs(value - truth) <= 3 * se
    low = replace(s, opening=s.opening - 16.9)  # 3.1 mm, then 8.1 mm after the step
    first, moved = _with_logging_gap(low, 80.0, 25, 9.1)
    assert moved.unobserved_steps == 1
    assert identify_step(moved).gauges["3F"].fit.n == first - s.n_open - (s.k_open - 40)
    first, inflow = _with_logging_gap(s, 80.0, 25, s.opening[-1], flow_after_m3h=36.0)
    assert inflow.unobserved_steps == 0
    assert identify_step(inflow).gauges["3F"].fit.n == first - s.n_open - (s.k_open - 40)
    # a meter's noise is no inflow change, a gap three samples after the step included
    for after_onset_s in (3.0, 30.0):
        _, noisy = _with_logging_gap(s, after_onset_s, 25, s.opening[-1], flow_sd_m3h=0.3)
        assert noisy.steps[0].held_after.stop == noisy.n_samples


def test_identify_step_refusals() -> None:
    s = make_step(7, noise_sd=0.4)
    flow = np.full(s.n, 30.0)
    rec = record_from_arrays(s.t, s.opening, s.hold, flow, {"3F": s.h})
    with pytest.raises(IdentificationError, match="no gauge 9Z"):
        identify_step(rec, gauge="9Z")
    with pytest.raises(IdentificationError, match="step 3 requested"):
        identify_step(rec, step_index=3)
    flat = record_from_arrays(s.t, np.full(s.n, 20.0), np.ones(s.n, bool), flow, {"3F": s.h})
    with pytest.raises(IdentificationError, match="no step"):
        identify_step(flat)


def test_the_driven_fit_takes_a_pool_slower_than_the_flume_caps() -> None:
    """A canal pool's time constant (two hours) and dead time (five minutes) lie beyond the
    driven fit's flume-scale caps (5000 s, 120 s): started from the step fit's values, it
    fits them instead of refusing its own start. The data are the model's own noise-free
    response on a 60 s grid, so the fit lands on the truth to the optimiser's tolerance
    (1e-6 relative here, far below what one sample of 60 s could resolve)."""
    from gatetwin.identification.fopdt_driven import (
        DEAD_TIME_MAX_S,
        TAU_MAX_S,
        fit_fopdt_driven,
        fopdt_response,
    )

    gain, tau, delay = -5.0, 7200.0, 300.0
    assert tau > TAU_MAX_S and delay > DEAD_TIME_MAX_S
    t = np.arange(0.0, 12 * 3600.0, 60.0)
    opening = np.where(t < 3600.0, 500.0, 560.0)
    level = 2000.0 + fopdt_response(t, opening, gain, tau, delay, 500.0)
    fit = fit_fopdt_driven(t, opening, level, initial=(-4.0, 6000.0, 240.0))
    assert fit.gain_mm_per_mm == pytest.approx(gain, rel=1e-6)
    assert fit.time_constant_s == pytest.approx(tau, rel=1e-6)
    assert fit.dead_time_s == pytest.approx(delay, rel=1e-6)
