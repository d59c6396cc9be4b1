"""Timing of the identification methods (prints; never asserts).

1. ARX(2,2,1) at 1e6 samples: :func:`gatetwin.identify.fit_arx` (normal equations from
   lagged dot products) against ``numpy.linalg.lstsq`` on the explicitly built regressor of
   the same rows, in the same run, with the ratio. Two layouts: all samples with the
   opening reconstructed (segments cut at logging gaps and NaNs), and hold rows only
   with ARX(2,1,1) (about 26 000 hold segments; nb = 2 is not identifiable there).
2. The full 75-model order search at 1e5 samples.
3. The least-squares FOPDT fit (and the paper's method) on one step record.

Run: ``python benchmarks/bench_identify.py``. Times are the best of a few repeats
(``time.perf_counter``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy import signal

from gatetwin.identify import (
    continuous_segments,
    fit_arx,
    fit_fopdt,
    paper_step_method,
    reconstructed_opening,
    search_orders,
    split_segments,
)

TS = 1.2


def best_of(func: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Smallest wall time of ``repeats`` calls, s, and the last result."""
    best, out = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - start)
    return best, out


def prbs_data(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """ARX(2,2,1) response to a random-duration square wave with open ramps."""
    rng = np.random.default_rng(seed)
    lengths = rng.integers(10, 61, n // 20)
    ramps = rng.integers(2, 6, lengths.size)
    opening, hold = [], []
    level = 40.0
    for hold_len, ramp in zip(lengths, ramps, strict=True):
        target = 30.0 if level > 35.0 else 40.0
        opening += [
            np.full(hold_len, level),
            level + (target - level) * np.arange(1, ramp + 1) / (ramp + 1),
        ]
        hold += [np.ones(hold_len, bool), np.zeros(ramp, bool)]
        level = target
    e = np.concatenate(opening)[:n]
    h = np.concatenate(hold)[:n]
    a_poly, b_poly = [1.0, -1.2, 0.3], [0.0, -1.5, -0.8]
    y = signal.lfilter(b_poly, a_poly, e - 35.0) + signal.lfilter(
        [1.0], a_poly, rng.normal(0, 0.5, n)
    )
    y = 250.0 + y
    y[rng.choice(n, n // 1000, replace=False)] = np.nan
    dt = np.full(n, TS)
    dt[rng.choice(np.arange(1, n), n // 5000, replace=False)] = 10 * TS  # logging gaps
    t = np.cumsum(dt) - TS
    return {"t": t, "e": np.where(h, e, np.nan), "hold": h, "y": y}


def hold_segments(hold: np.ndarray) -> np.ndarray:
    edges = np.diff(np.concatenate(([0], hold.astype(np.int8), [0])))
    return np.column_stack((np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def explicit_regressor(
    u: np.ndarray, y: np.ndarray, segments: np.ndarray, na: int, nb: int, nk: int
) -> tuple[np.ndarray, np.ndarray]:
    """The regression of :func:`fit_arx`, built the usual way (one column per lag)."""
    clean = split_segments(segments, u, y)
    lengths = clean[:, 1] - clean[:, 0]
    inside = (
        np.repeat(clean[:, 0], lengths)
        + np.arange(lengths.sum())
        - np.repeat(np.cumsum(lengths) - lengths, lengths)
    )
    uu, yy = u - u[inside].mean(), y - y[inside].mean()
    m = max(na, nk + nb - 1)
    keep = lengths > m
    starts, counts = clean[keep, 0] + m, lengths[keep] - m
    rows = (
        np.repeat(starts, counts)
        + np.arange(counts.sum())
        - np.repeat(np.cumsum(counts) - counts, counts)
    )
    cols = [yy[rows - i] for i in range(1, na + 1)] + [uu[rows - nk - j] for j in range(nb)]
    return np.column_stack(cols), yy[rows]


def compare_arx(label: str, u: np.ndarray, y: np.ndarray, segs: np.ndarray, orders: tuple) -> None:
    t_dot, fit = best_of(lambda: fit_arx(u, y, segs, *orders), 5)
    t_build, (x, rhs) = best_of(lambda: explicit_regressor(u, y, segs, *orders), 3)
    t_solve, theta = best_of(lambda: np.linalg.lstsq(x, rhs, rcond=None)[0], 3)
    diff = np.linalg.norm(fit.theta - theta) / np.linalg.norm(theta)
    print(f"ARX{orders} {label}: {fit.n_rows} rows, {len(segs)} segments")
    print(f"  dot-product normal equations : {1e3 * t_dot:8.1f} ms")
    print(f"  lstsq, regressor build       : {1e3 * t_build:8.1f} ms")
    print(f"  lstsq, solve                 : {1e3 * t_solve:8.1f} ms")
    print(f"  ratio lstsq (build + solve) / dot : {(t_build + t_solve) / t_dot:6.1f} x")
    print(f"  ratio lstsq (solve only) / dot    : {t_solve / t_dot:6.1f} x")
    print(f"  |theta_dot - theta_lstsq| / |theta| = {diff:.1e}")


def bench_arx() -> None:
    d = prbs_data(1_000_000)
    u = reconstructed_opening(d["t"], d["e"], d["hold"])
    compare_arx("all samples", u, d["y"], continuous_segments(d["t"], TS), (2, 2, 1))
    compare_arx("hold rows", d["e"], d["y"], hold_segments(d["hold"]), (2, 1, 1))


def bench_orders() -> None:
    d = prbs_data(100_000, seed=1)
    u = reconstructed_opening(d["t"], d["e"], d["hold"])
    segs = continuous_segments(d["t"], TS)
    elapsed, table = best_of(lambda: search_orders(u, d["y"], segs, time_s=d["t"]), 3)
    print(f"order search, {len(table)} models, 1e5 samples: {1e3 * elapsed:8.1f} ms")


def bench_fopdt() -> None:
    rng = np.random.default_rng(2)
    n = 100 + 2 + 500
    t = TS * np.arange(n)
    onset = t[100] - 0.5
    h = 230.0 - 77.0 * -np.expm1(-np.maximum(t - onset - 4.5, 0.0) / 71.0)
    h += rng.normal(0.0, 0.35, n)
    hold = np.ones(n, bool)
    hold[100:102] = False
    t_paper, paper = best_of(lambda: paper_step_method(t, h, hold, t[100], n, 5.0), 5)
    mask = hold & (np.arange(n) >= paper.pre_start_index)
    t_fit, fit = best_of(lambda: fit_fopdt(t, h, mask, t[100], 5.0, paper.pre_mean_mm), 5)
    print(f"FOPDT on one step record ({fit.n} samples):")
    print(
        f"  least-squares fit : {1e3 * t_fit:8.1f} ms  (K {fit.gain_mm_per_mm:.2f}, "
        f"L {fit.dead_time_s:.2f} s, T {fit.time_constant_s:.1f} s)"
    )
    print(f"  paper's method    : {1e3 * t_paper:8.1f} ms")


def main() -> None:
    bench_arx()
    bench_orders()
    bench_fopdt()


if __name__ == "__main__":
    main()
