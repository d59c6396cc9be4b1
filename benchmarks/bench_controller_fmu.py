"""Cost of one step of the MPC controller FMU (C, casadi-generated) against the Python MPC.

A small C host (bench_controller_host.c, compiled here against the FMU's own sources) steps
the controller FMU in a closed loop with set-point steps (rate limit active through each
transient) and prints the doStep time percentiles, the share of samples with active
constraints, the fallbacks, the mean qrqp iterations, ``sizeof(ModelData)`` and the heap the
FMU takes (at instantiation; during the steps). The Python controller
(:class:`gatetwin.mpc.MpcController`, qpOASES, then qrqp) runs the same loop in the same
process; the ratios are printed side by side, never asserted.

usage: python benchmarks/bench_controller_fmu.py [--horizon 100] [--steps 400] [--python-steps 400]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from fmpy import extract, platform, read_model_description, sharedLibraryExtension

from gatetwin.fmu.c_build import find_compiler
from gatetwin.fmu.mpc_controller import export_mpc_controller
from gatetwin.mpc import MpcController, MpcSettings, demo_plant

HERE = Path(__file__).parent


def build_host(sources: Path, out: Path) -> None:
    cmd = [*find_compiler(), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{sources}",
           "-o", str(out), str(HERE / "bench_controller_host.c"), "-ldl", "-lm"]  # fmt: skip
    subprocess.run(cmd, check=True)


def run_host(host: Path, extracted: Path, steps: int) -> dict[str, float]:
    md = read_model_description(str(extracted))
    binary = extracted / "binaries" / platform / (md.coSimulation.modelIdentifier
                                                  + sharedLibraryExtension)  # fmt: skip
    done = subprocess.run([str(host), str(binary), (extracted / "resources").as_uri(),
                           str(steps)], capture_output=True, text=True, check=False)  # fmt: skip
    if done.returncode != 0:
        raise RuntimeError(f"host failed ({done.returncode}): {done.stderr.strip()[-500:]}")
    return {k: float(v) for k, v in (line.split() for line in done.stdout.splitlines())}


def python_loop(settings: MpcSettings, steps: int) -> np.ndarray:
    """The host's loop with the Python controller; seconds per controller step."""
    plant = demo_plant()
    mpc = MpcController(plant, settings, linearisation="schedule")
    level, keep = 190.0, math.exp(-settings.sample_period_s / 62.0)
    mpc.reset(25.0, level, 40.0)
    out = np.empty(steps)
    for k in range(steps):
        start = time.perf_counter()
        opening = mpc.step(level, 40.0, 210.0 if (k // 100) % 2 else 190.0)
        out[k] = time.perf_counter() - start
        level = keep * level + (1.0 - keep) * (190.0 - 13.6 * (opening - 25.0))
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--horizon", type=int, default=100)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--python-steps", type=int, default=400)
    args = parser.parse_args(argv)
    settings = replace(MpcSettings(), horizon=args.horizon)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        start = time.perf_counter()
        fmu = export_mpc_controller(demo_plant(), folder / "bench_mpc.fmu", settings=settings)
        export_s = time.perf_counter() - start
        extracted = Path(extract(str(fmu), str(folder / "x")))
        host = folder / "host"
        build_host(extracted / "sources", host)
        c = run_host(host, extracted, args.steps)
    py = {name: python_loop(replace(settings, qp_solver=name), args.python_steps)
          for name in ("qpoases", "qrqp")}  # fmt: skip
    print(f"horizon {args.horizon}, export + compile {export_s:.1f} s")
    print(f"C FMU doStep over {args.steps} steps: p50 {c['p50_ns'] / 1e6:.3f} ms, "
          f"p99 {c['p99_ns'] / 1e6:.3f} ms, max {c['max_ns'] / 1e6:.3f} ms; rate, range or band "
          f"constraints active at {100 * c['active_share']:.0f} % of samples, "
          f"{c['fallbacks']:.0f} fallbacks, {c['mean_iterations']:.1f} qrqp iterations a step "
          "on average")
    for name, s in py.items():
        p50, p99 = np.percentile(s, 50), np.percentile(s, 99)
        print(f"Python MpcController ({name}) over {args.python_steps} steps: p50 "
              f"{p50 * 1e3:.3f} ms, p99 {p99 * 1e3:.3f} ms, max {s.max() * 1e3:.3f} ms; "
              f"C FMU / Python p50 = {c['p50_ns'] / 1e9 / p50:.3g}, "
              f"p99 = {c['p99_ns'] / 1e9 / p99:.3g}")
    print(f"static memory: sizeof(ModelData) = {c['sizeof_modeldata'] / 1e6:.3f} MB; heap "
          f"through the FMI callbacks: {c['heap_at_instantiation_bytes'] / 1e6:.3f} MB at "
          f"instantiation, {c['heap_during_steps_bytes']:.0f} bytes during the steps")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
