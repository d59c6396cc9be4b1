"""Cost of one ARX sample in each rendering, next to the same measurement on another checkout.

Every rendering of the ARX family runs the one sample of :mod:`gatetwin.plant.blocks`
(``arx_sample``): the Python reference simulator, the numba grid simulator of the diagnosis,
the pythonfmu FMU and the C FMU (its generated ``blocks.c``). This script times each, in
nanoseconds per ARX sample, for a second-order plant (ARX(2, 2, 1)) and for the largest
orders an FMU takes (ARX(8, 8, 2)); the FMUs through fmpy with long communication steps (many
samples per ``doStep``), so fmpy's own cost per call is spread thin.

With ``--against SRC`` (another checkout's ``src`` folder) it runs itself again on that
source, in a separate process, and prints both columns and their ratio (this tree / other):
how much a change to the arithmetic's single source costs or gains. Never asserted.

usage: python benchmarks/bench_arx.py [--samples 20000] [--against /path/to/other/src]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_S = 1.2
#: Samples per FMU communication step: fmpy's cost per doStep (some microseconds) shared out
#: below a nanosecond per sample for the C FMU.
SAMPLES_PER_STEP = {"c": 50000, "python": 500}


def _plant(na: int, nb: int, nk: int):
    from gatetwin.plant.model import ArxPlant, Schedule

    rng = np.random.default_rng(na * 100 + nb)
    a = rng.uniform(-0.05, 0.05, (na, 2))
    a[0] += 0.5  # stable: sum |a| < 1
    values = {f"a{i + 1}": tuple(a[i]) for i in range(na)}
    values.update({f"b{j + 1}": tuple(rng.uniform(-1, 1, 2)) for j in range(nb)})
    values["level_ref_mm"] = (231.0, 360.0)
    return ArxPlant(gauge="3F", opening_ref_mm=20.0, sample_period_s=SAMPLE_S, na=na, nb=nb,
                    nk=nk, schedule=Schedule((30.0, 85.0), values))  # fmt: skip


def _inputs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    times = np.arange(n + 1) * SAMPLE_S
    opening = 20.0 + 6.0 * np.sign(rng.standard_normal(n + 1))
    flow = np.linspace(35.0, 80.0, n + 1)
    return times, opening, flow


def _per_sample_ns(run, samples: int, repeats: int = 5) -> float:
    """The fastest of ``repeats`` runs after a first one (compilation, caches)."""
    run()
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best / samples * 1e9


def _fmu_ns(plant, backend: str, samples: int, folder: Path) -> float:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from gatetwin.fmu import export_fmu

    name = f"bench_arx_{plant.na}"
    fmu = export_fmu(plant, folder / f"{backend}_{name}.fmu", backend=backend, model_name=name,
                     provenance={"benchmark": "arx"})  # fmt: skip
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    out = next(v.valueReference for v in md.modelVariables if v.causality == "output")
    unzipped = extract(fmu, str(folder / f"x_{backend}_{name}"))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName="b",
                      modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
    slave.instantiate()
    per_step = SAMPLES_PER_STEP[backend]
    h = per_step * SAMPLE_S
    steps = max(1, samples // per_step)

    def run() -> None:
        slave.reset()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal([vr["opening_mm"], vr["flow_m3h"]], [20.0, 55.0])
        slave.exitInitializationMode()
        for k in range(steps):
            slave.setReal([vr["opening_mm"]], [26.0 if k % 2 else 14.0])
            slave.doStep(k * h, h)
            slave.getReal([out])

    try:
        return _per_sample_ns(run, steps * per_step)
    finally:
        slave.terminate()
        slave.freeInstance()


def measure(samples: int) -> dict[str, float]:
    """Nanoseconds per ARX sample, by rendering and orders."""
    from gatetwin.diagnosis.grid_sim import grid_inputs, simulate_grid
    from gatetwin.plant.simulate import simulate

    warnings.simplefilter("ignore")
    times, opening, flow = _inputs(samples)
    grid = grid_inputs(times, opening, flow, SAMPLE_S)
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for orders in ((2, 2, 1), (8, 8, 2)):
            plant = _plant(*orders)
            tag = "ARX({}, {}, {})".format(*orders)
            out[f"{tag} reference simulator"] = _per_sample_ns(
                lambda p=plant: simulate(p, times, opening, flow), samples)  # fmt: skip
            out[f"{tag} numba grid simulator"] = _per_sample_ns(
                lambda p=plant: simulate_grid(p, grid), samples)  # fmt: skip
            out[f"{tag} C FMU"] = _fmu_ns(plant, "c", samples * 50, Path(tmp))
            out[f"{tag} pythonfmu FMU"] = _fmu_ns(plant, "python", samples, Path(tmp))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20000)
    parser.add_argument("--against", type=Path, help="another checkout's src folder")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    here = measure(args.samples)
    if args.json:
        print(json.dumps(here))
        return
    other: dict[str, float] = {}
    if args.against is not None:
        env = {**os.environ, "PYTHONPATH": str(args.against.resolve())}
        done = subprocess.run([sys.executable, __file__, "--samples", str(args.samples), "--json"],
                              env=env, check=True, capture_output=True, text=True)  # fmt: skip
        other = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"{'ns per ARX sample':40s} {'this tree':>10s}" + (
        f" {'other':>10s} {'ratio':>7s}" if other else ""))  # fmt: skip
    for key, value in here.items():
        line = f"{key:40s} {value:10.1f}"
        if key in other:
            line += f" {other[key]:10.1f} {value / other[key]:7.2f}"
        print(line)


if __name__ == "__main__":
    main()
