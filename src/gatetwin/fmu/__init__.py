"""Export a plant as an FMI co-simulation FMU: FMI 2.0 (C or pythonfmu backend) or FMI 3.0 (C).

Both backends render the same :class:`~gatetwin.fmu.description.FmuDescription` and follow
:class:`gatetwin.plant.simulate.PlantSimulator` operation by operation. This package builds
FMUs; validating and simulating them is left to fmpy and to gatetwin.validation.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gatetwin.errors import ExportError, OutputError
from gatetwin.fmu.checks import check_finite_response
from gatetwin.fmu.description import FmuDescription, describe
from gatetwin.plant.model import ArxPlant, FopdtPlant, PhysicalPlant, Plant, plant_to_dict

if TYPE_CHECKING:
    from gatetwin.fmu.c_build import Builds

BACKENDS = ("c", "python")
#: FMI versions an FMU can be exported in (FMI 3.0: the C backend).
FMI_VERSIONS = ("2.0", "3.0")

__all__ = ["BACKENDS", "FMI_VERSIONS", "FmuDescription", "describe", "export_fmu"]


def export_fmu(
    plant: Plant,
    out_path: str | os.PathLike[str],
    *,
    backend: str,
    model_name: str,
    provenance: dict[str, Any],
    platforms: str | tuple[str, ...] = "host",
    fmi_version: str = "2.0",
    start_inputs: tuple[float, float] | None = None,
    builds: Builds | None = None,
) -> Path:
    """Build an FMU of ``plant`` at ``out_path``; return its path.

    Parameters
    ----------
    plant : FopdtPlant or ArxPlant
        The plant to render, with its effect blocks (:mod:`gatetwin.plant.effects`; their
        parameters become tunable FMI parameters ``effect.<kind>.<parameter>``); ARX orders
        up to 8.
    out_path : path
        Target ``.fmu`` file; written atomically (built in a temporary folder next to it and
        moved into place only on success).
    backend : {"c", "python"}
        ``"c"`` compiles the C templates with ``$CC``/``cc``/``gcc``; ``"python"`` builds a
        pythonfmu FMU carrying a self-contained slave.
    model_name : str
        modelIdentifier and modelName: a C identifier.
    provenance : dict
        JSON data stored as ``resources/provenance.json``; its scalar entries are also quoted
        in the modelDescription ``description`` attribute.
    platforms : str or tuple of str
        C backend: ``"host"`` (the default), ``"all"``, or folder names of
        :func:`gatetwin.fmu.platforms.platforms_of` in the FMI version's layout
        (comma-separated, or a tuple); platforms other than the host's are cross-compiled
        with Zig (``gatetwin[cross]``).
    fmi_version : {"2.0", "3.0"}
        FMI 3.0 co-simulation: C backend; same variables, value references and outputs.
    start_inputs : (float, float), optional
        Start values of ``opening_mm`` (mm) and ``flow_m3h`` (m3/h): where the FMU rests when
        a master initialises it without setting its inputs (default: the model's reference
        opening and the middle of its discharge range).
    builds : dict, optional
        C backend: binaries already built, kept by the caller (start with ``{}``): the FMI
        2.0 and 3.0 FMUs of one plant carry one binary (both glues compiled in), so the
        second export given the same dict takes the first's binary instead of compiling
        it again (:func:`gatetwin.fmu.c_build.build_both_apis`).

    Raises
    ------
    ExportError
        Unknown backend, bad model name, gauge or plant, a plant whose output is not finite,
        no C compiler, build failure.
    OutputError
        The FMU cannot be written where asked (read-only or missing folder, disk full).
    """
    if backend not in BACKENDS:
        raise ExportError(f"backend must be one of {', '.join(BACKENDS)} (got {backend!r})")
    if not isinstance(plant, (FopdtPlant, ArxPlant, PhysicalPlant)):
        raise ExportError(
            f"cannot export {type(plant).__name__}: expected FopdtPlant, ArxPlant or PhysicalPlant"
        )
    if fmi_version not in FMI_VERSIONS:
        raise ExportError(f"fmi_version must be one of {', '.join(FMI_VERSIONS)} (got "
                          f"{str(fmi_version)[:20]!r})")  # fmt: skip
    if fmi_version == "3.0" and backend != "c":
        raise ExportError("FMI 3.0 FMUs are built by the C backend (--backend c)")
    target = Path(out_path)
    if target.suffix.lower() != ".fmu":
        raise ExportError(f"output {target} must end in .fmu")
    folders = _platform_folders(backend, platforms, fmi_version)
    desc = describe(plant, model_name, provenance, f"{backend}:{_code_digest(backend)}",
                    start_inputs)  # fmt: skip
    check_finite_response(plant, model_name, provenance)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
            _build(plant, desc, backend, Path(tmp), target, folders, fmi_version, builds)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write the FMU ({exc.strerror or exc})") from None
    return target


def _host_folder(fmi_version: str) -> str:
    """The host's folder under ``binaries/`` in ``fmi_version``'s layout."""
    from fmpy import platform, platform_tuple

    return platform if fmi_version == "2.0" else platform_tuple


def _platform_folders(
    backend: str, platforms: str | tuple[str, ...], fmi_version: str = "2.0"
) -> tuple[str, ...]:
    """The binaries' folders to build (checked before anything is built)."""
    from gatetwin.fmu.platforms import resolve, zig_cc

    platform = _host_folder(fmi_version)
    folders = resolve(platforms, platform, fmi_version)
    if backend != "c" and folders != (platform,):
        raise ExportError("platforms: the python backend runs on the exporting platform only")
    if any(f != platform for f in folders):
        zig_cc("x86_64-linux-gnu")  # one line when the cross compiler is missing
    return folders


def _build(
    plant: Plant,
    desc: FmuDescription,
    backend: str,
    work: Path,
    target: Path,
    folders: tuple[str, ...] = (),
    fmi_version: str = "2.0",
    builds: Builds | None = None,
) -> None:
    resources = _write_resources(plant, desc, backend, work / "resources")
    built = work / target.name
    if backend == "c":
        _build_c(desc, work / "fmu", resources, built, folders, fmi_version, builds)
    else:
        from gatetwin.fmu.python_build import build_python_fmu

        build_python_fmu(desc, work, resources, built)
    os.replace(built, target)


def _code_digest(backend: str) -> str:
    """sha256 (first 16 hex digits) of the code an FMU of ``backend`` is built from."""
    if backend == "c":
        from gatetwin.fmu.c_build import templates_dir

        files = sorted(p for p in templates_dir().iterdir() if p.suffix in {".c", ".h"})
    else:
        from gatetwin.fmu.python_build import GUARD, PARTS, STATE, TEMPLATE

        files = [TEMPLATE, GUARD, STATE, *PARTS]
    plant_dir = Path(__file__).resolve().parents[1] / "plant"
    files += [plant_dir / "physical_kernel.py", plant_dir / "blocks.py"]
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _write_resources(plant: Plant, desc: FmuDescription, backend: str, folder: Path) -> list[Path]:
    folder.mkdir()
    try:
        provenance = json.dumps(desc.provenance, indent=2, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ExportError(f"provenance must be JSON data without NaN ({exc})") from None
    fmu_facts = {
        "model_identifier": desc.model_identifier,
        "guid": desc.guid,
        "backend": backend,
        "variables": {v.name: v.vr for v in desc.variables},
    }
    plant_json = json.dumps({"plant": plant_to_dict(plant), "fmu": fmu_facts}, indent=2)
    (folder / "provenance.json").write_text(provenance + "\n", encoding="utf-8")
    (folder / "plant.json").write_text(plant_json + "\n", encoding="utf-8")
    return [folder / "provenance.json", folder / "plant.json"]


def _build_c(
    desc: FmuDescription,
    fmu_dir: Path,
    resources: list[Path],
    out: Path,
    folders: tuple[str, ...] = (),
    fmi_version: str = "2.0",
    builds: Builds | None = None,
) -> None:
    from fmpy import sharedLibraryExtension

    from gatetwin.fmu.c_build import build_c_fmu, zip_folder

    platform = _host_folder(fmi_version)
    build_c_fmu(desc, fmu_dir, platform, sharedLibraryExtension, folders, fmi_version, builds)
    (fmu_dir / "resources").mkdir()
    for path in resources:
        (fmu_dir / "resources" / path.name).write_bytes(path.read_bytes())
    zip_folder(fmu_dir, out)
