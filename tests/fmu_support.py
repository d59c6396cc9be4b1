"""Shared helpers of tests/fmu/test_fmu_*.py: test plants, an fmpy FMU2Slave driver, runs."""

from __future__ import annotations

import shutil
import subprocess
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from gatetwin.fmu import export_fmu
from gatetwin.plant.model import ArxPlant, FopdtPlant, Schedule
from gatetwin.plant.simulate import simulator_for

TESTS = Path(__file__).parent
BACKENDS = ("c", "python")
FAMILIES = ("fopdt", "arx")
PROVENANCE = {
    "model_file_sha256": "9f2c4e0d5b7a",
    "fit": {"nrmse": 0.031, "r2": 0.987},
    "flow_validity_m3h": [30.0, 85.0],
}


def fopdt_plant() -> FopdtPlant:
    return FopdtPlant(
        gauge="3F",
        opening_ref_mm=20.0,
        schedule=Schedule(
            (30.0, 55.0, 85.0),
            {
                "gain_mm_per_mm": (-15.4, -12.0, -10.5),
                "time_constant_s": (71.0, 55.0, 42.0),
                "dead_time_s": (4.5, 7.0, 9.5),
                "level_ref_mm": (231.0, 300.0, 360.0),
            },
        ),
    )


def arx_plant() -> ArxPlant:
    return ArxPlant(
        gauge="3F",
        opening_ref_mm=20.0,
        sample_period_s=1.2,
        na=2,
        nb=2,
        nk=1,
        schedule=Schedule(
            (30.0, 85.0),
            {
                "a1": (0.713, 0.575),
                "a2": (0.248, 0.148),
                "b1": (-1.93, -2.53),
                "b2": (1.17, -0.51),
                "level_ref_mm": (231.0, 360.0),
            },
        ),
    )


PLANTS = {"fopdt": fopdt_plant, "arx": arx_plant}


def export_all(folder: Path) -> dict[tuple[str, str], Path]:
    """Every (backend, family) FMU of the test plants (each checked for well-formed XML)."""
    fmus = {
        (backend, family): export_fmu(
            PLANTS[family](),
            folder / f"gate_3F_{family}_{backend}.fmu",
            backend=backend,
            model_name=f"gate_3F_{family}",
            provenance=PROVENANCE,
        )
        for backend in BACKENDS
        for family in FAMILIES
    }
    for path in fmus.values():
        assert_well_formed(path)
    return fmus


def model_description_problem(fmu: Path) -> str:
    """Why the FMU's modelDescription.xml is not well-formed XML ("" when it is): parsed by
    expat (xml.etree) and by lxml, the parser fmpy uses."""
    from lxml import etree

    with zipfile.ZipFile(fmu) as zf:
        xml = zf.read("modelDescription.xml")
    try:
        ET.fromstring(xml)
        etree.fromstring(xml, etree.XMLParser(recover=False, huge_tree=False))
    except (ET.ParseError, etree.XMLSyntaxError) as exc:
        return f"modelDescription.xml is not well formed: {exc}"
    return ""


def assert_well_formed(fmu: Path) -> None:
    why = model_description_problem(fmu)
    assert not why, f"{fmu}: {why}"


def gatetwin_fmus(folder: Path) -> list[Path]:
    """The FMUs gatetwin generated under ``folder`` (zip archives whose model description
    names gatetwin as its generation tool); other .fmu files tests write are skipped."""
    found = []
    for path in sorted(folder.rglob("*.fmu")):
        try:
            with zipfile.ZipFile(path) as zf:
                head = zf.read("modelDescription.xml")
        except (zipfile.BadZipFile, KeyError, OSError):
            continue
        if b'generationTool="gatetwin' in head:
            found.append(path)
    return found


@dataclass
class Driver:
    """One FMU instance driven through fmpy's FMU2Slave, with its log messages."""

    slave: FMU2Slave
    vr: dict[str, int]
    output: str
    messages: list[tuple[int, str]] = field(default_factory=list)
    time_s: float = 0.0
    _callbacks: fmi2CallbackFunctions | None = None

    def start(self, opening_mm: float, flow_m3h: float, start_s: float = 0.0) -> None:
        self.slave.setupExperiment(startTime=start_s)
        self.slave.enterInitializationMode()
        self.set_inputs(opening_mm, flow_m3h)
        self.slave.exitInitializationMode()
        self.time_s = start_s

    def set_inputs(self, opening_mm: float, flow_m3h: float) -> None:
        self.slave.setReal([self.vr["opening_mm"], self.vr["flow_m3h"]], [opening_mm, flow_m3h])

    def level(self) -> float:
        return self.slave.getReal([self.vr[self.output]])[0]

    def step(self, h: float, opening_mm: float, flow_m3h: float) -> float:
        self.set_inputs(opening_mm, flow_m3h)
        self.slave.doStep(self.time_s, h)
        self.time_s += h
        return self.level()

    def close(self) -> None:
        self.slave.freeInstance()


class Fmi3Driver(Driver):
    """One FMI 3.0 instance through fmpy's FMU3Slave, with the verbs of :class:`Driver`."""

    def start(self, opening_mm: float, flow_m3h: float, start_s: float = 0.0) -> None:
        self.slave.enterInitializationMode(startTime=start_s)
        self.set_inputs(opening_mm, flow_m3h)
        self.slave.exitInitializationMode()
        self.time_s = start_s

    def set_inputs(self, opening_mm: float, flow_m3h: float) -> None:
        self.slave.setFloat64([self.vr["opening_mm"], self.vr["flow_m3h"]],
                              [opening_mm, flow_m3h])  # fmt: skip

    def level(self) -> float:
        return self.slave.getFloat64([self.vr[self.output]])[0]


def _open_fmu3(md, extracted: Path, name: str, logging_on: bool) -> Fmi3Driver:
    from fmpy.fmi3 import FMU3Slave

    slave = FMU3Slave(
        guid=md.guid,
        unzipDirectory=str(extracted),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    output = next(v.name for v in md.modelVariables if v.causality == "output")
    driver = Fmi3Driver(slave, {v.name: v.valueReference for v in md.modelVariables}, output)

    def log(env, status, category, message):
        driver.messages.append((status, message.decode()))

    slave.instantiate(loggingOn=logging_on, logMessage=log)
    return driver


def open_fmu(extracted: Path, name: str = "instance", logging_on: bool = True) -> Driver:
    """An instance of the extracted FMU (FMI 2.0 or 3.0) behind the :class:`Driver` verbs."""
    md = read_model_description(str(extracted))
    if md.fmiVersion == "3.0":
        return _open_fmu3(md, extracted, name, logging_on)
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=str(extracted),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    output = next(v.name for v in md.modelVariables if v.causality == "output")
    driver = Driver(slave, {v.name: v.valueReference for v in md.modelVariables}, output)

    def log(env, instance, status, category, message):
        driver.messages.append((status, message.decode()))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    driver._callbacks = callbacks
    slave.instantiate(callbacks=callbacks, loggingOn=logging_on)
    return driver


def extract_all(fmus: dict[tuple[str, str], Path], folder: Path) -> dict[tuple[str, str], Path]:
    return {
        key: Path(extract(str(path), str(folder / f"{key[0]}_{key[1]}")))
        for key, path in fmus.items()
    }


def driven_inputs(
    family: str, n: int, seed: int = 0, step_s: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, openings and flows of a long run: steps and PRBS-like opening changes, and a
    discharge that crosses the knots and leaves their range on both sides."""
    rng = np.random.default_rng(seed)
    if family == "arx":
        steps = 1.2 * rng.integers(1, 4, n - 1)
    else:
        steps = rng.uniform(0.05, 4.0, n - 1) if step_s is None else np.full(n - 1, step_s)
    times = np.concatenate([[0.0], np.cumsum(steps)])
    hold = rng.integers(1, 12, n)
    levels = 20.0 + 6.0 * np.sign(rng.standard_normal(n))
    opening = np.repeat(levels, hold)[:n]
    opening[n // 4 : n // 4 + 40] = 35.0  # a long step
    flow = np.interp(np.arange(n), [0, n / 4, n / 2, 3 * n / 4, n], [20.0, 95.0, 55.0, 10.0, 60.0])
    return times, opening, flow


def reference_run(plant, times, opening, flow) -> np.ndarray:
    sim = simulator_for(plant)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # flow outside the knots, on purpose
        sim.initialize(float(opening[0]), float(flow[0]), float(times[0]))
        out = [sim.level_mm]
        for i in range(1, len(times)):
            h = float(times[i] - times[i - 1])
            out.append(sim.do_step(h, float(opening[i - 1]), float(flow[i - 1])))
    return np.array(out)


def fmu_run(driver: Driver, times, opening, flow) -> np.ndarray:
    driver.start(float(opening[0]), float(flow[0]), float(times[0]))
    out = [driver.level()]
    for i in range(1, len(times)):
        h = float(times[i] - times[i - 1])
        out.append(driver.step(h, float(opening[i - 1]), float(flow[i - 1])))
    return np.array(out)


def compiler() -> str | None:
    return shutil.which("cc") or shutil.which("gcc")


def compile_host(sources: Path, out: Path, extra: tuple[str, ...] = ()) -> None:
    """Build tests/c/fmu_host.c against the FMI headers in an FMU's sources/ folder."""
    subprocess.run(
        [
            compiler(),
            "-std=c99",
            "-O1",
            "-g",
            "-Wall",
            "-Wextra",
            "-Werror",
            *extra,
            "-I",
            str(sources),
            "-o",
            str(out),
            str(TESTS / "c" / "fmu_host.c"),
            "-ldl",
            "-lm",
        ],
        check=True,
        capture_output=True,
        text=True,
    )


#: Flags of a sanitised build: any address or undefined-behaviour report aborts the process.
SANITIZE = (
    "-fsanitize=address,undefined,float-cast-overflow",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
    "-g",
)


def sanitizers_work(folder: Path) -> bool:
    """Whether the C compiler builds and runs a program with :data:`SANITIZE`."""
    probe = folder / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    try:
        built = subprocess.run([compiler(), *SANITIZE, "-o", str(folder / "probe"), str(probe)],
                               capture_output=True)  # fmt: skip
        return built.returncode == 0 and subprocess.run([str(folder / "probe")]).returncode == 0
    except OSError:
        return False


def build_fuzzer(out_dir: Path) -> Path:
    """tests/c/fmu_fuzz.c compiled with :data:`SANITIZE` against the FMI 2.0 headers of the
    templates: one fuzzer for every gatetwin C FMU (each described by :func:`fuzz_spec`)."""
    from gatetwin.fmu.c_build import templates_dir

    fuzzer = out_dir / "fmu_fuzz"
    subprocess.run(
        [compiler(), "-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", *SANITIZE,
         "-I", str(templates_dir()), "-o", str(fuzzer), str(TESTS / "c" / "fmu_fuzz.c"), "-ldl",
         "-lm"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    return fuzzer


def build_sanitized(extracted: Path, out_dir: Path) -> Path:
    """The FMU's binary rebuilt from its ``sources/`` with :data:`SANITIZE`."""
    from gatetwin.fmu.c_build import compile_shared

    md = read_model_description(str(extracted))
    binary = out_dir / f"{md.coSimulation.modelIdentifier}_sanitized.so"
    root = ET.parse(extracted / "modelDescription.xml").getroot()
    c_files = tuple(e.get("name") for e in root.iter("File"))
    compile_shared(extracted / "sources", c_files, binary, SANITIZE)
    return binary


#: The fuzzer's variable kinds by (causality, variability) of the modelDescription.
_FUZZ_KINDS = {("input", None): "input", ("output", None): "output",
               ("parameter", "tunable"): "tunable", ("parameter", "fixed"): "fixed"}  # fmt: skip


def fuzz_spec(
    extracted: Path, out: Path, ranges: dict[str, tuple[float, float]] | None = None,
    sampled: bool = False, warns_on_change: str | None = None,
) -> Path:  # fmt: skip
    """The SPEC file tests/c/fmu_fuzz.c reads for the extracted FMI 2.0 FMU, written to ``out``:
    GUID, value references, kinds and start values from its modelDescription.xml, the
    plausible values of the inputs named in ``ranges``; the state's size and int fields from
    tests/c/fmu_layout.c compiled against its ``sources/``. ``sampled``: the FMU steps whole
    samples of its default experiment's step size (the MPC controller, the observer).
    ``warns_on_change``: the input each setting of which may bring one more fmi2Warning."""
    md = read_model_description(str(extracted))
    lines = [f"guid {md.guid}"]
    for v in sorted(md.modelVariables, key=lambda v: v.valueReference):
        variability = v.variability if v.causality == "parameter" else None
        start = float(v.start) if v.start is not None else 0.0
        lines.append(f"var {v.valueReference} {_FUZZ_KINDS[v.causality, variability]} {start!r}")
        if v.causality == "input" and v.name in (ranges or {}):
            lo, hi = ranges[v.name]
            lines.append(f"range {v.valueReference} {float(lo)!r} {float(hi)!r}")
        if v.name == "sample_period_s":
            lines.append(f"sample_period {v.valueReference}")
        if v.causality == "input" and v.name == warns_on_change:
            lines.append(f"warns_on_change {v.valueReference}")
    if sampled:
        lines.append(f"sample_period_s {float(md.defaultExperiment.stepSize)!r}")
    probe = out.with_suffix(".layout")
    subprocess.run(
        [compiler(), "-std=c99", "-Wall", "-Wextra", "-Werror", "-I", str(extracted / "sources"),
         "-o", str(probe), str(TESTS / "c" / "fmu_layout.c")],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    layout = subprocess.run([str(probe)], check=True, capture_output=True, text=True).stdout
    out.write_text("\n".join([*lines, layout]), encoding="utf-8")
    return out


def with_zip_bomb(src: Path, dst: Path) -> Path:
    """``src`` (a zip: an FMU or an SSP package) with one more member that unpacks to more
    than gatetwin's 512 MiB limit (zeros: a few hundred kB packed)."""
    from gatetwin.records.limits import DEFAULT_MAX_BYTES

    chunk = bytes(1 << 20)
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            zout.writestr(item, zin.read(item))
        with zout.open("resources/zeros.bin", "w", force_zip64=True) as member:
            for _ in range(DEFAULT_MAX_BYTES // len(chunk) + 1):
                member.write(chunk)
    return dst


def fmpy_ssp_runner_from_start_values(monkeypatch):
    """FMPy's SSP runner (``fmpy.ssp.simulation``) with its first step given each input's
    start value: the runner sets every connector to 0.0 and exchanges nothing before the
    first step, so without this an FMU's first step sees zero inputs (a closed gate, no
    inflow); a package's start values are what each input's source gives at the start.
    Patched for the test through ``monkeypatch``; returns the module."""
    import fmpy.ssp.simulation as runner

    def first_step_at_start_values(component, time, step_size, _do_step=runner.do_step):
        if time == 0.0:
            for c in component.connectors:
                if c.kind == "input":
                    c.value = runner.get_value(component, c.name)
        _do_step(component, time, step_size)

    monkeypatch.setattr(runner, "do_step", first_step_at_start_values)
    return runner
