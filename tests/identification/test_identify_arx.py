"""Known-truth tests of ARX identification (gatetwin.identification.arx, metrics, orders, prbs)."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pytest
from scipy import signal

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx import ArxFit, fit_arx, predict_one_step, simulate_free
from gatetwin.identification.metrics import (
    dc_gain,
    dominant_pole,
    is_stable,
    one_step_metrics,
    residual_whiteness,
    simulation_metrics,
)
from gatetwin.identification.orders import choose, search_orders
from gatetwin.identification.prbs import identify_prbs
from gatetwin.identification.preprocess import (
    continuous_segments,
    hampel_filter,
    holdout_split,
    reconstructed_opening,
    split_segments,
)
from gatetwin.records import record_from_arrays

TS = 1.2
A_TRUE = (1.2, -0.3)  # poles 0.845 and 0.355
B_TRUE = (-1.5, -0.8)  # DC gain -23 mm/mm


@dataclass(frozen=True)
class Prbs:
    """A synthetic PRBS record (ARX(2,2,1) truth) with hold and open runs."""

    t: np.ndarray
    logged: np.ndarray  # opening as logged: NaN during actuator motion
    hold: np.ndarray
    y: np.ndarray
    holds: np.ndarray  # (n, 2) hold segments
    opening: np.ndarray  # the true opening (linear ramps during motion)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def everything(self) -> np.ndarray:
        return continuous_segments(self.t, TS)


def make_prbs(
    seed: int,
    n: int = 6000,
    *,
    a: tuple[float, ...] = A_TRUE,
    b: tuple[float, ...] = B_TRUE,
    nk: int = 1,
    noise_sd: float = 0.5,
) -> Prbs:
    """Hold runs of 10-60 samples at 30 or 40 mm, open runs of 2-5 samples between them
    (actuator at constant speed, opening not logged); the level evolves at every sample."""
    rng = np.random.default_rng(seed)
    opening = np.empty(n)
    hold = np.zeros(n, dtype=bool)
    holds = []
    k, current = 0, 40.0
    while k < n:
        stop = min(n, k + int(rng.integers(10, 61)))
        opening[k:stop], hold[k:stop] = current, True
        holds.append((k, stop))
        k = stop
        target = 30.0 if current > 35.0 else 40.0
        m = int(rng.integers(2, 6))
        stop = min(n, k + m)
        opening[k:stop] = current + (target - current) * np.arange(1, stop - k + 1) / (m + 1)
        k, current = stop, target
    n = holds[-1][1]  # end on a hold: trailing motion could not be reconstructed
    opening, hold = opening[:n], hold[:n]
    u = opening - 35.0
    a_poly = np.concatenate(([1.0], -np.asarray(a)))
    b_poly = np.concatenate((np.zeros(nk), b))
    y = signal.lfilter(b_poly, a_poly, u) + signal.lfilter(
        [1.0], a_poly, rng.normal(0, noise_sd, n)
    )
    logged = np.where(hold, opening, np.nan)
    return Prbs(TS * np.arange(n), logged, hold, 250.0 + y, np.array(holds), opening)


def explicit_lstsq(
    u: np.ndarray, y: np.ndarray, segments: np.ndarray, na: int, nb: int, nk: int
) -> np.ndarray:
    """The textbook way: build the regressor row by row and call numpy.linalg.lstsq."""
    clean = split_segments(segments, u, y)
    inside = np.concatenate([np.arange(s, e) for s, e in clean])
    uu, yy = u - u[inside].mean(), y - y[inside].mean()
    m = max(na, nk + nb - 1)
    rows = np.concatenate([np.arange(s + m, e) for s, e in clean if e > s + m])
    cols = [yy[rows - i] for i in range(1, na + 1)]
    cols += [uu[rows - nk - j] for j in range(nb)]
    return np.linalg.lstsq(np.column_stack(cols), yy[rows], rcond=None)[0]


# ------------------------------------------------------------------ coefficient recovery


@pytest.mark.parametrize("seed", range(20))
def test_all_rows_recover_arx221(seed: int) -> None:
    # b1 and b2 are told apart only by the few ramp samples of each gate motion: at
    # 6000 samples their standard errors are ~0.012 and ~0.025, so the 0.03 criterion
    # needs a long record (60000 samples: se ~0.004 / 0.008).
    d = make_prbs(seed, n=60_000)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    np.testing.assert_allclose(u, d.opening, atol=1e-9)  # ramps are exactly linear
    fit = fit_arx(u, d.y, d.everything, 2, 2, 1)
    np.testing.assert_allclose(fit.a, A_TRUE, atol=0.03)
    np.testing.assert_allclose(fit.b, B_TRUE, atol=0.03)
    assert fit.noise_variance_mm2 == pytest.approx(0.25, rel=0.05)
    assert fit.opening_mean_mm == pytest.approx(np.mean(u))


def test_arx_standard_errors_are_honest() -> None:
    inside = []
    for seed in range(30):
        d = make_prbs(100 + seed)
        u = reconstructed_opening(d.t, d.logged, d.hold)
        fit = fit_arx(u, d.y, d.everything, 2, 2, 1)
        se = np.array(fit.a_se + fit.b_se)
        inside.append(np.abs(fit.theta - np.array(A_TRUE + B_TRUE)) < 2.576 * se)
    assert np.all(np.mean(inside, axis=0) >= 0.9)


@pytest.mark.parametrize("seed", range(20))
def test_hold_rows_recover_a_and_the_sum_of_b(seed: int) -> None:
    # On hold rows the opening is one value per segment: u(k-1) = u(k-2) on every row, so
    # ARX(2,1,1) is the identifiable model, with b1 = b1_true + b2_true.
    d = make_prbs(seed)
    fit = fit_arx(d.logged, d.y, d.holds, 2, 1, 1)
    np.testing.assert_allclose(fit.a, A_TRUE, atol=0.03)
    assert fit.b[0] == pytest.approx(sum(B_TRUE), abs=0.03)
    assert fit.n_rows == sum(e - s - 2 for s, e in d.holds if e - s > 2)


def test_hold_rows_refuse_unidentifiable_b() -> None:
    d = make_prbs(0, n=2000)
    with pytest.raises(IdentificationError, match="constant within every segment"):
        fit_arx(d.logged, d.y, d.holds, 2, 2, 1)


def test_orders_refused() -> None:
    d = make_prbs(0, n=500)
    for orders in [(0, 1, 1), (1, 0, 1), (1, 1, -1), (1.5, 1, 1)]:
        with pytest.raises(IdentificationError, match="orders"):
            fit_arx(d.logged, d.y, d.holds, *orders)
    with pytest.raises(IdentificationError, match="regression rows"):
        fit_arx(d.logged, d.y, [(0, 6)], 5, 1, 0)


# ------------------------------------------------------------------ normal equations


@pytest.mark.parametrize(
    ("mode", "orders"),
    [
        ("hold", (2, 1, 1)),
        ("hold", (3, 1, 0)),
        ("hold", (1, 1, 2)),
        ("all", (2, 2, 1)),
        ("all", (3, 4, 2)),
        ("all", (5, 5, 0)),
    ],
)
def test_dot_products_equal_lstsq(mode: str, orders: tuple[int, int, int]) -> None:
    d = make_prbs(7, n=5000)
    rng = np.random.default_rng(1)
    y = d.y.copy()
    y[rng.choice(d.n, 40, replace=False)] = np.nan  # NaNs split segments
    if mode == "hold":
        u, segs = d.logged.copy(), d.holds
        u[rng.choice(np.flatnonzero(d.hold), 10, replace=False)] = np.nan
    else:
        u, segs = reconstructed_opening(d.t, d.logged, d.hold), d.everything
    fit = fit_arx(u, y, segs, *orders)
    ref = explicit_lstsq(u, y, segs, *orders)
    # relative to the size of theta (a true-zero coefficient has no relative error)
    assert np.linalg.norm(fit.theta - ref) <= 1e-8 * np.linalg.norm(ref)


def test_lags_never_bridge_segments() -> None:
    d = make_prbs(3, n=4000)
    fit = fit_arx(d.logged, d.y, d.holds, 2, 1, 1)
    jumped = d.y + np.where(d.hold, 0.0, 1000.0)  # huge jumps only while the gate moves
    fit_jumped = fit_arx(d.logged, jumped, d.holds, 2, 1, 1)
    np.testing.assert_allclose(fit_jumped.theta, fit.theta, rtol=1e-12)
    # Naive fits are hit: lags across open runs (one segment over everything) ...
    u = reconstructed_opening(d.t, d.logged, d.hold)
    naive = fit_arx(u, jumped, [(0, d.n)], 2, 1, 1)
    assert np.max(np.abs(naive.theta - fit.theta)) > 0.1
    # ... or hold samples concatenated and lagged as if contiguous.
    keep = d.hold
    concat = fit_arx(d.logged[keep], d.y[keep], [(0, int(keep.sum()))], 2, 1, 1)
    assert np.max(np.abs(concat.theta - fit.theta)) > 0.02


def test_drop_counts_follow_max_lag() -> None:
    # the first max(na, nk + nb - 1) samples of each segment give no row
    d = make_prbs(5, n=3000)
    for na, nk in [(1, 0), (2, 1), (1, 2), (4, 0)]:
        fit = fit_arx(d.logged, d.y, d.holds, na, 1, nk)
        m = max(na, nk)
        assert fit.max_lag == m
        assert fit.n_rows == sum(max(e - s - m, 0) for s, e in d.holds)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    assert fit_arx(u, d.y, d.everything, 1, 3, 2).n_rows == d.n - 4


# ------------------------------------------------------------------ prediction, simulation


def test_simulate_free_reproduces_noise_free_truth() -> None:
    d = make_prbs(2, n=3000, noise_sd=0.0)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    truth = ArxFit(2, 2, 1, A_TRUE, B_TRUE, (0, 0), (0, 0), ((0,) * 4,) * 4, 0.0, 1, 35.0, 250.0)
    # start from rest: y = 250 before the record, opening 35 (u' = 0)
    sim = simulate_free(truth, u, y_init=np.full(2, 250.0), u_init=np.full(2, 35.0))
    np.testing.assert_allclose(sim, d.y, atol=1e-9)
    fit = fit_arx(u, d.y, d.everything, 2, 2, 1)
    # Not exact: the model has no intercept and the data are demeaned by their sample
    # means, which differ slightly from the equilibrium pair the data were built on.
    np.testing.assert_allclose(fit.theta, A_TRUE + B_TRUE, atol=2e-3)
    pred = predict_one_step(fit, u, d.y, d.everything)
    assert np.isnan(pred[:2]).all()
    m = one_step_metrics(d.y, pred)
    assert m.r2 == pytest.approx(1.0, abs=1e-5) and m.rmse_mm < 0.05
    assert simulation_metrics(d.y, sim).fit_percent == pytest.approx(100.0)


def test_simulate_free_starts_at_equilibrium_and_refuses_gaps() -> None:
    fit = ArxFit(2, 2, 1, A_TRUE, B_TRUE, (0, 0), (0, 0), ((0,) * 4,) * 4, 0.0, 1, 35.0, 250.0)
    sim = simulate_free(fit, np.full(50, 40.0))
    np.testing.assert_allclose(sim, 250.0 + dc_gain(A_TRUE, B_TRUE) * 5.0, rtol=1e-12)
    with pytest.raises(IdentificationError, match="reconstructed_opening"):
        simulate_free(fit, np.array([35.0, np.nan, 35.0]))


def test_one_step_residuals_are_the_noise() -> None:
    d = make_prbs(4)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    fit = fit_arx(u, d.y, d.everything, 2, 2, 1)
    pred = predict_one_step(fit, u, d.y, d.everything)
    m = one_step_metrics(d.y, pred)
    assert m.rmse_mm == pytest.approx(0.5, rel=0.05)
    assert m.mae_mm == pytest.approx(0.5 * np.sqrt(2 / np.pi), rel=0.06)
    assert m.r2 > 0.99
    assert m.n == fit.n_rows


# ------------------------------------------------------------------ whiteness


def test_whiteness_of_true_model_and_misfit() -> None:
    p_true, p_bad = [], []
    for seed in range(20):
        d = make_prbs(seed, n=4000)
        u = reconstructed_opening(d.t, d.logged, d.hold)
        good = fit_arx(u, d.y, d.everything, 2, 2, 1)
        res = d.y - predict_one_step(good, u, d.y, d.everything)
        w = residual_whiteness(res, u, n_fitted=2)
        p_true.append(w.ljung_box_p)
        assert w.n == good.n_rows and w.max_lag == 25 and w.ljung_box_dof == 23
        assert w.n_outside <= 3 and w.n_cross_outside <= 3
        bad = fit_arx(u, d.y, d.everything, 1, 1, 1)
        res_bad = d.y - predict_one_step(bad, u, d.y, d.everything)
        p_bad.append(residual_whiteness(res_bad, u, n_fitted=1).ljung_box_p)
    assert np.mean(np.array(p_true) > 0.01) >= 0.9
    assert np.median(p_true) > 0.2
    assert max(p_bad) < 1e-6


def test_ljung_box_definition_and_null_distribution() -> None:
    rng = np.random.default_rng(0)
    e = rng.normal(size=800)
    e[100:110] = np.nan  # a gap: pairs across it are left out
    w = residual_whiteness(e, max_lag=10)
    ok = np.isfinite(e)
    e0 = np.where(ok, e - np.nanmean(e), 0.0)
    n = ok.sum()
    r = np.array([e0[k:] @ e0[:-k] for k in range(1, 11)]) / (e0 @ e0)
    np.testing.assert_allclose(w.autocorrelation, r, rtol=1e-12)
    q = n * (n + 2) * np.sum(r**2 / (n - np.arange(1, 11)))
    assert w.ljung_box_q == pytest.approx(q)
    assert w.band == pytest.approx(2.576 / np.sqrt(n))
    qs = [residual_whiteness(rng.normal(size=1000), max_lag=20).ljung_box_q for _ in range(200)]
    assert np.mean(qs) == pytest.approx(20, rel=0.1)  # chi-square(20) mean


# ------------------------------------------------------------------ poles, gains


def test_paper_table4_implied_poles_and_gains() -> None:
    # docs/reference_study.md: C has a dominant pole ~0.969 (~38 s) and DC gain ~-19.5;
    # D ~0.768 (~4.5 s) and ~-11.
    c = dominant_pole((0.713, 0.248), TS)
    assert c.kind == "real" and c.real == pytest.approx(0.969, abs=1e-3)
    assert c.time_constant_s == pytest.approx(38.0, abs=0.5)
    assert dc_gain((0.713, 0.248), (-1.93, 1.17)) == pytest.approx(-19.5, abs=0.1)
    d = dominant_pole((0.575, 0.148), TS)
    assert d.real == pytest.approx(0.768, abs=1e-3)
    assert d.time_constant_s == pytest.approx(4.5, abs=0.1)
    assert dc_gain((0.575, 0.148), (-2.53, -0.51)) == pytest.approx(-11.0, abs=0.1)
    assert is_stable((0.713, 0.248)) and is_stable((0.575, 0.148))


def test_dominant_pole_kinds() -> None:
    osc = dominant_pole((1.6, -0.8), TS)
    assert osc.kind == "complex" and osc.imag > 0
    assert osc.time_constant_s == pytest.approx(-TS / np.log(np.sqrt(0.8)))
    neg = dominant_pole((-0.9,), TS)
    assert neg.kind == "negative" and neg.time_constant_s is None
    assert not is_stable((1.1,))
    assert dominant_pole((1.1,), TS).time_constant_s is None


# ------------------------------------------------------------------ order search


def test_order_search_picks_true_orders_by_bic() -> None:
    picked = []
    for seed in range(10):
        d = make_prbs(seed, n=4000)
        u = reconstructed_opening(d.t, d.logged, d.hold)
        table = search_orders(u, d.y, d.everything, time_s=d.t)
        assert len(table) == 75
        assert len({r.n_rows for r in table}) == 1  # one common row set
        choice = choose(table, "bic")
        assert choice.criterion == "bic" and "bic" in choice.reason
        picked.append(choice.row.orders)
    assert picked.count((2, 2, 1)) >= 8, picked


def test_order_search_matches_direct_fits_and_holdout() -> None:
    d = make_prbs(1, n=3000)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    est, val = holdout_split(d.everything, d.n, fraction=0.3, time_s=d.t)
    table = search_orders(u, d.y, d.everything, [2], [2], [1], holdout=(est, val))
    row = table[0]
    # common row set = the model's own here (max lag of the grid = 2)
    fit = fit_arx(u, d.y, est, 2, 2, 1)
    n, p = fit.n_rows, 4
    ssr = fit.noise_variance_mm2 * (n - p)
    assert row.bic == pytest.approx(n * np.log(ssr / n) + p * np.log(n))
    assert row.aic == pytest.approx(n * np.log(ssr / n) + 2 * p)
    pred = predict_one_step(fit, u, d.y, val)
    assert row.holdout_rmse_mm == pytest.approx(one_step_metrics(d.y, pred).rmse_mm, rel=1e-6)
    assert 50 < row.holdout_fit_percent <= 100


def test_order_search_on_hold_rows_marks_unidentifiable() -> None:
    d = make_prbs(2, n=3000)
    u = reconstructed_opening(d.t, d.logged, d.hold)
    table = search_orders(u, d.y, d.holds, time_s=d.t)
    assert all(not r.identifiable for r in table if r.nb >= 2)
    assert all(r.identifiable for r in table if r.nb == 1)
    best = choose(table, "bic").row
    assert (best.na, best.nb) == (2, 1)
    with pytest.raises(IdentificationError, match="unknown order criterion"):
        choose(table, "r2")


# ------------------------------------------------------------------ preprocessing


def test_hampel_replaces_spikes_within_segments() -> None:
    d = make_prbs(6, n=3000)
    rng = np.random.default_rng(2)
    inner = np.concatenate([np.arange(s + 3, e - 3) for s, e in d.holds if e - s > 12])
    # a Hampel filter sees spikes where the level is not racing (window MAD small)
    quiet = np.array([np.ptp(d.y[k - 3 : k + 4]) < 3.0 for k in inner])
    spikes = np.sort(rng.choice(inner[quiet], 25, replace=False))
    spikes = spikes[np.diff(spikes, prepend=-10) > 7]
    dirty = d.y.copy()
    dirty[spikes] += 40.0 * rng.choice([-1, 1], spikes.size)
    out = hampel_filter(dirty, d.holds)
    assert set(spikes) <= set(out.replaced_index)
    assert out.n_replaced <= spikes.size + 0.01 * d.n
    assert np.max(np.abs(out.values[spikes] - d.y[spikes])) < 5.0
    outside = ~d.hold
    np.testing.assert_array_equal(out.values[outside], dirty[outside])


def test_split_segments_and_reconstruction() -> None:
    y = np.arange(20.0)
    y[[3, 12]] = np.nan
    segs = split_segments([(0, 8), (8, 20)], y)
    np.testing.assert_array_equal(segs, [[0, 3], [4, 8], [8, 12], [13, 20]])
    t = np.array([0.0, 1.0, 2.0, 4.0, 5.0, 9.0])
    e = np.array([10.0, 10.0, np.nan, np.nan, 20.0, 20.0])
    hold = np.array([True, True, False, False, True, True])
    np.testing.assert_allclose(reconstructed_opening(t, e, hold), [10, 10, 12.5, 17.5, 20, 20])
    est, val = holdout_split([(0, 10), (12, 20)], 20, fraction=0.3)
    np.testing.assert_array_equal(est, [[0, 10], [12, 14]])
    np.testing.assert_array_equal(val, [[14, 20]])


# ------------------------------------------------------------------ record wrapper


def prbs_record(seed: int, n: int = 5000) -> tuple[Prbs, object]:
    d = make_prbs(seed, n=n)
    flow = np.full(d.n, 41.5)
    rec = record_from_arrays(d.t, d.logged, d.hold, flow, {"3F": d.y}, test="prbs")
    return d, rec


def test_identify_prbs_fixed_orders() -> None:
    d, rec = prbs_record(11)
    ident = identify_prbs(rec)
    out = json.loads(json.dumps(ident.to_dict(), allow_nan=False))
    for key in [
        "test",
        "gauge",
        "na",
        "nb",
        "nk",
        "a",
        "b",
        "one_step",
        "simulation",
        "dc_gain",
        "time_constant_s",
        "orders",
        "whiteness",
        "stable",
        "criterion",
    ]:
        assert key in out, key
    assert out["test"] == "prbs" and out["gauge"] == "3F"
    assert (out["na"], out["nb"], out["nk"]) == (2, 2, 1)
    assert out["rows"] == "all" and "constant" in out["rows_reason"]
    np.testing.assert_allclose(out["a"], A_TRUE, atol=0.03)
    # b1, b2 separately are known to ~0.01-0.03 at 5000 samples: judge by their se
    assert np.all(np.abs(np.array(out["b"]) - B_TRUE) < 3.5 * np.array(out["b_se"]))
    assert sum(out["b"]) == pytest.approx(sum(B_TRUE), abs=0.03)
    assert {"r2", "mae_mm", "rmse_mm"} <= set(out["one_step"])
    assert {"fit_percent", "rmse_mm"} <= set(out["simulation"])
    assert out["one_step"]["rmse_mm"] == pytest.approx(0.5, rel=0.1)
    assert out["dc_gain"] == pytest.approx(-23.0, rel=0.1)
    assert out["time_constant_s"] == pytest.approx(-TS / np.log(0.8449), rel=0.1)
    assert out["stable"] and out["criterion"] == "fixed" and out["orders"] == []
    assert out["flow_m3h"] == pytest.approx(41.5)
    assert ArxFit.from_dict(out["model"]) == ident.fit


def test_identify_prbs_auto_orders_and_hold_rows() -> None:
    _, rec = prbs_record(12)
    ident = identify_prbs(rec, orders="auto", criterion="bic")
    assert (ident.fit.na, ident.fit.nb, ident.fit.nk) == (2, 2, 1)
    out = ident.to_dict()
    assert out["criterion"] == "bic" and len(out["orders"]) == 75
    hold = identify_prbs(rec, orders=(2, 1, 1), rows="hold")
    assert hold.rows == "hold"
    np.testing.assert_allclose(hold.fit.a, A_TRUE, atol=0.03)
    with pytest.raises(IdentificationError, match="gauge 3F.*constant within every segment"):
        identify_prbs(rec, rows="hold")
    with pytest.raises(IdentificationError, match="no gauge 1D"):
        identify_prbs(rec, gauge="1D")


def test_identify_prbs_survives_spikes_nans_and_gaps() -> None:
    d = make_prbs(13, n=8000)
    rng = np.random.default_rng(5)
    y = d.y.copy()
    quiet = [k for k in range(10, d.n - 10) if d.hold[k] and np.ptp(d.y[k - 3 : k + 4]) < 3.0]
    spikes = rng.choice(quiet[::8], 15, replace=False)
    y[spikes] += 60.0
    y[rng.choice(d.n, 20, replace=False)] = np.nan
    t = d.t.copy()
    t[4000:] += 30.0  # a logging gap: no row may bridge it
    rec = record_from_arrays(t, d.logged, d.hold, np.full(d.n, 84.5), {"3F": y}, test="prbs")
    ident = identify_prbs(rec)
    assert ident.spikes_replaced >= spikes.size
    np.testing.assert_allclose(ident.fit.a, A_TRUE, atol=0.03)
    assert np.all(np.abs(np.array(ident.fit.b) - B_TRUE) < 4 * np.array(ident.fit.b_se))
    assert ident.one_step.rmse_mm < 0.6
    assert ident.whiteness.ljung_box_p > 1e-3


def test_a_prbs_record_without_the_flumes_gauge_names_is_identified(tmp_path, capsys):
    """A field logger's gauges (no ``3F``): ``gatetwin identify`` and ``gatetwin.identify``
    take the gauge ``gatetwin models`` would (the highest signal-to-noise ratio: the one the
    flume calls 3F), where the command asked for a gauge 3F."""
    from gatetwin import identify
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.cli import main

    names = {"1D": "U1", "2E": "U2", "3F": "U3", "4G": "U4", "5H": "U5"}
    source = bundled_records_dir() / "C.csv"
    text = source.read_text(encoding="utf-8")
    sidecar = json.loads(source.with_suffix(".json").read_text(encoding="utf-8"))
    for old, new in names.items():
        text = text.replace(f"level_{old}_mm", f"level_{new}_mm")
    sidecar["gauges"] = {names[g]: d for g, d in sidecar["gauges"].items()}
    record = tmp_path / "C.csv"
    record.write_text(text, encoding="utf-8")
    record.with_suffix(".json").write_text(json.dumps(sidecar), encoding="utf-8")
    assert main(["identify", str(record), "--json", str(tmp_path / "c.json")]) == 0
    assert json.loads((tmp_path / "c.json").read_text())["gauge"] == "U3"
    assert "ARX(2,2,1) at U3" in capsys.readouterr().out
    assert identify(record).plant.gauge == "U3"
