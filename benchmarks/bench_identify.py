"""Timing of the identification methods (prints; never asserts).

1. ARX(2,2,1) at 1e6 samples: :func:`gatetwin.identification.fit_arx` (normal equations from
   lagged dot products) against ``numpy.linalg.lstsq`` on the explicitly built regressor of
   the same rows, in the same run, with the ratio. Two layouts: all samples with the
   opening reconstructed (segments cut at logging gaps and NaNs), and hold rows only
   with ARX(2,1,1) (about 26 000 hold segments; nb = 2 is not identifiable there).
2. The full 75-model order search at 1e5 samples.
3. The least-squares FOPDT fit (and the paper's method) on one step record.

Run: ``python benchmarks/bench_identify.py [--samples N] [--order-samples N] [--save]``
(``--save`` keeps the numbers in ``docs/results/identify.json`` for the identification
page). Times are the best of a few repeats (``time.perf_counter``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from gatetwin.identification import (
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


def compare_arx(u: np.ndarray, y: np.ndarray, segs: np.ndarray, orders: tuple) -> dict:
    t_dot, fit = best_of(lambda: fit_arx(u, y, segs, *orders), 5)
    t_build, (x, rhs) = best_of(lambda: explicit_regressor(u, y, segs, *orders), 3)
    t_solve, theta = best_of(lambda: np.linalg.lstsq(x, rhs, rcond=None)[0], 3)
    diff = np.linalg.norm(fit.theta - theta) / np.linalg.norm(theta)
    return {"orders": list(orders), "rows": int(fit.n_rows), "segments": len(segs),
            "dot_s": t_dot, "lstsq_build_s": t_build, "lstsq_solve_s": t_solve,
            "relative_theta_difference": float(diff)}  # fmt: skip


def bench_arx(samples: int) -> dict:
    d = prbs_data(samples)
    u = reconstructed_opening(d["t"], d["e"], d["hold"])
    every = continuous_segments(d["t"], TS)
    holds = hold_segments(d["hold"])
    return {"all samples": compare_arx(u, d["y"], every, (2, 2, 1)),
            "hold rows": compare_arx(d["e"], d["y"], holds, (2, 1, 1))}  # fmt: skip


def bench_orders(samples: int) -> dict:
    d = prbs_data(samples, seed=1)
    u = reconstructed_opening(d["t"], d["e"], d["hold"])
    segs = continuous_segments(d["t"], TS)
    elapsed, table = best_of(lambda: search_orders(u, d["y"], segs, time_s=d["t"]), 3)
    return {"samples": samples, "models": len(table), "seconds": elapsed}


def bench_fopdt() -> dict:
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
    return {"samples": int(fit.n), "least_squares_s": t_fit, "paper_method_s": t_paper,
            "gain_mm_per_mm": fit.gain_mm_per_mm, "dead_time_s": fit.dead_time_s,
            "time_constant_s": fit.time_constant_s}  # fmt: skip


def report(data: dict) -> str:
    """The benchmark's numbers as Markdown (printed, and the identification page's block)."""
    lines = ["| ARX, rows | dot products (ms) | `lstsq` regressor build + solve (ms) | ratio | "
             "ratio to the solve alone | θ difference (relative) |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for label, r in data["arx"].items():
        build, solve, dot = r["lstsq_build_s"], r["lstsq_solve_s"], r["dot_s"]
        orders = ",".join(str(o) for o in r["orders"])
        lines.append(f"| ARX({orders}), {label} ({r['rows']:,} rows, {r['segments']:,} segments) "
                     f"| {1e3 * dot:.1f} | {1e3 * build:.1f} + {1e3 * solve:.1f} | "
                     f"{(build + solve) / dot:.1f}× | {solve / dot:.1f}× | "
                     f"{r['relative_theta_difference']:.1e} |")  # fmt: skip
    o, f = data["orders"], data["fopdt"]
    return "\n".join(lines) + (
        f"\n\nARX data: {data['arx_samples']:,} samples. Order search, {o['models']} models, "
        f"{o['samples']:,} samples: {1e3 * o['seconds']:.0f} ms. FOPDT on one step record "
        f"({f['samples']} samples): least-squares fit {1e3 * f['least_squares_s']:.1f} ms, "
        f"the paper's method {1e3 * f['paper_method_s']:.1f} ms. Best of 3–5 repeats.\n"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="ARX data length")
    parser.add_argument("--order-samples", type=int, default=100_000)
    parser.add_argument(
        "--save", action="store_true", help="keep the numbers in docs/results/identify.json"
    )
    args = parser.parse_args(argv)
    data = {"arx_samples": args.samples, "arx": bench_arx(args.samples),
            "orders": bench_orders(args.order_samples), "fopdt": bench_fopdt()}  # fmt: skip
    print(report(data))
    if args.save:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from results import save

        print(save("identify", data, "python benchmarks/bench_identify.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


if __name__ == "__main__":
    main()
