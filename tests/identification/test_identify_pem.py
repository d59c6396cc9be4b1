"""Known-truth tests of the OE, ARMAX and Box-Jenkins fits and of the structure selection.

Tolerances are statistical. A fit's estimate ``theta`` is compared with the truth by the
Mahalanobis distance ``(theta - truth)^T Cov^-1 (theta - truth)`` with the fit's own
covariance; for a consistent estimator with honest standard errors it is approximately
chi-square with ``p`` degrees of freedom. A single seed must lie below the 0.999 quantile
(the parameters of these models are strongly correlated -- ``a1`` and ``a2`` move
together -- so a joint test is the right one, not ``p`` separate ones). Biased fits are
shown by distances beyond the ``1 - 1e-9`` quantile. Coverage over 20 seeds of the 0.99
quantile must be at least 0.85: below that with honest errors has probability < 0.02
(binomial(20, 0.99)), and a seed sweep of 200 measured OE coverage 0.97 with a small
finite-sample bias of about 0.3 standard errors.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal, stats

from gatetwin.errors import IdentificationError
from gatetwin.identification.armax import fit_armax
from gatetwin.identification.arx import ArxFit, deviations, fit_arx, predict_one_step, simulate_free
from gatetwin.identification.bj import fit_bj
from gatetwin.identification.discrete_select import select_discrete
from gatetwin.identification.metrics import dc_gain, free_run_on_segments
from gatetwin.identification.oe import fit_oe
from gatetwin.identification.pem import (
    PemOrders,
    innovations,
    is_admissible,
    one_step_prediction,
    reflect_into_unit_disc,
)
from gatetwin.identification.pemfit import PemFit, from_arx
from gatetwin.identification.prbs import identify_prbs, prbs_signals
from gatetwin.records import Record, read_record, record_from_arrays

F_TRUE = (1.2, -0.3)  # poles 0.845 and 0.355 ("+" convention: x(k) = 1.2 x(k-1) - 0.3 ...)
B_TRUE = (-1.5, -0.8)  # DC gain -23 mm/mm
C_TRUE = (0.7, 0.2)  # zeros of C at modulus 0.45
RECORDS = "src/gatetwin/data/records"


def _den(coefficients: tuple[float, ...]) -> np.ndarray:
    return np.concatenate(([1.0], -np.asarray(coefficients)))


def telegraph(rng: np.random.Generator, n: int) -> np.ndarray:
    """Opening switching between 30 and 40 mm, held 3-19 samples."""
    u, k, level = np.empty(n), 0, 40.0
    while k < n:
        m = int(rng.integers(3, 20))
        u[k : k + m] = level
        k, level = k + m, 70.0 - level
    return u


def oe_data(seed: int, n: int = 3000, noise_sd: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """``y = B/F u + e`` with white ``e``: coloured for ARX's equation error."""
    rng = np.random.default_rng(seed)
    u = telegraph(rng, n)
    x = signal.lfilter(np.concatenate(([0.0], B_TRUE)), _den(F_TRUE), u - 35.0)
    return u, 250.0 + x + rng.normal(0.0, noise_sd, n)


def armax_data(seed: int, n: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """``A y = B u + C e``, ``e`` white with sd 2 mm."""
    rng = np.random.default_rng(seed)
    u = telegraph(rng, n)
    e = rng.normal(0.0, 2.0, n)
    x = signal.lfilter(np.concatenate(([0.0], B_TRUE)), _den(F_TRUE), u - 35.0)
    return u, 250.0 + x + signal.lfilter(np.concatenate(([1.0], C_TRUE)), _den(F_TRUE), e)


def bj_data(seed: int, n: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """``y = B/F u + C/D e`` with ``C = 1 + 0.5 q^-1``, ``D = 1 - 0.9 q^-1``."""
    rng = np.random.default_rng(seed)
    u = telegraph(rng, n)
    x = signal.lfilter(np.concatenate(([0.0], B_TRUE)), _den(F_TRUE), u - 35.0)
    v = signal.lfilter([1.0, 0.5], [1.0, -0.9], rng.normal(0.0, 2.0, n))
    return u, 250.0 + x + v


def mahalanobis(fit: PemFit | ArxFit, truth: tuple[float, ...]) -> float:
    diff = np.asarray(fit.theta, dtype=float) - np.asarray(truth)
    return float(diff @ np.linalg.solve(np.asarray(fit.covariance), diff))


def q999(p: int) -> float:
    return float(stats.chi2.ppf(0.999, p))


# ------------------------------------------------------------------ output error


def test_oe_recovers_truth_where_arx_is_biased() -> None:
    u, y = oe_data(1)
    seg = [(0, u.size)]
    oe = fit_oe(u, y, seg, 2, 2, 1)
    arx = fit_arx(u, y, seg, 2, 2, 1)
    assert oe.structure == "oe" and oe.stable and oe.converged
    assert mahalanobis(oe, F_TRUE + B_TRUE) < q999(4)
    # Equation-error ARX on the same data: the truth lies far outside its own confidence
    # region (output noise is coloured in ARX's equation error), so an OE that silently
    # returned the ARX start would fail the line above.
    assert mahalanobis(arx, F_TRUE + B_TRUE) > stats.chi2.isf(1e-9, 4)
    truth_gain = dc_gain(F_TRUE, B_TRUE)
    assert abs(dc_gain(oe.a, oe.b) - truth_gain) < abs(dc_gain(arx.a, arx.b) - truth_gain)


def test_oe_standard_errors_cover_the_truth() -> None:
    inside = []
    for seed in range(20):
        u, y = oe_data(100 + seed)
        fit = fit_oe(u, y, [(0, u.size)], 2, 2, 1)
        inside.append(mahalanobis(fit, F_TRUE + B_TRUE) < stats.chi2.ppf(0.99, 4))
    assert np.mean(inside) >= 0.85


def test_oe_segments_are_not_bridged() -> None:
    u, y = oe_data(2)
    segs = np.array([(0, 1500), (1600, 3000)])
    dev = deviations(u, y, segs)
    orders = PemOrders("oe", 2, 2, 1)
    theta = np.array(F_TRUE + B_TRUE)
    before = innovations(orders, theta, dev)
    y2 = y.copy()
    y2[1400:1600] += 500.0  # the end of segment 1 and the gap change...
    u2 = u.copy()
    u2[1500:1600] = 0.0
    point = (dev.opening_mean_mm, dev.level_mean_mm)
    after = innovations(orders, theta, deviations(u2, y2, segs, point))
    np.testing.assert_array_equal(before[1], after[1])  # ...segment 2 does not see it
    assert [v.size for v in before] == [1500 - 2, 1400 - 2]  # each drops its first 2


def test_oe_fit_with_nan_gaps_recovers_truth() -> None:
    u, y = oe_data(3, n=4000)
    y[[700, 1900, 1901, 3100]] = np.nan  # each NaN cuts the segment; no row bridges it
    fit = fit_oe(u, y, [(0, u.size)], 2, 2, 1)
    assert fit.n_rows == 4000 - 4 - 4 * 2
    assert mahalanobis(fit, F_TRUE + B_TRUE) < q999(4)


def test_oe_one_step_predictor_is_the_simulation() -> None:
    u, y = oe_data(4, n=800)
    fit = fit_oe(u, y, [(0, 800)], 2, 2, 1)
    dev = deviations(u, y, [(0, 800)], (fit.opening_mean_mm, fit.level_mean_mm))
    pred = one_step_prediction(fit.orders, fit.theta, dev) + fit.level_mean_mm
    sim = simulate_free(fit.as_arx(), u[2:], y_init=y[:2], u_init=u[:2])
    np.testing.assert_allclose(pred[2:], sim, rtol=0, atol=1e-9)


def test_oe_refuses_unidentifiable_b() -> None:
    u = np.repeat([30.0, 40.0] * 20, 25)
    y = 250.0 + np.random.default_rng(0).normal(0, 1, u.size)
    holds = [(k, k + 25) for k in range(0, u.size, 25)]
    with pytest.raises(IdentificationError, match="sum of the b"):
        fit_oe(u, y, holds, 2, 2, 1, start=(0.5, 0.1, -1.0, -1.0))


# ------------------------------------------------------------------ ARMAX and BJ


def test_armax_recovers_truth_where_arx_is_biased() -> None:
    u, y = armax_data(5)
    seg = [(0, u.size)]
    fit = fit_armax(u, y, seg, 2, 2, 2, 1)
    assert fit.structure == "armax" and fit.stable
    assert mahalanobis(fit, F_TRUE + B_TRUE + C_TRUE) < q999(6)
    arx = fit_arx(u, y, seg, 2, 2, 1)
    assert mahalanobis(arx, F_TRUE + B_TRUE) > stats.chi2.isf(1e-9, 4)


def test_armax_standard_errors_cover_the_truth() -> None:
    inside = []
    for seed in range(20):
        u, y = armax_data(200 + seed)
        fit = fit_armax(u, y, [(0, u.size)], 2, 2, 2, 1)
        inside.append(mahalanobis(fit, F_TRUE + B_TRUE + C_TRUE) < stats.chi2.ppf(0.99, 6))
    assert np.mean(inside) >= 0.85


def test_armax_with_c_zero_predicts_like_arx() -> None:
    u, y = armax_data(6, n=600)
    arx = fit_arx(u, y, [(0, 600)], 2, 2, 1)
    dev = deviations(u, y, [(0, 600)])
    orders = PemOrders("armax", 2, 2, 1, nc=1)
    pred = one_step_prediction(orders, np.array(arx.a + arx.b + (0.0,)), dev)
    reference = predict_one_step(arx, u, y, [(0, 600)])
    np.testing.assert_allclose(
        pred + dev.level_mean_mm, reference, rtol=0, atol=1e-9, equal_nan=True
    )


def test_bj_recovers_truth() -> None:
    u, y = bj_data(7)
    fit = fit_bj(u, y, [(0, u.size)], 2, 2, 1, 1, 1)
    assert fit.structure == "bj" and fit.stable
    assert mahalanobis(fit, F_TRUE + B_TRUE + (0.5, 0.9)) < q999(6)


def test_orders_are_checked() -> None:
    with pytest.raises(IdentificationError):
        PemOrders("armax", 2, 2, 1)  # ARMAX needs nc >= 1
    with pytest.raises(IdentificationError):
        PemOrders("oe", 2, 2, 1, nc=1)
    with pytest.raises(IdentificationError):
        PemOrders("box", 2, 2, 1)
    with pytest.raises(IdentificationError):
        fit_armax(np.zeros(10), np.zeros(10), [(0, 10)], 2, 2, 0, 1)


def test_reflection_keeps_the_spectrum_shape_and_makes_admissible() -> None:
    c = np.array([-2.5, 1.0])  # 1 - 2.5 q^-1 + q^-2: roots 2 and 0.5
    inside = reflect_into_unit_disc(c, plus=True)
    np.testing.assert_allclose(np.sort(np.abs(np.roots(np.r_[1.0, inside]))), [0.5, 0.5])
    orders = PemOrders("armax", 1, 1, 1, nc=2)
    assert not is_admissible(orders, np.r_[0.5, 1.0, c])
    assert is_admissible(orders, np.r_[0.5, 1.0, inside])
    w = np.linspace(0, np.pi, 50)
    gain = [np.abs(np.polyval(np.r_[1.0, k][::-1], np.exp(-1j * w))) for k in (c, inside)]
    ratio = gain[0] / gain[1]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)  # same shape, scaled


def test_pem_fit_round_trips_to_arx_layout() -> None:
    u, y = oe_data(8, n=1000)
    arx = fit_arx(u, y, [(0, 1000)], 2, 2, 1)
    wrapped = from_arx(arx)
    assert wrapped.as_arx() == arx
    d = json.loads(json.dumps(fit_oe(u, y, [(0, 1000)], 2, 2, 1).to_dict(), allow_nan=False))
    assert d["structure"] == "oe" and d["denominator"] == "F" and d["c"] == []


# ------------------------------------------------------------------ selection


def prbs_oe_record(seed: int, n: int = 3000) -> Record:
    """A PRBS record (holds and constant-speed moves) whose level is OE with white noise."""
    rng = np.random.default_rng(seed)
    opening, hold, k, current = np.empty(n), np.zeros(n, bool), 0, 40.0
    while k < n:
        stop = min(n, k + int(rng.integers(8, 30)))
        opening[k:stop], hold[k:stop] = current, True
        k, target, m = stop, 70.0 - current, int(rng.integers(2, 4))
        stop = min(n, k + m)
        opening[k:stop] = current + (target - current) * np.arange(1, stop - k + 1) / (m + 1)
        k, current = stop, target
    last = int(np.flatnonzero(hold)[-1]) + 1
    opening, hold = opening[:last], hold[:last]
    x = signal.lfilter(np.concatenate(([0.0], B_TRUE)), _den(F_TRUE), opening - 35.0)
    y = 250.0 + x + rng.normal(0.0, 10.0, last)
    t = 1.2 * np.arange(last)
    logged = np.where(hold, opening, np.nan)
    return record_from_arrays(t, logged, hold, np.full(last, 84.5), {"3F": y}, test="prbs")


def test_selection_picks_a_simulator_on_oe_data() -> None:
    sel = select_discrete(prbs_oe_record(9))
    fits = {c.structure: c for c in sel.candidates}
    assert [c.structure for c in sel.candidates] == ["arx", "oe", "armax", "bj"]
    assert sel.structure != "arx"
    assert fits["oe"].simulation.fit_percent > fits["arx"].simulation.fit_percent
    best = max(c.simulation.fit_percent for c in sel.candidates if c.stable)
    assert sel.chosen.simulation.fit_percent == best


@pytest.mark.parametrize("name", ["C", "D"])
def test_selection_on_bundled_records(name: str) -> None:
    record = read_record(f"{RECORDS}/{name}.csv")
    sel = select_discrete(record)
    fits = {c.structure: c for c in sel.candidates}
    # Equation-error ARX is biased by the coloured level noise; OE minimises the very
    # free-run error scored here (on the estimation part), so its hold-out fit must be
    # the better one. Measured: C 68.9 % vs 28.7 %, D 64.0 % vs 26.7 %.
    assert fits["oe"].simulation.fit_percent > fits["arx"].simulation.fit_percent
    # the ARX candidate is the paper's model exactly as identify_prbs reports it
    ident = identify_prbs(record)
    assert fits["arx"].fit.as_arx() == ident.fit
    assert fits["arx"].one_step.r2 == pytest.approx(ident.one_step.r2, rel=1e-12)
    assert fits["arx"].simulation == ident.simulation
    out = json.loads(json.dumps(sel.to_dict(), allow_nan=False))
    coeffs = out["simulation_coefficients"]
    assert out["structure"] == sel.structure in ("arx", "oe", "armax", "bj")
    assert coeffs["a"] == list(sel.chosen.fit.a) and coeffs["b"] == list(sel.chosen.fit.b)
    assert out["noise_model"]["simulated"] is False
    # the simulation coefficients drive the ARX free run unchanged
    sig = prbs_signals(record, "3F", rows="auto", holdout_fraction=0.3, spike_floor_mm=0.0)
    again = free_run_on_segments(sel.simulation_model, sig.u, sig.y, sig.fit_segments)[1]
    assert again == sel.chosen.simulation_full


def test_selection_reports_unknown_structures_and_gauges() -> None:
    record = read_record(f"{RECORDS}/D.csv")
    with pytest.raises(IdentificationError, match="structures"):
        select_discrete(record, structures=("arx", "ssm"))
    with pytest.raises(IdentificationError, match="no gauge"):
        select_discrete(record, gauge="9Z")
    only = select_discrete(record, structures=("arx",))
    assert only.structure == "arx" and len(only.candidates) == 1


def test_armax_reaches_the_lower_of_two_minima_on_record_d() -> None:
    # Record D's ARMAX(2,2,2,1) criterion has a local minimum next to the ARX start
    # (innovation variance ~3.0 mm² against ~2.8 mm² at the lower one); the
    # Hannan-Rissanen start must lead the default fit to the lower one.
    record = read_record(f"{RECORDS}/D.csv")
    sig = prbs_signals(record, "3F", rows="auto", holdout_fraction=0.3, spike_floor_mm=0.0)
    arx = fit_arx(sig.u, sig.y, sig.fit_segments, 2, 2, 1)
    from_arx_start = fit_armax(
        sig.u, sig.y, sig.fit_segments, 2, 2, 2, 1, start=arx.theta.tolist() + [0.0, 0.0]
    )
    default = fit_armax(sig.u, sig.y, sig.fit_segments, 2, 2, 2, 1)
    assert default.noise_variance_mm2 < 0.97 * from_arx_start.noise_variance_mm2
