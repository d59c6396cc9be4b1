"""MPC solve time: the condensed QP against the Opti + IPOPT formulation, in one run.

A closed loop (the demo's inflow step 40 → 60 m³/h with 0.7 mm gauge noise, on the Python
reference simulation of the demo plant, so that only the controller costs time) is driven
by the QP MPC. At every sample the very same :class:`~gatetwin.mpc.qp.MpcProblem` is also
handed to the other solvers ("shadow" solves), so all of them are timed on identical
problems, side by side:

1. QP (DAQP, warm-started: the default) against Opti + IPOPT at horizons 50, 100 and 200:
   median and p99 solve time, their ratio (target: QP >= 10x faster), p99 < 20 ms at a
   horizon >= 100, and the largest first-move difference (target < 1e-3 mm).
2. The QP solvers (DAQP through its package; qpOASES and OSQP through casadi) at the demo's
   horizon: which is fastest, and how far each one's first move is from qpOASES's. OSQP is
   shadowed only every ``--osqp-every`` samples: at these tolerances it takes ~1 s a solve.

3. The MPC re-linearised on the envelope at every sample against the single-point MPC,
   both driving the Python reference of the envelope FOPDT ``models/fopdt_3F.json``
   through the demo's ``wide_range`` scenario (120 → 300 mm at 50 m³/h, Q ±30 m³/h):
   solve and whole-step times side by side (the envelope's step includes the tangent, and
   a rebuild of the condensed QP whenever the tangent has moved by a grid step).

Times are wall-clock for the solver call alone (casadi ``conic`` or the Opti function);
the MPC's whole step (observer, condensing) is reported for the QP path too. Nothing is
asserted: the script prints and says which targets were met.

usage: python benchmarks/bench_mpc.py [--minutes 10] [--horizons 50 100 200] [--osqp-every 10]
       [--wide-minutes 30] [--only-envelope] [--save]

``--save`` keeps parts 1 and 3 in ``docs/results/mpc_solve.json`` for the MPC page.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from gatetwin.modelfile import read_model_file
from gatetwin.mpc import (
    DemoSettings,
    LoopPlant,
    ModelCore,
    MpcController,
    MpcProblem,
    MpcSettings,
    MpcSolution,
    OptiBackend,
    QpBackend,
    demo_plant,
    demo_scenarios,
    loop_metrics,
    run_closed_loop,
    wide_scenario,
)

#: The envelope FOPDT of gauge 3F identified from the bundled records.
MODEL_3F = Path(__file__).resolve().parents[1] / "models" / "fopdt_3F.json"
TARGET_RATIO = 10.0
TARGET_P99_MS = 20.0
TARGET_DIFF_MM = 1e-3


@dataclass
class Shadow:
    """A named solver timed on the problems the loop's QP sees."""

    name: str
    backend: QpBackend | OptiBackend
    every: int = 1
    times_s: list[float] = field(default_factory=list)
    diffs_mm: list[float] = field(default_factory=list)
    failures: int = 0


class ShadowedBackend:
    """The loop's QP backend; every problem is also solved by each shadow."""

    def __init__(self, primary: QpBackend, shadows: list[Shadow]) -> None:
        self.primary = primary
        self.shadows = shadows
        self.times_s: list[float] = []
        self.shadow_s: list[float] = []  # wall time spent in shadows, per loop sample
        self.count = -1  # the controller's priming solve at reset() is not counted

    def solve(self, problem: MpcProblem) -> MpcSolution:
        solution = self.primary.solve(problem)
        start = time.perf_counter()
        if self.count >= 0:
            self.times_s.append(solution.solve_s)
            self._shadow(problem, solution)
            self.shadow_s.append(time.perf_counter() - start)
        self.count += 1
        return solution

    def _shadow(self, problem: MpcProblem, solution: MpcSolution) -> None:
        for shadow in self.shadows:
            if self.count % shadow.every:
                continue
            other = shadow.backend.solve(problem)
            shadow.times_s.append(other.solve_s)
            shadow.diffs_mm.append(abs(other.first_move_mm - solution.first_move_mm))
            shadow.failures += not other.success


def closed_loop(settings: MpcSettings, shadows: list[Shadow], minutes: float):
    demo = replace(DemoSettings(), mpc=settings)
    plant_model = demo_plant()
    scenario = next(s for s in demo_scenarios(minutes, demo) if s.name == "inflow_step")
    controller = MpcController(plant_model, settings)
    backend = ShadowedBackend(controller.backend, shadows)
    controller.backend = backend
    plant = LoopPlant(ModelCore(plant_model), noise=demo.noise)
    run = run_closed_loop(
        plant,
        controller,
        scenario,
        level_band_mm=settings.level_band_mm,
        max_move_mm=settings.max_move_mm,
        opening_range_mm=settings.opening_range_mm,
    )
    return np.array(backend.times_s), run.step_s - np.array(backend.shadow_s)


def ms(values) -> tuple[float, float]:
    arr = np.asarray(values) * 1e3
    return float(np.median(arr)), float(np.percentile(arr, 99))


def qp_against_ipopt(horizons: list[int], minutes: float) -> list[dict]:
    print("1. condensed QP (DAQP, warm start) vs Opti + IPOPT, same problems, one run")
    print(f"   inflow step, {minutes:g} min at 1.2 s, Python FOPDT plant, noise 0.7 mm")
    head = (
        f"{'N':>5} {'QP med':>8} {'QP p99':>8} {'QP max':>8} {'at t s':>7} {'step p99':>9} "
        f"{'IPOPT med':>10} "
        f"{'IPOPT p99':>10} {'ratio med':>10} {'ratio p99':>10} {'max|Δu0| mm':>12}"
    )
    print(head)
    verdicts, rows = [], []
    for n in horizons:
        settings = MpcSettings(horizon=n)
        ipopt = Shadow("ipopt", OptiBackend(settings))
        qp_s, step_s = closed_loop(settings, [ipopt], minutes)
        qp_med, qp_p99 = ms(qp_s)
        ip_med, ip_p99 = ms(ipopt.times_s)
        _, step_p99 = ms(step_s)
        diff = max(ipopt.diffs_mm)
        print(
            f"{n:>5} {qp_med:>8.2f} {qp_p99:>8.2f} {np.max(qp_s) * 1e3:>8.1f} "
            f"{np.argmax(qp_s) * 1.2:>7.1f} {step_p99:>9.2f} {ip_med:>10.1f} "
            f"{ip_p99:>10.1f} {ip_med / qp_med:>9.0f}x {ip_p99 / qp_p99:>9.0f}x {diff:>12.1e}"
        )
        verdicts.append((n, ip_med / qp_med, qp_p99, diff, ipopt.failures))
        rows.append({"horizon": n, "qp_ms": [qp_med, qp_p99], "ipopt_ms": [ip_med, ip_p99],
                     "max_first_move_difference_mm": float(diff),
                     "ipopt_failures": ipopt.failures})  # fmt: skip
    print(
        f"   (ms; 'step' = the MPC's whole step: observer, condensing and solve; the inflow\n"
        f"   steps at t = {minutes * 10:g} s: the Hessian changes and the solver starts over)"
    )
    for n, ratio, p99, diff, fails in verdicts:
        p99_note = f"p99 {p99:.1f} ms < {TARGET_P99_MS:g} ms: {p99 < TARGET_P99_MS}"
        print(
            f"   N={n}: QP >= {TARGET_RATIO:g}x faster: {ratio >= TARGET_RATIO}; "
            f"{p99_note if n >= 100 else 'p99 target applies at N >= 100'}; "
            f"first moves agree < {TARGET_DIFF_MM:g} mm: {diff < TARGET_DIFF_MM}; "
            f"IPOPT failures: {fails}"
        )
    return rows


def qp_solvers(horizon: int, minutes: float, osqp_every: int) -> None:
    print(f"\n2. QP solvers at N={horizon} on the same problems (first move vs qpOASES)")
    settings = MpcSettings(horizon=horizon, qp_solver="qpoases")
    shadows = [
        Shadow("daqp", QpBackend(replace(settings, qp_solver="daqp"))),
        Shadow("osqp", QpBackend(replace(settings, qp_solver="osqp")), every=osqp_every),
    ]
    start = time.perf_counter()
    qp_s, _ = closed_loop(settings, shadows, minutes)
    print(f"{'solver':>8} {'solves':>7} {'median ms':>10} {'p99 ms':>8} {'max|Δu0| mm':>12} "
          f"{'failed':>7}")  # fmt: skip
    med, p99 = ms(qp_s)
    print(f"{'qpoases':>8} {len(qp_s):>7} {med:>10.2f} {p99:>8.2f} {0.0:>12.1e} {0:>7}")
    for sh in shadows:
        med, p99 = ms(sh.times_s)
        print(
            f"{sh.name:>8} {len(sh.times_s):>7} {med:>10.2f} {p99:>8.2f} "
            f"{max(sh.diffs_mm):>12.1e} {sh.failures:>7}"
        )
    print(f"   ({time.perf_counter() - start:.0f} s)")


def envelope_against_single_point(minutes: float) -> dict:
    print(f"\n3. envelope MPC vs single-point MPC, wide_range, {minutes:g} min, N = "
          f"{MpcSettings().horizon}, Python envelope FOPDT plant, noise 0.7 mm")  # fmt: skip
    plant_model = read_model_file(MODEL_3F).plant
    demo = DemoSettings()
    scenario = wide_scenario(plant_model, minutes, demo)
    rows = {}
    for linearisation in ("schedule", "envelope"):
        controller = MpcController(plant_model, demo.mpc, linearisation=linearisation)
        plant = LoopPlant(ModelCore(plant_model), noise=demo.noise)
        run = run_closed_loop(
            plant,
            controller,
            scenario,
            level_band_mm=demo.mpc.level_band_mm,
            max_move_mm=demo.mpc.max_move_mm,
            opening_range_mm=demo.mpc.opening_range_mm,
        )
        rows[linearisation] = (ms(run.solve_s), ms(run.step_s), loop_metrics(run))
    print(f"{'MPC':>13} {'solve med':>10} {'solve p99':>10} {'step med':>9} {'step p99':>9} "
          f"{'IAE mm·s':>9} {'violations':>10}")  # fmt: skip
    for name, ((s_med, s_p99), (st_med, st_p99), m) in rows.items():
        label = "single-point" if name == "schedule" else "envelope"
        print(f"{label:>13} {s_med:>10.2f} {s_p99:>10.2f} {st_med:>9.2f} {st_p99:>9.2f} "
              f"{m['iae']:>9.0f} {m['violations']:>10}")  # fmt: skip
    (s0, _), (t0, t0_99), m0 = rows["schedule"]
    (s1, _), (t1, t1_99), m1 = rows["envelope"]
    print(
        f"   envelope / single-point: solve median {s1 / s0:.2f}x, step median "
        f"{t1 / t0:.2f}x, step p99 {t1_99 / t0_99:.2f}x, IAE {m1['iae'] / m0['iae']:.3f}"
    )
    return {name: {"solve_ms": list(solve), "step_ms": list(step), "iae": float(m["iae"]),
                   "violations": int(m["violations"])}
            for name, (solve, step, m) in rows.items()}  # fmt: skip


def warm_up(horizons: list[int]) -> None:
    """A short loop at each horizon first: a process's first solves at a new problem size
    pay one-off costs (first touch of fresh memory, library start-up: tens of ms in this
    VM) that are not the solver's."""
    for n in sorted(set(horizons), reverse=True):
        closed_loop(MpcSettings(horizon=n), [], 2.0)


def report(data: dict) -> str:
    """Parts 1 and 3 as Markdown (printed last, and the MPC page's generated block)."""
    lines = []
    if data.get("qp_against_ipopt"):
        lines += ["| horizon N | QP median / p99 (ms) | IPOPT median / p99 (ms) | ratio (median) "
                  "| max first-move difference |", "|---|---|---|---|---|"]  # fmt: skip
        for r in data["qp_against_ipopt"]:
            (qm, q99), (im, i99) = r["qp_ms"], r["ipopt_ms"]
            diff = r["max_first_move_difference_mm"]
            lines.append(f"| {r['horizon']} | {qm:.2f} / {q99:.2f} | {im:.1f} / {i99:.1f} | "
                         f"{im / qm:.0f}× | {diff:.1e} mm |")  # fmt: skip
        lines += ["", f"Inflow step, {data['minutes']:g} min at 1.2 s, the same problems for "
                  "both solvers.", ""]  # fmt: skip
    env = data["envelope"]
    lines += ["| MPC | solve median / p99 (ms) | whole step median / p99 (ms) | IAE (mm·s) |",
              "|---|---|---|---|"]  # fmt: skip
    for key, label in (("schedule", "single-point"), ("envelope", "envelope")):
        (sm, s99), (tm, t99) = env[key]["solve_ms"], env[key]["step_ms"]
        lines.append(f"| {label} | {sm:.2f} / {s99:.1f} | {tm:.2f} / {t99:.1f} | "
                     f"{env[key]['iae']:.0f} |")  # fmt: skip
    ratio = env["envelope"]["step_ms"][0] / env["schedule"]["step_ms"][0]
    lines += ["", f"`wide_range`, {data['wide_minutes']:g} min, N = {data['envelope_horizon']}; "
              f"the envelope's median step is {ratio:.2f}× the single-point's."]  # fmt: skip
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--horizons", type=int, nargs="+", default=[50, 100, 200])
    parser.add_argument("--osqp-every", type=int, default=10)
    parser.add_argument("--wide-minutes", type=float, default=30.0)
    parser.add_argument("--only-envelope", action="store_true",
                        help="run part 3 only")  # fmt: skip
    parser.add_argument("--save", action="store_true",
                        help="keep parts 1 and 3 in docs/results/mpc_solve.json")  # fmt: skip
    args = parser.parse_args(argv)
    warm_up([*args.horizons, MpcSettings().horizon])
    data = {"minutes": args.minutes, "wide_minutes": args.wide_minutes,
            "envelope_horizon": MpcSettings().horizon, "qp_against_ipopt": []}  # fmt: skip
    if not args.only_envelope:
        data["qp_against_ipopt"] = qp_against_ipopt(args.horizons, args.minutes)
        qp_solvers(MpcSettings().horizon, args.minutes, args.osqp_every)
    data["envelope"] = envelope_against_single_point(args.wide_minutes)
    print("\n" + report(data))
    if args.save:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from results import save

        print(save("mpc_solve", data, "python benchmarks/bench_mpc.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip


if __name__ == "__main__":
    main()
