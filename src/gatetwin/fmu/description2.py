"""``modelDescription.xml`` of the FMI 2.0 co-simulation FMU, of any component, for both
backends, and the parts the FMI 3.0 one (:mod:`gatetwin.fmu.description3`) writes alike.

Renders a description (:class:`~gatetwin.fmu.interface.ComponentInterface`: a plant's
:class:`~gatetwin.fmu.description.FmuDescription` or a controller's); every attribute is
escaped and the document parsed back. Not the C configuration
(:mod:`gatetwin.fmu.config_header`) and not the description itself
(:mod:`gatetwin.fmu.description`).
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.etree import ElementTree as ET

from gatetwin.fmu.checks import check_well_formed, xml_text
from gatetwin.fmu.interface import LOG_CATEGORIES, UNITS, ComponentInterface, VariableSpec

__all__ = [
    "CoSimulationFlags",
    "finished_xml",
    "initial_dependencies",
    "model_description_xml",
    "shared_elements",
    "xml_bool",
]


@dataclass(frozen=True)
class CoSimulationFlags:
    """The ``CoSimulation`` element's capability flags of one backend."""

    needs_execution_tool: bool
    can_serialize_fmu_state: bool
    can_not_use_memory_management_functions: bool
    source_files: tuple[str, ...] = ()


def model_description_xml(desc: ComponentInterface, flags: CoSimulationFlags, tool: str) -> bytes:
    """``modelDescription.xml`` (FMI 2.0, co-simulation) for either backend, of a plant or of
    a controller.

    Every attribute passes through :func:`~gatetwin.fmu.checks.xml_text` and the result is
    parsed back, so the file is well-formed XML whatever text the model carried.
    """
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": desc.model_identifier,
            "guid": desc.guid,
            "description": desc.summary,
            "generationTool": tool,
            "variableNamingConvention": "structured",
            "numberOfEventIndicators": "0",
        },
    )
    cs = ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": desc.model_identifier,
            "needsExecutionTool": xml_bool(flags.needs_execution_tool),
            "canHandleVariableCommunicationStepSize": "true",
            "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canNotUseMemoryManagementFunctions": xml_bool(
                flags.can_not_use_memory_management_functions
            ),
            "canGetAndSetFMUstate": "true",
            "canSerializeFMUstate": xml_bool(flags.can_serialize_fmu_state),
            "providesDirectionalDerivative": "false",
        },
    )
    if flags.source_files:
        files = ET.SubElement(cs, "SourceFiles")
        for name in flags.source_files:
            ET.SubElement(files, "File", {"name": name})
    shared_elements(root, desc)
    _model_variables(root, desc)
    _model_structure(root, desc)
    return finished_xml(root, f"{desc.model_identifier}: modelDescription.xml")


def shared_elements(root: ET.Element, desc: ComponentInterface) -> None:
    """What both FMI versions write alike: units, log categories, default experiment."""
    _unit_definitions(root)
    categories = ET.SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES.items():
        ET.SubElement(categories, "Category", {"name": name, "description": text})
    ET.SubElement(
        root, "DefaultExperiment", {"startTime": "0.0", "stepSize": repr(desc.step_size_s)}
    )


def finished_xml(root: ET.Element, what: str) -> bytes:
    """The document's bytes, every attribute escaped and the result parsed back."""
    for element in root.iter():
        for key, value in element.attrib.items():
            element.set(key, xml_text(value))
    ET.indent(root)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"
    check_well_formed(xml, what)
    return xml


def xml_bool(value: bool) -> str:
    return "true" if value else "false"


def _unit_definitions(root: ET.Element) -> None:
    units = ET.SubElement(root, "UnitDefinitions")
    for name, (_, exponents, factor) in UNITS.items():
        unit = ET.SubElement(units, "Unit", {"name": name})
        base = {k: str(v) for k, v in exponents.items()}
        if factor != 1.0:
            base["factor"] = repr(factor)
        ET.SubElement(unit, "BaseUnit", base)


def _model_variables(root: ET.Element, desc: ComponentInterface) -> None:
    variables = ET.SubElement(root, "ModelVariables")
    for v in desc.variables:
        attrs = {
            "name": v.name,
            "valueReference": str(v.vr),
            "description": v.description,
            "causality": v.causality,
            "variability": v.variability,
        }
        if v.initial is not None:
            attrs["initial"] = v.initial
        sv = ET.SubElement(variables, "ScalarVariable", attrs)
        real = {"unit": v.unit}
        if v.start is not None:
            real["start"] = repr(float(v.start))
        ET.SubElement(sv, "Real", real)


def initial_dependencies(desc: ComponentInterface) -> list[VariableSpec]:
    """The inputs and parameters the output's initial value depends on: those marked
    ``initial_dependency`` but the dynamics-only columns (time constant, dead time, sample
    period); for a plant, what its equilibrium depends on."""
    dynamic_only = {"time_constant_s", "dead_time_s", "sample_period_s"}
    return [
        v
        for v in desc.variables
        if v.causality in ("input", "parameter")
        and v.initial_dependency
        and not any(v.name.startswith(f"schedule.{c}[") or v.name == c for c in dynamic_only)
    ]


def _model_structure(root: ET.Element, desc: ComponentInterface) -> None:
    """The outputs have no direct feedthrough; initially they depend on
    :func:`initial_dependencies` (a plant's output: the equilibrium of the inputs)."""
    index = {v.name: i for i, v in enumerate(desc.variables, start=1)}
    initial_deps = [index[v.name] for v in initial_dependencies(desc)]
    structure = ET.SubElement(root, "ModelStructure")
    # every output (a plant has one; a controller FMU has its command and diagnostics)
    outs = [index[v.name] for v in desc.variables if v.causality == "output"]
    outputs = ET.SubElement(structure, "Outputs")
    for out in outs:
        ET.SubElement(outputs, "Unknown", {"index": str(out), "dependencies": ""})
    initial = ET.SubElement(structure, "InitialUnknowns")
    for out in outs:
        ET.SubElement(
            initial,
            "Unknown",
            {
                "index": str(out),
                "dependencies": " ".join(map(str, initial_deps)),
            },
        )
