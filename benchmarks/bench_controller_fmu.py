"""Cost of one step of the MPC controller FMU (C, casadi-generated) against the Python MPC.

A small C host (bench_controller_host.c, compiled here against the FMU's own sources) steps
the controller FMU in a closed loop with set-point steps (rate limit active through each
transient) and prints the doStep time percentiles, the share of samples with active
constraints, the fallbacks, the mean and largest QP iterations, ``sizeof(ModelData)`` and the
heap the FMU takes (at instantiation; during the steps). The Python controller
(:class:`gatetwin.mpc.MpcController`, qpOASES) runs the same loop in the same process; the
numbers are printed side by side, never asserted.

usage: python benchmarks/bench_controller_fmu.py [--horizon 100] [--steps 400]
       [--python-steps 400] [--save]
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
#: The host's set-point cycle, 100 samples each (bench_controller_host.c).
SETPOINTS_MM = (190.0, 210.0, 190.0, 340.0)


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
        opening = mpc.step(level, 40.0, SETPOINTS_MM[(k // 100) % len(SETPOINTS_MM)])
        out[k] = time.perf_counter() - start
        level = keep * level + (1.0 - keep) * (190.0 - 13.6 * (opening - 25.0))
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--horizon", type=int, default=100)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--python-steps", type=int, default=400)
    parser.add_argument(
        "--save", action="store_true", help="keep the numbers in docs/results/controller_fmu.json"
    )
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
    py = python_loop(replace(settings, qp_solver="qpoases"), args.python_steps)
    data = {"horizon": args.horizon, "steps": args.steps, "export_s": export_s,
            "fmu": c, "python_qpoases_ms": {"p50": float(np.percentile(py, 50)) * 1e3,
                                            "p99": float(np.percentile(py, 99)) * 1e3,
                                            "max": float(py.max()) * 1e3}}  # fmt: skip
    print(report(data))
    if args.save:
        sys.path.insert(0, str(HERE))
        from results import save

        print(save("controller_fmu", data, "python benchmarks/bench_controller_fmu.py "
                   + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip
    sys.stdout.flush()


#: The host's phases: all samples, the +-20 mm set-point steps, the 150 mm one.
PHASES = (("all samples", ""), ("+-20 mm steps", "small_steps_"), ("150 mm step", "large_step_"))


def report(data: dict) -> str:
    """The benchmark's numbers as Markdown (printed, and the README's generated block)."""
    c, py = data["fmu"], data["python_qpoases_ms"]
    lines = ["| samples | doStep p50 (ms) | p99 (ms) | max (ms) |", "|---|---|---|---|"]
    for label, key in PHASES:
        lines.append(f"| {label} | {c[key + 'p50_ns'] / 1e6:.3f} | {c[key + 'p99_ns'] / 1e6:.3f}"
                     f" | {c[key + 'max_ns'] / 1e6:.3f} |")  # fmt: skip
    lines.append(f"| Python `MpcController` (qpOASES), all samples | {py['p50']:.3f} | "
                 f"{py['p99']:.3f} | {py['max']:.3f} |")  # fmt: skip
    return "\n".join(lines) + (
        f"\n\nHorizon {data['horizon']}, {data['steps']} samples; export with the compile "
        f"{data['export_s']:.0f} s. Rate, range or band constraints active at "
        f"{100 * c['active_share']:.0f} % of the samples; {c['fallbacks']:.0f} fallbacks; QP "
        f"iterations {c['mean_iterations']:.1f} a sample on average, {c['max_iterations']:.0f} "
        f"at most. `sizeof(ModelData)` {c['sizeof_modeldata'] / 1e6:.2f} MB, all of it "
        f"allocated at instantiation; {c['heap_during_steps_bytes']:.0f} bytes of heap during "
        "the steps.\n"
    )


if __name__ == "__main__":
    main()
