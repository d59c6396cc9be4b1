"""Virtual-flume speed: simulated time / wall time at dx = 5 cm over a 3000 s run.

Run: ``python benchmarks/bench_flume.py``. Prints the real-time ratio of the compiled
solver (target >= 500x on one core) and, side by side in the same run, of a vectorised
numpy version of the same time step (why the solver is compiled with numba).
"""

from __future__ import annotations

import time

import numpy as np

from gatetwin.flume import FlumeConfig, run_flume, spin_up
from gatetwin.flume.gate import G
from gatetwin.flume.solver import Grid, time_step_s

SIM_S = 3000.0


def numpy_step(h: np.ndarray, q: np.ndarray, bed: np.ndarray, r: float, q_in: float) -> None:
    """One HLL/hydrostatic-reconstruction step written with numpy array operations."""
    zs = np.maximum(bed[:-1], bed[1:])
    hl = np.maximum(0.0, h[:-1] + bed[:-1] - zs)
    hr = np.maximum(0.0, h[1:] + bed[1:] - zs)
    ul, ur = q[:-1] / h[:-1], q[1:] / h[1:]
    cl, cr = np.sqrt(G * hl), np.sqrt(G * hr)
    sl = np.minimum(ul - cl, ur - cr)
    sr = np.maximum(ul + cl, ur + cr)
    fl0, fl1 = hl * ul, hl * ul * ul + 0.5 * G * hl * hl
    fr0, fr1 = hr * ur, hr * ur * ur + 0.5 * G * hr * hr
    inv = 1.0 / (sr - sl)
    f0 = (sr * fl0 - sl * fr0 + sl * sr * (hr - hl)) * inv
    f1 = (sr * fl1 - sl * fr1 + sl * sr * (hr * ur - hl * ul)) * inv
    flux0 = np.concatenate([[q_in], f0, [q_in]])
    left = np.concatenate([f1 + 0.5 * G * (h[:-1] ** 2 - hl**2), [0.5 * G * h[-1] ** 2]])
    right = np.concatenate([[0.5 * G * h[0] ** 2], f1 + 0.5 * G * (h[1:] ** 2 - hr**2)])
    h -= r * (flux0[1:] - flux0[:-1])
    q -= r * (left - right)


def main() -> None:
    cfg = FlumeConfig(dx_m=0.05)
    n = int(SIM_S / cfg.sample_period_s) + 1
    state = spin_up(cfg, 40.0, 20.0, duration_s=12.0)  # also compiles the solver
    cmd = np.where((np.arange(n) // 200) % 2 == 0, 20.0, 25.0)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        run_flume(cfg, cmd, np.full(n, 40.0), state=state)
        best = min(best, time.perf_counter() - t0)
    grid = Grid.of(cfg)
    dt, n_sub = time_step_s(cfg, grid)
    h, q = state.depth_m.copy(), state.unit_discharge_m2s.copy()
    steps = 20 * n_sub
    t0 = time.perf_counter()
    for _ in range(steps):
        numpy_step(h, q, grid.bed_m, dt / grid.dx_m, 40.0 / 3600 / cfg.width_m)
    numpy_per_step = (time.perf_counter() - t0) / steps
    numpy_ratio = dt / numpy_per_step
    print(f"cells: {grid.n_cells}, dt = {dt * 1000:.2f} ms, steps: {n_sub * (n - 1)}")
    print(f"numba solver: {SIM_S:.0f} s simulated in {best:.3f} s wall "
          f"-> {SIM_S / best:.0f}x real time (target >= 500x)")  # fmt: skip
    print(f"numpy step:   {numpy_per_step * 1e6:.1f} us/step -> {numpy_ratio:.0f}x real time")
    print(f"numba / numpy speed ratio: {SIM_S / best / numpy_ratio:.0f}x")


if __name__ == "__main__":
    main()
