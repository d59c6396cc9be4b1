"""Build the C backend of a plant FMU: sources from ``fmu_templates/``, compiled here.

The FMU folder gets ``binaries/<platform>/<modelIdentifier>.so`` (built with ``$CC`` or
``cc``/``gcc``), ``sources/`` (every C file and header, the generated ``model_config.h`` and
``BUILD.txt`` with the compile line; the files are also listed in ``SourceFiles``) and
``modelDescription.xml``. This module does not zip or place the FMU; see :func:`export_fmu`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shlex
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gatetwin.errors import ExportError, OutputError
from gatetwin.fmu.description import (
    ComponentInterface,
    CoSimulationFlags,
    FmuDescription,
    model_config_header,
    model_description_xml,
)
from gatetwin.fmu.description3 import model_description_xml3

__all__ = [
    "CFLAGS",
    "COMMON_HEADERS",
    "COMMON_SOURCES",
    "FLAGS",
    "FMI_APIS",
    "GENERATED_SUPPORT_FILES",
    "GENERATED_SUPPORT_SOURCES",
    "GLUE_CORE_HEADERS",
    "GLUE_CORE_SOURCES",
    "HOST_FLAGS",
    "KERNEL_HEADERS",
    "KERNEL_PREFIX",
    "KERNEL_SOURCES",
    "Builds",
    "FmiApi",
    "build_both_apis",
    "build_c_fmu",
    "build_description_xml",
    "build_generated_component",
    "c_double",
    "check_fmi_version",
    "compile_command",
    "compile_shared",
    "find_compiler",
    "fmu_target",
    "generated_blocks",
    "generated_kernel",
    "package_host_fmu",
    "source_files",
    "templates_dir",
    "write_atomically",
    "write_sources",
    "zip_folder",
]

#: Compile flags of every C FMU; -ffp-contract=off keeps compilers from fusing a*b+c into
#: one FMA, which would change results in the last bit against the Python reference. -O3
#: lets GCC vectorise loops of unknown length (the MPC controller's QP updates: its doStep
#: p99 at N = 100, benchmarks/bench_controller_fmu.py, fell by about 40 %). Neither GCC nor
#: clang (Zig) reorders a floating-point sum without -fassociative-math (part of
#: -ffast-math), and element-wise vector operations give the scalar bits: the results keep
#: their bits.
CFLAGS = (
    "-std=c99",
    "-O3",
    "-fPIC",
    "-shared",
    "-fvisibility=hidden",
    "-ffp-contract=off",
    "-Wall",
    "-Wextra",
    "-Werror",
)
#: Added for the host's binary: link-time optimisation inlines across the component's files
#: (the effect blocks a model does not carry become nothing, the schedule lookup joins the
#: step). It changes no arithmetic: FMPy's CMake rebuild from sources/, without it, gives the
#: shipped binary's bits (the cross-compiled binaries are built without it too: Zig's MinGW
#: target cannot link it).
HOST_FLAGS = ("-flto",)
#: blocks.c/.h are generated from gatetwin.plant.blocks (:func:`generated_blocks`).
#: component.c (the variable table and the message formatter)
#: serves every component.
COMMON_SOURCES = ("component.c", "plant.c", "support.c", "effects.c", "blocks.c")
COMMON_HEADERS = ("component.h", "plant_data.h", "plant.h", "effects.h", "blocks.h")
#: What every component with casadi-generated arithmetic (the MPC controller, the observer)
#: compiles besides its own file: the variable table and message formatter, and the calls and
#: checks around the generated code (generated_support.h).
GENERATED_SUPPORT_SOURCES = ("component.c", "generated_support.c")
GENERATED_SUPPORT_FILES = (*GENERATED_SUPPORT_SOURCES, "generated_support.h")


#: What both FMI glues build on (the instance, logging, modes, FMU states, the step).
GLUE_CORE_SOURCES = ("glue_core.c",)
GLUE_CORE_HEADERS = ("glue_core.h",)


@dataclass(frozen=True)
class FmiApi:
    """What one FMI version adds to the component: its glue, headers and their licence."""

    version: str
    glue: str
    headers: tuple[str, ...]
    license: str

    @property
    def glue_sources(self) -> tuple[str, ...]:
        """The C files of the glue, in compile order: the version's own, then the core."""
        return (self.glue, *GLUE_CORE_SOURCES)

    @property
    def glue_headers(self) -> tuple[str, ...]:
        """The headers the glue includes: the version's, then the core's."""
        return (*self.headers, *GLUE_CORE_HEADERS)


#: The FMI APIs a C FMU can carry, by ``fmiVersion``.
FMI_APIS = {
    api.version: api
    for api in (
        FmiApi("2.0", "fmi2_glue.c",
               ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               "LICENSE-FMI2-headers.txt"),
        FmiApi("3.0", "fmi3_glue.c",
               ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"),
               "LICENSE-FMI3-headers.txt"),
    )
}  # fmt: skip
FLAGS = CoSimulationFlags(
    needs_execution_tool=False,
    can_serialize_fmu_state=True,
    can_not_use_memory_management_functions=False,
)


def check_fmi_version(fmi_version: object) -> str:
    """``fmi_version`` if a glue exists for it (a key of :data:`FMI_APIS`); else
    :class:`ExportError` naming the versions there are."""
    if not isinstance(fmi_version, str) or fmi_version not in FMI_APIS:
        raise ExportError(f"fmi_version must be one of {', '.join(FMI_APIS)} (got "
                          f"{str(fmi_version)[:20]!r})")  # fmt: skip
    return fmi_version


def templates_dir() -> Path:
    """The C templates: packaged copy (``gatetwin/fmu/templates``) or the repository's."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "templates", here.parents[2] / "fmu_templates"):
        if (candidate / "fmi2_glue.c").is_file():
            return candidate
    raise ExportError("FMU C templates not found (gatetwin/fmu/templates or fmu_templates/)")


def find_compiler() -> list[str]:
    """The C compiler command: ``$CC`` if set, else ``cc`` or ``gcc`` on the PATH."""
    from_env = shlex.split(os.environ.get("CC", ""))
    if from_env and shutil.which(from_env[0]):
        return from_env
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path:
            return [path]
    raise ExportError("no C compiler found (looked for $CC, cc, gcc); use --backend python")


#: The C rendering of gatetwin.plant.physical_kernel (generated) and its fixed support code.
KERNEL_SOURCES = ("physical_kernel.c", "kernel_point.c", "kernel_support.c")
KERNEL_HEADERS = ("physical_kernel.h", "kernel_point.h", "kernel_support.h")
#: Prefix of the generated kernel functions and macros.
KERNEL_PREFIX = "gt_"


def source_files(
    family: str, with_kernel: bool = False, fmi_version: str = "2.0"
) -> tuple[str, ...]:
    """The C files compiled for one family, in compile order."""
    kernel = KERNEL_SOURCES if with_kernel or family == "physical" else ()
    return (*FMI_APIS[fmi_version].glue_sources, *COMMON_SOURCES, *kernel, f"model_{family}.c")


def generated_kernel() -> dict[str, str]:
    """File name -> text of the C rendering of the physical kernel."""
    from gatetwin.plant import physical_kernel
    from gatetwin.plant.kernel_render import c_source

    source, header = c_source(physical_kernel, KERNEL_PREFIX)
    return {"physical_kernel.c": source, "physical_kernel.h": header}


def generated_blocks() -> dict[str, str]:
    """File name -> text of the C rendering of the effect blocks' arithmetic."""
    from gatetwin.plant import blocks
    from gatetwin.plant.ast_render import c_module

    source, header = c_module(blocks, blocks.RENDERED_C, KERNEL_PREFIX)
    return {"blocks.c": source, "blocks.h": header}


def write_sources(
    desc: FmuDescription, sources_dir: Path, fmi_version: str = "2.0"
) -> tuple[str, ...]:
    """Copy the templates one model needs into ``sources_dir`` and generate model_config.h."""
    templates = templates_dir()
    sources_dir.mkdir(parents=True, exist_ok=True)
    with_kernel = desc.kernel_first is not None
    api = FMI_APIS[fmi_version]
    c_files = source_files(desc.family, with_kernel, fmi_version)
    generated = {**generated_blocks(), **(generated_kernel() if with_kernel else {})}
    headers = (*api.glue_headers, *COMMON_HEADERS, *(KERNEL_HEADERS if with_kernel else ()))
    for name in (*c_files, *headers, f"model_{desc.family}.h", api.license):
        if name not in generated:
            shutil.copyfile(templates / name, sources_dir / name)
    for name, text in generated.items():
        (sources_dir / name).write_text(text, encoding="utf-8")
    (sources_dir / "model_config.h").write_text(model_config_header(desc), encoding="utf-8")
    line = " ".join(["cc", *CFLAGS, "-o", f"{desc.model_identifier}.so", *c_files, "-lm"])
    (sources_dir / "BUILD.txt").write_text(
        "Build the FMU binary from this folder (any C99 compiler with the same flags):\n\n"
        f"    {line}\n\nmodel_config.h is generated by gatetwin (gatetwin.fmu.description)"
        + ", blocks.c and blocks.h from gatetwin.plant.blocks"
        + (
            ", physical_kernel.c and physical_kernel.h from gatetwin.plant.physical_kernel"
            if with_kernel
            else ""
        )
        + "; the other files\nare gatetwin's fixed FMU templates.\n",
        encoding="utf-8",
    )
    (sources_dir / "buildDescription.xml").write_bytes(build_description_xml(desc, c_files))
    return c_files


def build_description_xml(desc: ComponentInterface, c_files: tuple[str, ...]) -> bytes:
    """``sources/buildDescription.xml`` (the FMI build description, the format FMI 3.0
    defines and FMI 2.0.4 adopts): one build configuration, the C99 sources, the compiler
    options the shipped binaries are built with."""
    import xml.etree.ElementTree as ET

    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    config = ET.SubElement(root, "BuildConfiguration", modelIdentifier=desc.model_identifier)
    options = " ".join(f for f in CFLAGS if f not in ("-shared", "-std=c99"))
    files = ET.SubElement(config, "SourceFileSet", language="C99", compilerOptions=options)
    for name in c_files:
        ET.SubElement(files, "SourceFile", name=name)
    ET.SubElement(config, "Library", name="m", description="the C math library (libm)")
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def fmu_target(out_path: str | os.PathLike[str]) -> Path:
    """``out_path`` as a path, refused unless it ends in ``.fmu``."""
    target = Path(out_path)
    if target.suffix.lower() != ".fmu":
        raise ExportError(f"output {target} must end in .fmu")
    return target


def write_atomically(target: Path, build: Callable[[Path, str], Path]) -> Path:
    """``build(work, file_name)`` in a folder beside ``target`` (removed afterwards); what it
    returns is moved onto ``target``, so a failed build leaves nothing behind."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
            os.replace(build(Path(tmp), target.name), target)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write the FMU ({exc.strerror or exc})") from None
    return target


def c_double(value: float) -> str:
    """``value`` as a C double literal (``repr``, with ``.0`` where it has no point)."""
    text = repr(float(value))
    return text if any(c in text for c in ".en") else text + ".0"


def zip_folder(folder: Path, out: Path) -> None:
    """Zip every file under ``folder`` into ``out`` (an FMU or an SSP), paths relative to it."""
    import zipfile

    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(folder).as_posix())


def package_host_fmu(
    desc: ComponentInterface,
    fmu_dir: Path,
    c_files: tuple[str, ...],
    out: Path,
    provenance: dict[str, Any],
    fmi_version: str = "2.0",
) -> None:
    """Finish a component FMU whose ``fmu_dir/sources`` hold ``c_files``: the host's binary in
    ``fmi_version``'s folder, modelDescription.xml, ``resources/provenance.json``
    (``provenance``), all zipped into ``out``."""
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    folder = platform if fmi_version == "2.0" else platform_tuple
    binary = fmu_dir / "binaries" / folder / f"{desc.model_identifier}{sharedLibraryExtension}"
    binary.parent.mkdir(parents=True)
    compile_shared(fmu_dir / "sources", c_files, binary)
    flags = dataclasses.replace(FLAGS, source_files=c_files)
    render = model_description_xml if fmi_version == "2.0" else model_description_xml3
    (fmu_dir / "modelDescription.xml").write_bytes(render(desc, flags, tool="gatetwin (C backend)"))
    (fmu_dir / "resources").mkdir()
    text = json.dumps(provenance, indent=2, sort_keys=True, allow_nan=False)
    (fmu_dir / "resources" / "provenance.json").write_text(text + "\n", encoding="utf-8")
    zip_folder(fmu_dir, out)


def build_generated_component(
    fmu_dir: Path,
    desc: object,
    *,
    component_files: tuple[str, ...],
    generated_stem: str,
    config_header: str,
    generated_by: str,
    tool: str,
    fmi_version: str = "2.0",
    also_compile: tuple[str, ...] = (),
) -> None:
    """Lay out the C FMU of a component whose arithmetic is generated (the MPC controller,
    the observer) in ``fmu_dir``: the generated ``<generated_stem>.c``/``.h`` are already in
    ``fmu_dir/sources``; this adds ``fmi_version``'s glue and headers, ``component.h``,
    :data:`GENERATED_SUPPORT_FILES`, the component's fixed ``component_files`` (its ``.c``
    first), ``model_config.h``, ``BUILD.txt``, the host's binary and ``modelDescription.xml``
    (``desc`` as :func:`~gatetwin.fmu.description.model_description_xml` takes it). The
    component is the same under either API: only the glue and the description's rendering
    differ. ``also_compile`` names further C files the component calls (already in
    ``fmu_dir/sources`` or among ``component_files``)."""
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    api = FMI_APIS[fmi_version]
    sources = fmu_dir / "sources"
    c_files = (*api.glue_sources, *GENERATED_SUPPORT_SOURCES, component_files[0],
               f"{generated_stem}.c", *also_compile)  # fmt: skip
    templates = templates_dir()
    for name in (*api.glue_sources, *GENERATED_SUPPORT_FILES, *component_files,
                 *api.glue_headers, "component.h", api.license):  # fmt: skip
        shutil.copyfile(templates / name, sources / name)
    (sources / "model_config.h").write_text(config_header, encoding="utf-8")
    line = " ".join(["cc", *CFLAGS, "-o", f"{desc.model_identifier}.so", *c_files, "-lm"])
    (sources / "BUILD.txt").write_text(
        f"Build the FMU binary from this folder:\n\n    {line}\n\nmodel_config.h, "
        f"{generated_stem}.c and {generated_stem}.h are generated by gatetwin ({generated_by} "
        "with casadi.CodeGenerator);\nthe other files are gatetwin's fixed FMU templates.\n",
        encoding="utf-8",
    )
    name = f"{desc.model_identifier}{sharedLibraryExtension}"
    folder = platform if fmi_version == "2.0" else platform_tuple
    binary = fmu_dir / "binaries" / folder / name
    binary.parent.mkdir(parents=True)
    compile_shared(sources, c_files, binary)
    flags = dataclasses.replace(FLAGS, source_files=c_files)
    render = model_description_xml if fmi_version == "2.0" else model_description_xml3
    (fmu_dir / "modelDescription.xml").write_bytes(render(desc, flags, tool=tool))


def compile_command(
    c_files: tuple[str, ...],
    out: Path,
    extra_flags: tuple[str, ...] = (),
    compiler: list[str] | None = None,
) -> list[str]:
    """The command line :func:`compile_shared` runs (in the sources' folder)."""
    # absolute: the compiler runs in sources_dir, so a relative output path would miss
    return [*(compiler or find_compiler()), *CFLAGS, *extra_flags, "-o",
            str(Path(out).resolve()), *c_files, "-lm"]  # fmt: skip


def compile_shared(
    sources_dir: Path,
    c_files: tuple[str, ...],
    out: Path,
    extra_flags: tuple[str, ...] = (),
    compiler: list[str] | None = None,
) -> None:
    """Compile ``c_files`` in ``sources_dir`` into the shared library ``out`` (with
    ``compiler``, default the system's)."""
    cmd = compile_command(c_files, out, extra_flags, compiler)
    try:
        done = subprocess.run(
            cmd, cwd=sources_dir, capture_output=True, text=True, timeout=300, check=False
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise ExportError(f"C compiler {cmd[0]} could not run: {exc}") from None
    if done.returncode != 0:
        lines = done.stderr.splitlines()
        # the linker's own line says why (collect2's summary line does not)
        errors = [ln for ln in lines if "error" in ln and "collect2" not in ln]
        errors = errors or [ln for ln in lines if " ld:" in ln or ln.startswith("ld:")] or lines
        first = errors[0] if errors else f"exit status {done.returncode}"
        raise ExportError(f"C compiler {cmd[0]} failed: {first.strip()}")


#: C binaries already built: (bytes, file mode) by the digest of what each was built from
#: (:func:`build_both_apis`).
Builds = dict[str, tuple[bytes, int]]


def build_both_apis(
    sources_dir: Path,
    c_files: tuple[str, ...],
    out: Path,
    extra_flags: tuple[str, ...] = (),
    compiler: list[str] | None = None,
    builds: Builds | None = None,
) -> None:
    """Build a plant's binary ``out`` from ``sources_dir`` with the glue of every FMI version
    compiled in, not only the one of the FMU's ``sources/`` (which, built on their own, give
    a binary exporting that version's functions alone, with the same arithmetic). The FMI
    2.0 and 3.0 FMUs of one plant compile the same component with the same compiler and
    flags, so with the same ``builds`` (a dict the caller keeps) the second takes the
    first's binary, found by the digest of the compile command and of every C file and
    header compiled; ``None`` builds afresh."""
    templates = templates_dir()
    glues = tuple(api.glue for api in FMI_APIS.values())
    files = (*glues, *(f for f in c_files if f not in glues))
    with tempfile.TemporaryDirectory(prefix="gatetwin-build-") as tmp:
        build = Path(tmp)
        for path in sources_dir.iterdir():
            if path.suffix in (".c", ".h"):
                shutil.copyfile(path, build / path.name)
        for api in FMI_APIS.values():
            for name in (api.glue, *api.headers):
                if not (build / name).exists():
                    shutil.copyfile(templates / name, build / name)
        command = compile_command(files, build / "binary", extra_flags, compiler)
        at = command.index("-o")  # the output's path aside
        digest = hashlib.sha256(json.dumps(command[:at] + command[at + 2 :]).encode())
        for path in sorted(build.iterdir()):
            digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
        key = digest.hexdigest()
        if builds is not None and key in builds:
            data, mode = builds[key]
            out.write_bytes(data)
            out.chmod(mode)
            return
        compile_shared(build, files, out, extra_flags, compiler)
        if builds is not None:
            builds[key] = (out.read_bytes(), out.stat().st_mode & 0o777)


def build_c_fmu(
    desc: FmuDescription,
    fmu_dir: Path,
    platform: str,
    extension: str,
    platforms: tuple[str, ...] = (),
    fmi_version: str = "2.0",
    builds: Builds | None = None,
) -> None:
    """Lay out the C FMU in ``fmu_dir`` (sources, binaries, modelDescription.xml): the host's
    binary in ``binaries/<platform>``, and one per other folder of ``platforms``
    (:func:`gatetwin.fmu.platforms.platforms_of`), cross-compiled; each binary taken from
    ``builds`` where it holds it (:func:`build_both_apis`)."""
    from gatetwin.fmu.platforms import Platform, platforms_of, zig_cc

    sources_dir = fmu_dir / "sources"
    c_files = write_sources(desc, sources_dir, fmi_version)
    binary_dir = fmu_dir / "binaries" / platform
    binary_dir.mkdir(parents=True, exist_ok=True)
    build_both_apis(sources_dir, c_files, binary_dir / f"{desc.model_identifier}{extension}",
                    HOST_FLAGS, builds=builds)  # fmt: skip
    known = platforms_of(fmi_version)
    foreign = [known[f] for f in platforms if f != platform]

    def cross(target: Platform) -> None:
        out = fmu_dir / "binaries" / target.folder / f"{desc.model_identifier}{target.extension}"
        out.parent.mkdir(parents=True, exist_ok=True)
        build_both_apis(sources_dir, c_files, out, compiler=zig_cc(target.zig_target),
                        builds=builds)  # fmt: skip
        for extra in out.parent.iterdir():  # the linker's import library and debug database
            if extra != out:
                extra.unlink()

    # each compiler is its own process: as many at once as there are CPUs
    with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:
        list(pool.map(cross, foreign))
    flags = dataclasses.replace(FLAGS, source_files=c_files)
    render = model_description_xml if fmi_version == "2.0" else model_description_xml3
    (fmu_dir / "modelDescription.xml").write_bytes(render(desc, flags, tool="gatetwin (C backend)"))
