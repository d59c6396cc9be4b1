"""Build the pythonfmu backend of a plant FMU.

The slave is ``slave_template.py`` with the description embedded as JSON and the sources of
the FMI guard (``slave_guard.py``), the state checks (``slave_state.py``), the effect blocks,
the physical kernel and the slave's own parts (:data:`PARTS`: what they share, and one mixin
per family, each without its imports of gatetwin) pasted in, so the FMU carries its own code
and needs neither gatetwin nor numpy where it runs (only a Python with the pythonfmu runtime
that pythonfmu bundles into the FMU). pythonfmu's own modelDescription.xml
lacks ModelStructure/InitialUnknowns, units and descriptions; it is replaced by the one
rendered from the same description as the C FMU's, keeping pythonfmu's modelIdentifier (the
name of the binary it ships).
"""

from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from gatetwin.errors import ExportError
from gatetwin.fmu.description import (
    CoSimulationFlags,
    FmuDescription,
    model_description_xml,
    slave_config,
)

__all__ = [
    "BLOCKS",
    "FLAGS",
    "GUARD",
    "KERNEL",
    "PARTS",
    "STATE",
    "TEMPLATE",
    "blocks_source",
    "build_python_fmu",
    "guard_source",
    "kernel_source",
    "module_name",
    "module_source",
    "part_source",
    "slave_source",
]

TEMPLATE = Path(__file__).with_name("slave_template.py")
BLOCKS = Path(__file__).resolve().parents[1] / "plant" / "blocks.py"
_CONFIG_LINE = 'CONFIG_JSON = "{}"  # replaced at export by gatetwin.fmu.python_build'
_BLOCKS_BEGIN = "# BEGIN gatetwin.plant.blocks\n"
_BLOCKS_END = "# END gatetwin.plant.blocks\n"
GUARD = Path(__file__).with_name("slave_guard.py")
_GUARD_BEGIN = "# BEGIN gatetwin.fmu.slave_guard\n"
_GUARD_END = "# END gatetwin.fmu.slave_guard\n"
STATE = Path(__file__).with_name("slave_state.py")
_STATE_BEGIN = "# BEGIN gatetwin.fmu.slave_state\n"
_STATE_END = "# END gatetwin.fmu.slave_state\n"
KERNEL = Path(__file__).resolve().parents[1] / "plant" / "physical_kernel.py"
_KERNEL_BEGIN = "# BEGIN gatetwin.plant.physical_kernel\n"
_KERNEL_END = "# END gatetwin.plant.physical_kernel\n"
#: The slave's own parts, each spliced in between the template's markers named after it: what
#: the parts share (CONFIG, PlantError), then the ARX, FOPDT and physical families.
PARTS = tuple(Path(__file__).with_name(f"slave_{name}.py")
              for name in ("config", "arx", "fopdt", "physical"))  # fmt: skip
_IMPORTS_BEGIN = "# BEGIN gatetwin imports (removed at export: the slave defines these names)\n"
_IMPORTS_END = "# END gatetwin imports\n"
#: pythonfmu 0.7.0 serialises FMU states through ``Fmi2Slave._fmu_state_to_bytes`` (JSON);
#: the FMU needs a Python interpreter, hence needsExecutionTool.
FLAGS = CoSimulationFlags(
    needs_execution_tool=True,
    can_serialize_fmu_state=True,
    can_not_use_memory_management_functions=True,
)


def _embedded(path: Path, name: str) -> str:
    """A module's source without its docstring and ``__future__`` import (the slave has its
    own), to be pasted into the slave."""
    text = path.read_text(encoding="utf-8")
    body = text.split("from __future__ import annotations\n", 1)[-1]
    return f"# {name}, embedded at export\n" + body.strip() + "\n"


def blocks_source() -> str:
    """gatetwin/plant/blocks.py (standard library only), embedded."""
    return _embedded(BLOCKS, "gatetwin/plant/blocks.py")


def guard_source() -> str:
    """gatetwin/fmu/slave_guard.py (standard library and pythonfmu only), embedded."""
    return _embedded(GUARD, "gatetwin/fmu/slave_guard.py")


def module_source(path: Path) -> str:
    """gatetwin/plant/<path> (standard library only) run as a module of its own inside the
    slave, bound to its stem."""
    text, stem = path.read_text(encoding="utf-8"), path.stem
    return (
        f"# gatetwin/plant/{path.name}, embedded at export\n"
        "import types as _types\n\n"
        f"_{stem.upper()}_SOURCE = {text!r}\n"
        f'{stem} = _types.ModuleType("{stem}")\n'
        f'exec(compile(_{stem.upper()}_SOURCE, "{path.name}", "exec"), {stem}.__dict__)\n'
    )


def kernel_source() -> str:
    """gatetwin/plant/physical_kernel.py run as a module of its own inside the slave."""
    return module_source(KERNEL)


def part_source(path: Path) -> str:
    """gatetwin/fmu/<path> (one of :data:`PARTS`) embedded without its imports of gatetwin,
    whose names the slave defines itself."""
    text = _embedded(path, f"gatetwin/fmu/{path.name}")
    return _splice(text, _IMPORTS_BEGIN, _IMPORTS_END, "", path.name)


def _splice(text: str, begin: str, end: str, body: str, where: str = TEMPLATE.name) -> str:
    head, sep, rest = text.partition(begin)
    _, sep_end, tail = rest.partition(end)
    if not (sep and sep_end):
        raise ExportError(f"{where}: {begin.strip()} markers missing")
    return head + body + tail


def slave_source(desc: FmuDescription) -> str:
    """The slave module with the description, its parts and the effect-block kernels
    embedded."""
    text = TEMPLATE.read_text(encoding="utf-8")
    text = _splice(text, _BLOCKS_BEGIN, _BLOCKS_END, blocks_source())
    text = _splice(text, _GUARD_BEGIN, _GUARD_END, guard_source())
    text = _splice(text, _STATE_BEGIN, _STATE_END,
                   _embedded(STATE, "gatetwin/fmu/slave_state.py"))  # fmt: skip
    text = _splice(text, _KERNEL_BEGIN, _KERNEL_END, kernel_source())
    for path in PARTS:
        text = _splice(text, f"# BEGIN gatetwin.fmu.{path.stem}\n",
                       f"# END gatetwin.fmu.{path.stem}\n", part_source(path))  # fmt: skip
    if text.count(_CONFIG_LINE) != 1:
        raise ExportError(f"{PARTS[0].name}: CONFIG_JSON marker line missing")
    config = json.dumps(slave_config(desc), sort_keys=True, allow_nan=False)
    return text.replace(_CONFIG_LINE, f"CONFIG_JSON = {config!r}")


def module_name(desc: FmuDescription) -> str:
    """A module name unique per model: pythonfmu imports every slave into one interpreter."""
    return "gatetwin_slave_" + desc.guid.strip("{}").replace("-", "")[:16]


def build_python_fmu(
    desc: FmuDescription, work_dir: Path, resources: list[Path], out: Path
) -> None:
    """Build the pythonfmu FMU ``out`` (a zip) from ``desc``; ``resources`` go to resources/."""
    try:
        from pythonfmu import FmuBuilder
    except ImportError as exc:
        raise ExportError(f"the python backend needs pythonfmu ({exc})") from None
    script = work_dir / f"{module_name(desc)}.py"
    script.write_text(slave_source(desc), encoding="utf-8")
    built = work_dir / "pythonfmu" / f"{desc.model_identifier}.fmu"
    built.parent.mkdir()
    saved_path = list(sys.path)
    try:
        FmuBuilder.build_FMU(
            script,
            dest=built,
            project_files=resources,
            needsExecutionTool=FLAGS.needs_execution_tool,
            canGetAndSetFMUstate=True,
            canSerializeFMUstate=FLAGS.can_serialize_fmu_state,
        )
    except Exception as exc:  # pythonfmu raises plain exceptions of many kinds
        raise ExportError(f"pythonfmu build failed: {exc}") from None
    finally:  # the builder imports the script and leaves it on sys.path / in sys.modules
        sys.path[:] = saved_path
        sys.modules.pop(script.stem, None)
    _replace_model_description(built, out, desc)


def _replace_model_description(built: Path, out: Path, desc: FmuDescription) -> None:
    with zipfile.ZipFile(built) as src:
        theirs = ET.fromstring(src.read("modelDescription.xml"))
        identifier = theirs.find("CoSimulation").get("modelIdentifier")
        if identifier != desc.model_identifier:
            raise ExportError(
                f"pythonfmu named the model {identifier!r}, expected {desc.model_identifier!r}"
            )
        tool = f"gatetwin via {theirs.get('generationTool')}"
        ours = model_description_xml(desc, FLAGS, tool=tool)
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
            dst.writestr("modelDescription.xml", ours)
            for item in src.infolist():
                if item.filename != "modelDescription.xml":
                    dst.writestr(item, src.read(item.filename))
