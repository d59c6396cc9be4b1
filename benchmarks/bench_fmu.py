"""Cost of one communication step of the C and the pythonfmu FMU of the FOPDT test plant.

Two measurements, printed with their ratios (never asserted):

1. A tiny C host (bench_host.c, dlopen of the FMU binary) times N doStep calls: ns per
   doStep for the C FMU (target <= 50 ns, schedule interpolation included) and the pythonfmu
   FMU (the host loads libpython first; found through sysconfig), and their ratio
   (target >= 100x). Next to them, the bare reference (bench_bare.c, compiled in the same
   run with the FMU's flags): the same exact FOPDT step, its parameters fixed at the held
   discharge, nothing around it; the C FMU's setReal + doStep + getReal over it is the price
   of the FMI interface, the schedule and the checks (target <= 3x). The host also times the
   opening changed at every step instead of every 7th: what a step derives from the opening
   (an envelope model's steady level, kept in the FMU's step cache) is then derived anew at
   every step, the cache's worst case (a FOPDT's step then also holds an input arriving
   after the dead time: two exact pieces instead of one).
2. The same FMUs through fmpy's FMU2Slave (setReal + doStep + getReal per step): steps per
   second, next to fmpy's own overhead (an empty loop and a getReal-only loop).

``--families`` instead times the C FMU of every family in one run (the test plant's FOPDT,
the twin of the bare step, and the bundled ``models/`` fopdt_3F and arx_3F, whose envelopes
derive a steady point from the opening, and physical_3F) beside the bare FOPDT: per
setReal + doStep + getReal with the opening changed every 7 steps, changed at every step,
and moving by 0.1 mm at every step (a controller's output; the discharge held), each with
its ratio to the bare step.

``--save`` keeps those numbers in ``docs/results/fmu_steps.json`` (the benchmarks page's
table is rendered from it).

usage: python benchmarks/bench_fmu.py [--model MODEL.json | --families [--save]]
       [--n-c 5000000] [--n-python 20000] [--n-fmpy 20000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path
from typing import Any

from fmpy import extract, platform, read_model_description, sharedLibraryExtension
from fmpy.fmi2 import FMU2Slave

from gatetwin.fmu import export_fmu
from gatetwin.modelfile import read_model_file
from gatetwin.plant.model import FopdtPlant, Schedule

HERE = Path(__file__).parent
STEP_S = 1.0
#: The discharge every timing holds (between two knots of the test plant), m3/h.
FLOW_M3H = 47.0


def test_plant() -> FopdtPlant:
    """The FOPDT plant of tests/fmu/test_fmu_*.py."""
    return FopdtPlant(
        "3F",
        20.0,
        Schedule(
            (30.0, 55.0, 85.0),
            {
                "gain_mm_per_mm": (-15.4, -12.0, -10.5),
                "time_constant_s": (71.0, 55.0, 42.0),
                "dead_time_s": (4.5, 7.0, 9.5),
                "level_ref_mm": (231.0, 300.0, 360.0),
            },
        ),
    )


def build(folder: Path, plant: Any, backends: tuple[str, ...] = ("c", "python")) -> dict[str, Path]:
    """Export and extract the FMUs; return backend -> extracted folder."""
    out = {}
    folder.mkdir(parents=True, exist_ok=True)
    for backend in backends:
        fmu = export_fmu(
            plant,
            folder / f"bench_{backend}.fmu",
            backend=backend,
            model_name="bench_fopdt",
            provenance={"purpose": "benchmark"},
        )
        out[backend] = Path(extract(str(fmu), str(folder / backend)))
    return out


def host_args(extracted: Path, gauge: str = "3F") -> list[str]:
    md = read_model_description(str(extracted))
    vr = {v.name: str(v.valueReference) for v in md.modelVariables}
    name = md.coSimulation.modelIdentifier + sharedLibraryExtension
    binary = extracted / "binaries" / platform / name
    resources = (extracted / "resources").as_uri()
    return [
        str(binary),
        md.guid,
        resources,
        vr["opening_mm"],
        vr["flow_m3h"],
        vr[f"level_{gauge}_mm"],
    ]


def libpython() -> tuple[Path | None, str]:
    """The shared libpython of this interpreter, or None and why not."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return None, "this Python is built without --enable-shared (no libpython to load)"
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    path = Path(sysconfig.get_config_var("LIBDIR")) / name
    return (path, "") if path.is_file() else (None, f"{path} not found")


def run_host(
    host: Path, args: list[str], n: int, lib: Path | None = None, env: dict[str, str] | None = None,
    step_s: float | None = None,
) -> dict[str, float]:  # fmt: skip
    extra = [str(lib)] if lib else []
    done = subprocess.run(
        [str(host), *args, str(step_s or STEP_S), str(n), *extra],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"bench_host failed: {done.stderr.strip()[-500:]}")
    return {k: float(v) for k, v in (line.split() for line in done.stdout.splitlines())}


def fmpy_loop(extracted: Path, n: int) -> dict[str, float]:
    md = read_model_description(str(extracted))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=str(extracted),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bench",
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([vr["opening_mm"], vr["flow_m3h"]], [20.0, 47.0])
    slave.exitInitializationMode()
    inputs, level = [vr["opening_mm"], vr["flow_m3h"]], [vr["level_3F_mm"]]
    t = 0.0
    start = time.perf_counter()
    for k in range(n):
        slave.setReal(inputs, [18.0 if (k // 7) % 2 else 23.0, 47.0])
        slave.doStep(t, STEP_S)
        slave.getReal(level)
        t += STEP_S
    loop_s = time.perf_counter() - start
    start = time.perf_counter()
    for _ in range(n):
        slave.getReal(level)
    get_s = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return {"steps_per_s": n / loop_s, "step_us": loop_s / n * 1e6, "get_us": get_s / n * 1e6}


def bare_command(cc: str, folder: Path, plant: FopdtPlant, n: int) -> list[str]:
    """bench_bare.c compiled with the FMU's flags, and its command line on the plant's K, T,
    L and level at the held discharge."""
    from gatetwin.fmu.c_build import CFLAGS, HOST_FLAGS

    exe = folder / "bench_bare"
    flags = [f for f in (*CFLAGS, *HOST_FLAGS) if f not in ("-shared", "-fPIC",
                                                             "-fvisibility=hidden")]  # fmt: skip
    subprocess.run([cc, *flags, "-o", str(exe), str(HERE / "bench_bare.c"), "-lm"], check=True)
    params = {c: plant.schedule.at(c, FLOW_M3H) for c in
              ("gain_mm_per_mm", "time_constant_s", "dead_time_s", "level_ref_mm")}  # fmt: skip
    return [str(exe), *(repr(v) for v in params.values()), str(STEP_S), str(n)]


def run_bare(command: list[str]) -> float:
    """ns per set + step + get of one run of bench_bare."""
    done = subprocess.run(command, capture_output=True, text=True, timeout=1800, check=True)
    return float(done.stdout.split()[1])


def empty_loop_ns(n: int) -> float:
    t, start = 0.0, time.perf_counter()
    for k in range(n):
        _ = 18.0 if (k // 7) % 2 else 23.0
        t += STEP_S
    return (time.perf_counter() - start) / n * 1e9


def build_host(cc: str, sources: Path, out: Path) -> Path:
    """bench_host.c compiled against an FMU's FMI headers."""
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-I", str(sources),
                    "-o", str(out), str(HERE / "bench_host.c"), "-ldl"], check=True)  # fmt: skip
    return out


#: The cases of --families: bench_host's keys and what they are.
CASES = (("set_doStep_get_ns", "new every 7 steps"), ("set_every_step_ns", "new at every step"),
         ("moving_ns", "moving 0.1 mm/step"))  # fmt: skip


def families(cc: str, n: int, repeat: int) -> dict[str, Any]:
    """The C FMU of every family beside the bare FOPDT, in one run: ns per step of each case
    (the fastest of ``repeat`` runs) and of the bare step (:func:`report` prints them)."""
    models = Path(__file__).resolve().parents[1] / "models"
    plants = {"fopdt (test plant)": test_plant(),
              **{name: read_model_file(models / f"{name}.json").plant
                 for name in ("fopdt_3F", "arx_3F", "physical_3F")}}  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        fmus = {name: build(folder / f"fmu{i}", plant, ("c",))["c"]
                for i, (name, plant) in enumerate(plants.items())}  # fmt: skip
        host = build_host(cc, next(iter(fmus.values())) / "sources", folder / "bench_host")
        bare_cmd = bare_command(cc, folder, test_plant(), n)
        runs: dict[str, list[dict[str, float]]] = {name: [] for name in plants}
        bare_runs = []
        for _ in range(repeat):  # interleaved: a load change touches every case alike
            bare_runs.append(run_bare(bare_cmd))
            for name, plant in plants.items():
                step_s = getattr(plant, "sample_period_s", 1.0)
                runs[name].append(run_host(host, host_args(fmus[name], plant.gauge), n,
                                           step_s=step_s))  # fmt: skip
    return {"n": n, "repeat": repeat, "flow_m3h": FLOW_M3H, "bare_ns": min(bare_runs),
            "fmus": {name: {key: min(r[key] for r in runs[name]) for key, _ in CASES}
                     for name in plants}}  # fmt: skip


def report(data: dict[str, Any]) -> str:
    """:func:`families`' numbers as Markdown (printed, and the docs' generated block)."""
    bare = data["bare_ns"]
    lines = [
        f"C FMUs, setReal + doStep + getReal, ns per step (fastest of {data['repeat']} runs of "
        f"N = {data['n']:,}; Q = {data['flow_m3h']:g} m³/h held); the bare FOPDT "
        f"(`bench_bare.c`) {bare:.1f} ns",
        "",
        "| FMU | " + " | ".join(f"{what} (ns) | × bare" for _, what in CASES) + " |",
        "|---|" + "---|---|" * len(CASES),
    ]
    for name, best in data["fmus"].items():
        cells = " | ".join(f"{best[key]:.1f} | {best[key] / bare:.1f}" for key, _ in CASES)
        lines.append(f"| {name} | {cells} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-c", type=int, default=5_000_000, help="doSteps timed, C FMU")
    parser.add_argument("--n-python", type=int, default=20_000, help="doSteps, python FMU")
    parser.add_argument("--repeat", type=int, default=5,
                        help="C timings: runs of each, the fastest kept (a shared machine "
                        "only ever slows a run down)")  # fmt: skip
    parser.add_argument("--n-fmpy", type=int, default=20_000, help="steps through fmpy")
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--model",
        metavar="MODEL.json",
        help="time this model file's FMUs instead of the FOPDT test plant",
    )
    which.add_argument(
        "--families",
        action="store_true",
        help="time the C FMU of every family (and models/) beside the bare FOPDT",
    )
    parser.add_argument(
        "--save",
        action="store_true",
        help="--families: keep the numbers in docs/results/fmu_steps.json",
    )
    args = parser.parse_args(argv)
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if args.save and not args.families:
        parser.error("--save keeps the numbers of --families")
    if args.families:
        data = families(cc, args.n_c, args.repeat)
        print(report(data))
        if args.save:
            sys.path.insert(0, str(HERE))
            from results import save

            print(save("fmu_steps", data, "python benchmarks/bench_fmu.py "
                       + " ".join(argv if argv is not None else sys.argv[1:])))  # fmt: skip
        return
    plant = read_model_file(args.model).plant if args.model else test_plant()
    global STEP_S
    STEP_S = getattr(plant, "sample_period_s", STEP_S)  # an ARX steps at its sample period
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        fmus = build(folder, plant)
        host = build_host(cc, fmus["c"] / "sources", folder / "bench_host")
        what = args.model or "FOPDT test plant, 3 knots"
        print(f"{what}: Q = 47 m3/h, opening 18/23 mm alternating every 7 steps, step {STEP_S} s")
        print(f"\n1. C host (dlopen of the FMU binary, {sys.platform})")
        bare_cmd = None if args.model else bare_command(cc, folder, plant, args.n_c)
        runs, bare_runs = [], []
        for _ in range(args.repeat):  # interleaved: a load change touches both alike
            runs.append(run_host(host, host_args(fmus["c"], plant.gauge), args.n_c))
            if bare_cmd:
                bare_runs.append(run_bare(bare_cmd))
        c_ns = {key: min(r[key] for r in runs) for key in runs[0]}
        print(
            f"   C FMU       doStep                 {c_ns['doStep_ns']:10.1f} ns   "
            f"(target <= 50 ns; N = {args.n_c:,})"
        )
        print(f"               setReal+doStep+getReal {c_ns['set_doStep_get_ns']:10.1f} ns")
        every = c_ns["set_every_step_ns"]
        print(f"               the same, a new opening at every step {every:10.1f} ns   "
              f"({every / c_ns['set_doStep_get_ns']:.2f} x the above)")  # fmt: skip
        moving = c_ns["moving_ns"]
        print(f"               the same, the opening moving 0.1 mm a step {moving:10.1f} ns")
        if not args.model:
            bare = min(bare_runs)
            ratio = c_ns["set_doStep_get_ns"] / bare
            print(f"   bare FOPDT  set+step+get           {bare:10.1f} ns   (bench_bare.c; "
                  f"fastest of {args.repeat} runs, alternating with the C FMU's)")  # fmt: skip
            print(f"   ratio C FMU/bare                   {ratio:10.2f} x   (target <= 3 x)")
        lib, why = libpython()
        if lib is None:
            print(f"   python FMU  not timed from C: {why}")
        else:
            env = dict(os.environ, PYTHONHOME=sys.base_prefix, PYTHONNOUSERSITE="1")
            py_ns = run_host(host, host_args(fmus["python"], plant.gauge), args.n_python, lib, env)
            print(
                f"   python FMU  doStep                 {py_ns['doStep_ns']:10.1f} ns   "
                f"(N = {args.n_python:,}; libpython {lib.name})"
            )
            print(f"               setReal+doStep+getReal {py_ns['set_doStep_get_ns']:10.1f} ns")
            ratio = py_ns["doStep_ns"] / c_ns["doStep_ns"]
            print(f"   ratio python/C per doStep          {ratio:10.0f} x   (target >= 100 x)")
        print(f"\n2. fmpy FMU2Slave loop, setReal + doStep + getReal (N = {args.n_fmpy:,})")
        for backend in ("c", "python"):
            r = fmpy_loop(fmus[backend], args.n_fmpy)
            print(
                f"   {backend:6s} FMU  {r['steps_per_s']:12,.0f} steps/s  "
                f"({r['step_us']:.2f} us/step; one getReal alone {r['get_us']:.2f} us)"
            )
        print(
            f"   fmpy overhead: empty Python loop {empty_loop_ns(args.n_fmpy):.0f} ns/iter; a "
            "step is 3 fmpy calls, so the C FMU's fmpy rate is fmpy's ctypes cost, not the model"
        )


if __name__ == "__main__":
    main()
