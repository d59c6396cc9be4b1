"""C FMUs for other platforms, cross-compiled with Zig: the binaries are what they say, and
the foreign ones compute what the host's computes within 1e-9 mm (Windows under wine, 64-bit
ARM Linux under qemu-user; macOS checked statically). FMI 3.0 FMUs carry the same binaries in
FMI 3.0's folders, exporting the fmi3 functions; driven by the same host built for FMI 3.0,
they compute what the host's FMI 3.0 binary computes and what the FMI 2.0 binary of their
platform computes."""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from fmu_support import compiler  # noqa: E402
from gatetwin.bundled import bundled_records_dir
from gatetwin.fmu import export_fmu
from gatetwin.fmu.platforms import platforms_of, zig_available
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.modelfile import read_model_file
from gatetwin.records import read_record

TESTS = Path(__file__).resolve().parents[1]
MODEL = TESTS.parent / "models" / "fopdt_3F.json"
WINE = shutil.which("wine") or shutil.which("wine64")
needs_zig = pytest.mark.skipif(not zig_available(), reason="ziglang (gatetwin[cross]) absent")
#: Minutes of cross-compiling (and seconds of wine and qemu runs): CI runs the module with the
#: slow subset, over both workers
pytestmark = pytest.mark.slow
#: The FMI 2.0 co-simulation functions every binary must export.
FMI2_FUNCTIONS = {
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging", "fmi2Instantiate",
    "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode", "fmi2Terminate", "fmi2Reset", "fmi2GetReal",
    "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString", "fmi2SetReal", "fmi2SetInteger",
    "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate",
    "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate", "fmi2GetDirectionalDerivative", "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep", "fmi2GetStatus",
    "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus",
}  # fmt: skip
#: The FMI 3.0 co-simulation functions an importer calls first or most (every one of the
#: standard's is defined by fmi3_glue.c; these are the ones this test names).
FMI3_FUNCTIONS = {
    "fmi3GetVersion", "fmi3SetDebugLogging", "fmi3InstantiateCoSimulation", "fmi3FreeInstance",
    "fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3Terminate", "fmi3Reset",
    "fmi3GetFloat64", "fmi3SetFloat64", "fmi3GetFMUState", "fmi3SetFMUState",
    "fmi3FreeFMUState", "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState", "fmi3DoStep", "fmi3EnterStepMode",
}  # fmt: skip
#: What a macOS binary may take from libSystem: the C library calls of the sources and libm's
#: functions (clang joins a sin and a cos of one argument into __sincos_stret).
LIBSYSTEM = {
    "calloc", "free", "memcpy", "memcmp", "memset", "bzero", "__bzero", "strcmp", "strlen",
    "snprintf", "vsnprintf", "sqrt", "floor", "ceil", "fabs", "fmod", "ldexp", "fmax", "fmin",
    "nearbyint", "exp", "expm1", "log", "log1p", "sin", "cos", "pow", "__sincos_stret",
}  # fmt: skip
#: How far a foreign binary's levels may lie from the host's, mm: each platform's C library
#: computes exp, log, sin and pow to within an ulp or so, but not always the same ulp; no
#: computation of the FMUs magnifies an ulp (the time constants are the gate law's
#: derivatives, not differences), so a level of a few hundred mm differs by ~1e-13 mm a step,
#: and the bound of the renderings, 1e-9 mm, holds with room over a record's samples.
PLATFORM_TOL_MM = 1e-9


#: One model of each family; each carries a seiche (sin, cos), the FOPDT's and ARX's flow
#: schedules call exp, the ARX's envelope pow, the physical kernel exp and log.
MODELS = ("fopdt_3F", "arx_3F", "physical_3F")


@pytest.fixture(scope="session")
def exported(tmp_path_factory):
    """``exported(version, model)``: the FMU of ``models/<model>.json`` for every platform, as
    (path, extracted folder); each exported once."""
    if compiler() is None:
        pytest.skip("no C compiler on this machine")
    if not zig_available():
        pytest.skip("ziglang (gatetwin[cross]) absent")
    done: dict[tuple[str, str], tuple[Path, Path]] = {}

    def export(version: str, name: str = "fopdt_3F") -> tuple[Path, Path]:
        if (version, name) not in done:
            model = read_model_file(MODEL.with_name(f"{name}.json"))
            folder = tmp_path_factory.mktemp(f"platforms_{name}")
            path = export_fmu(model.plant, folder / f"{name}.fmu", backend="c",
                              model_name=model.name, provenance={"model": model.name},
                              platforms="all", fmi_version=version)  # fmt: skip
            with zipfile.ZipFile(path) as zf:
                zf.extractall(folder / "x")
            done[version, name] = path, folder / "x"
        return done[version, name]

    return export


@pytest.fixture(scope="session")
def fmu_all(exported):
    return exported("2.0")


@pytest.fixture(scope="session")
def fmu3_all(exported):
    return exported("3.0")


#: (FMI 2.0 folder, FMI 3.0 folder) of each format checked below.
FOLDERS = {"x86_64 ELF": ("linux64", "x86_64-linux"), "AArch64 ELF": ("aarch64-linux",) * 2,
           "AMD64 PE": ("win64", "x86_64-windows")}  # fmt: skip


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_every_platform_gets_one_binary_of_its_format(fmu_all, fmu3_all, version):
    root = (fmu_all if version == "2.0" else fmu3_all)[1]
    column = 0 if version == "2.0" else 1
    folder = {what: names[column] for what, names in FOLDERS.items()}
    found = {p.parent.name: p for p in (root / "binaries").glob("*/*")}
    assert set(found) == set(platforms_of(version))
    assert all(len(list(p.parent.iterdir())) == 1 for p in found.values())  # no .lib, .pdb
    elf_machine = {w: struct.unpack_from("<H", found[folder[w]].read_bytes(), 18)[0]
                   for w in ("x86_64 ELF", "AArch64 ELF")}  # fmt: skip
    assert elf_machine == {"x86_64 ELF": 62, "AArch64 ELF": 183}  # EM_X86_64, EM_AARCH64
    pe = found[folder["AMD64 PE"]].read_bytes()
    pe_offset = struct.unpack_from("<I", pe, 0x3C)[0]
    assert pe[:2] == b"MZ" and pe[pe_offset : pe_offset + 4] == b"PE\0\0"
    assert struct.unpack_from("<H", pe, pe_offset + 4)[0] == 0x8664  # AMD64


@pytest.mark.parametrize(
    ("version", "folder", "cpu"),
    [("2.0", "darwin64", "x86_64"), ("2.0", "aarch64-darwin", "ARM64"),
     ("3.0", "x86_64-darwin", "x86_64"), ("3.0", "aarch64-darwin", "ARM64")],
)  # fmt: skip
@pytest.mark.parametrize("model", MODELS)
def test_macos_binaries_export_fmi_and_need_only_libsystem(exported, version, folder, cpu, model):
    macholib = pytest.importorskip("macholib")
    from macholib.mach_o import CPU_TYPE_NAMES, LC_LOAD_DYLIB
    from macholib.MachO import MachO
    from macholib.SymbolTable import SymbolTable

    assert macholib
    path = next((exported(version, model)[1] / "binaries" / folder).iterdir())
    binary = MachO(str(path))
    header = binary.headers[0]
    assert CPU_TYPE_NAMES.get(header.header.cputype) == cpu
    symbols = SymbolTable(binary)
    # C symbols carry one leading underscore in Mach-O
    defined = {_c_name(name) for _, name in symbols.extdefsyms}
    undefined = {_c_name(name) for _, name in symbols.undefsyms}
    assert (FMI2_FUNCTIONS if version == "2.0" else FMI3_FUNCTIONS) <= defined
    assert undefined - {"dyld_stub_binder"} <= LIBSYSTEM, undefined - LIBSYSTEM
    dylibs = [c[2].rstrip(b"\0").decode() for c in header.commands if c[0].cmd == LC_LOAD_DYLIB]
    assert dylibs == ["/usr/lib/libSystem.B.dylib"]


def _c_name(symbol: bytes) -> str:
    text = symbol.decode()
    return text[1:] if text.startswith("_") else text


def _trace_inputs(folder: Path) -> tuple[list[str], Path]:
    """Arguments of tests/c/fmu_trace.c for the FMU, and a file of a record's inputs."""
    md = read_model_description(str(folder))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    out = next(v.name for v in md.modelVariables if v.causality == "output")
    rec = read_record(bundled_records_dir() / "Eboth.csv")  # moves and inflow steps together
    e = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
    inputs = folder / "inputs.txt"
    np.savetxt(inputs, np.column_stack([e, rec.flow_m3h]), fmt="%.17g")
    return [md.guid, str(vr["opening_mm"]), str(vr["flow_m3h"]), str(vr[out]), "1.2"], inputs


def _trace(command: list[str], inputs: Path) -> np.ndarray:
    """Run the trace host; its output through files, not pipes: the first wine run of a
    machine starts the wine server and its services, which inherit the host's descriptors and
    outlive it (a pipe would not close until they quit), so the call waits only for the
    host's own exit."""
    with inputs.open() as stdin, tempfile.TemporaryFile("w+") as stdout, \
            tempfile.TemporaryFile("w+") as stderr:  # fmt: skip
        done = subprocess.run(command, stdin=stdin, stdout=stdout, stderr=stderr, timeout=600,
                              env={**os.environ, "WINEDEBUG": "-all"})  # fmt: skip
        stdout.seek(0), stderr.seek(0)
        assert done.returncode == 0, stderr.read()[-2000:]
        return np.array([float(v) for v in stdout.read().split()])


def _host(root: Path, target: str | None, out: Path, version: str = "2.0") -> Path:
    """tests/c/fmu_trace.c built for ``version`` against the FMU's sources/ (its headers)."""
    flags = ["-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", "-I", str(root / "sources")]
    flags += ["-DTRACE_FMI3"] if version == "3.0" else []
    cc = [compiler()] if target is None else [sys.executable, "-m", "ziglang", "cc", "-target",
                                              target]  # fmt: skip
    libs = [] if target and "windows" in target else ["-ldl"]
    subprocess.run([*cc, *flags, "-o", str(out), str(TESTS / "c" / "fmu_trace.c"), *libs],
                   check=True, capture_output=True)  # fmt: skip
    return out


#: Where the trace host runs, by the FMU binary's format: its (FMI 2.0, FMI 3.0) folder, the
#: Zig target of the host (None: the system compiler) and what runs it.
TRACED = {
    "x86_64 ELF": (FOLDERS["x86_64 ELF"], None, ()),
    "AArch64 ELF": (FOLDERS["AArch64 ELF"], "aarch64-linux-gnu.2.17",
                    ("qemu-aarch64", "-L", "/usr/aarch64-linux-gnu")),
    "AMD64 PE": (FOLDERS["AMD64 PE"], "x86_64-windows-gnu", (WINE,)),
}  # fmt: skip
needs_qemu = pytest.mark.skipif(
    shutil.which("qemu-aarch64") is None or not Path("/usr/aarch64-linux-gnu").is_dir(),
    reason="qemu-user or the arm64 C library (libc6-arm64-cross) absent",
)
needs_wine = pytest.mark.skipif(WINE is None, reason="wine absent")


def _wine_prefix_made() -> None:
    """Make wine's prefix (``$WINEPREFIX``, else ~/.wine) before the first trace, one process
    at a time: two test workers whose first wine runs make it at once race on its folders
    and the wine server's socket ("chdir to /tmp/wine-…: No such file or directory"). The
    worker that finds no prefix runs ``wineboot -i`` (the tools beside ``wine``) and waits
    with ``wineserver -w`` until the services it started have quit; the others find it."""
    import fcntl

    prefix = Path(os.environ.get("WINEPREFIX") or Path.home() / ".wine")
    folder = Path(WINE).parent  # the PATH folder wine was found in
    env = {**os.environ, "WINEDEBUG": "-all"}
    with open(Path(tempfile.gettempdir()) / f"gatetwin-wine-{os.getuid()}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (prefix / "system.reg").is_file():
            return
        for command in ([folder / "wineboot", "-i"], [folder / "wineserver", "-w"]):
            subprocess.run(command, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, timeout=600, check=True)  # fmt: skip


@pytest.fixture(scope="session")
def traces(exported, tmp_path_factory):
    """``trace(version, format, model)``: the levels the FMU binary of that FMI version and
    format computes on the bundled record, driven by tests/c/fmu_trace.c (each run once)."""
    done: dict[tuple[str, str, str], np.ndarray] = {}
    done_wine: list[bool] = []

    def trace(version: str, what: str, model: str = "fopdt_3F") -> np.ndarray:
        if (version, what, model) not in done:
            root = exported(version, model)[1]
            folders, target, runner = TRACED[what]
            args, inputs = _trace_inputs(root)
            suffix = ".exe" if target and "windows" in target else ""
            out = tmp_path_factory.mktemp("trace") / f"trace{suffix}"
            host = _host(root, target, out, version)
            binary = next((root / "binaries" / folders[0 if version == "2.0" else 1]).iterdir())
            if runner == (WINE,) and not done_wine:
                _wine_prefix_made()
                done_wine.append(True)
            done[version, what, model] = _trace([*runner, str(host), str(binary), *args], inputs)
        return done[version, what, model]

    return trace


@needs_zig
@needs_qemu
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_the_arm64_linux_binary_under_qemu_agrees_with_the_host(traces, version, model):
    """glibc's ARM functions need not round as its x86-64 ones do: within PLATFORM_TOL_MM."""
    expected = traces(version, "x86_64 ELF", model)
    got = traces(version, "AArch64 ELF", model)
    assert expected.size > 1000 and got.size == expected.size
    assert np.max(np.abs(got - expected)) <= PLATFORM_TOL_MM


@needs_zig
@needs_wine
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_the_windows_binary_under_wine_agrees_with_the_host(traces, version, model):
    """Windows' C library computes exp, log and sin in its own way: within PLATFORM_TOL_MM."""
    expected = traces(version, "x86_64 ELF", model)
    got = traces(version, "AMD64 PE", model)
    assert expected.size > 1000 and got.size == expected.size
    assert np.max(np.abs(got - expected)) <= PLATFORM_TOL_MM


@needs_zig
@pytest.mark.parametrize(
    "what",
    ["x86_64 ELF", pytest.param("AArch64 ELF", marks=needs_qemu),
     pytest.param("AMD64 PE", marks=needs_wine)],
)  # fmt: skip
def test_fmi3_binaries_compute_what_the_fmi2_ones_compute_to_the_bit(traces, what):
    """The two versions compile the same component with the same flags for the same target
    and link the same C library; only the glue differs, and it moves no value: equal bits,
    Windows' too."""
    fmi2, fmi3 = traces("2.0", what), traces("3.0", what)
    assert fmi2.size > 1000 and np.array_equal(fmi3, fmi2)


def test_unknown_platforms_and_a_missing_cross_compiler_are_one_line(tmp_path, monkeypatch):
    import gatetwin.fmu.platforms as platforms

    model = read_model_file(MODEL)
    args = dict(backend="c", model_name=model.name, provenance={})
    with pytest.raises(Exception, match=r"platforms: unknown 'win65'"):
        export_fmu(model.plant, tmp_path / "a.fmu", platforms="win65", **args)
    monkeypatch.setattr(platforms, "zig_available", lambda: False)
    with pytest.raises(Exception, match=r"cross-compiling needs Zig's C compiler"):
        export_fmu(model.plant, tmp_path / "b.fmu", platforms="all", **args)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake absent (FMPy's build uses it)")
def test_a_c_fmu_rebuilt_from_its_sources_by_fmpy_gives_the_same_bits(tmp_path):
    """An importer rebuilds the binary from sources/ with FMPy's build helper and runs it in
    FMPy: the shipped binary's outputs, to the bit. (FMPy's CMake build does not link libm;
    a Python host has it loaded already, a bare C host would not: BUILD.txt and the build
    description name it.)"""
    if compiler() is None:
        pytest.skip("no C compiler on this machine")
    from fmpy.build import build_platform_binary
    from fmpy.model_description import read_build_description

    from fmu_support import fmu_run, open_fmu

    model = read_model_file(MODEL)
    path = export_fmu(model.plant, tmp_path / "m.fmu", backend="c", model_name=model.name,
                      provenance={"model": model.name})  # fmt: skip
    assert read_build_description(str(path))[0].modelIdentifier == model.name  # schema-valid
    shipped, rebuilt = tmp_path / "shipped", tmp_path / "rebuilt"
    for folder in (shipped, rebuilt):
        with zipfile.ZipFile(path) as zf:
            zf.extractall(folder)
    shutil.rmtree(rebuilt / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(str(rebuilt.resolve()), build_dir=str(tmp_path / "build"))
    rec = read_record(bundled_records_dir() / "Eboth.csv")
    times = np.arange(rec.n_samples) * rec.sample_period_s
    opening = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
    outputs = []
    for root in (shipped, rebuilt):
        driver = open_fmu(root, root.name, logging_on=False)
        try:
            outputs.append(fmu_run(driver, times, opening, rec.flow_m3h))
        finally:
            driver.close()
    assert outputs[0].size > 1000 and np.array_equal(outputs[0], outputs[1])
