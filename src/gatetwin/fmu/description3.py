"""``modelDescription.xml`` of the FMI 3.0 co-simulation FMU, from the same description.

The FMI 3.0 FMU renders the description the FMI 2.0 one renders, of any component
(:class:`~gatetwin.fmu.description.ComponentInterface`: a plant's
:class:`~gatetwin.fmu.description.FmuDescription` or a controller's
:class:`~gatetwin.fmu.controller.ControllerDescription`): same variables, value references,
units, start values, causality and variability, log categories, default experiment and
provenance summary. What FMI 3.0 writes
differently:

* the root carries ``instantiationToken`` (the FMI 2.0 ``guid``);
* every variable is a ``<Float64>`` element (no ``ScalarVariable`` wrapper);
* FMI 3.0 has an independent variable: ``time`` (s), value reference ``len(variables)``,
  one past the component's Real variables (``VR_TIME`` in ``fmi3_glue.c``);
* ``ModelStructure`` names variables by value reference (FMI 2.0: by index);
* the capability flags are FMI 3.0's: no event mode, no early return, no intermediate update.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from gatetwin.fmu.description import (
    ComponentInterface,
    CoSimulationFlags,
    finished_xml,
    initial_dependencies,
    shared_elements,
    xml_bool,
)

__all__ = ["TIME_NAME", "model_description_xml3", "time_vr"]

#: Name of FMI 3.0's independent variable.
TIME_NAME = "time"


def time_vr(desc: ComponentInterface) -> int:
    """Value reference of ``time``: one past the component's Real variables."""
    return len(desc.variables)


def model_description_xml3(desc: ComponentInterface, flags: CoSimulationFlags, tool: str) -> bytes:
    """``modelDescription.xml`` (FMI 3.0, co-simulation) of the C backend, of a plant or of a
    controller.

    Every attribute passes through :func:`~gatetwin.fmu.checks.xml_text` and the result is
    parsed back, so the file is well-formed XML whatever text the model carried.
    """
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "3.0",
            "modelName": desc.model_identifier,
            "instantiationToken": desc.guid,
            "description": desc.summary,
            "generationTool": tool,
            "variableNamingConvention": "structured",
        },
    )
    ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": desc.model_identifier,
            "needsExecutionTool": xml_bool(flags.needs_execution_tool),
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canGetAndSetFMUState": "true",
            "canSerializeFMUState": xml_bool(flags.can_serialize_fmu_state),
            "providesDirectionalDerivatives": "false",
            "providesAdjointDerivatives": "false",
            "canHandleVariableCommunicationStepSize": "true",
            "maxOutputDerivativeOrder": "0",
            "providesIntermediateUpdate": "false",
            "mightReturnEarlyFromDoStep": "false",
            "canReturnEarlyAfterIntermediateUpdate": "false",
            "hasEventMode": "false",
            "providesEvaluateDiscreteStates": "false",
        },
    )
    shared_elements(root, desc)
    _model_variables(root, desc)
    _model_structure(root, desc)
    return finished_xml(root, f"{desc.model_identifier}: modelDescription.xml (FMI 3.0)")


def _model_variables(root: ET.Element, desc: ComponentInterface) -> None:
    variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(
        variables,
        "Float64",
        {
            "name": TIME_NAME,
            "valueReference": str(time_vr(desc)),
            "description": "Simulation time",
            "causality": "independent",
            "variability": "continuous",
            "unit": "s",
        },
    )
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
        attrs["unit"] = v.unit
        if v.start is not None:
            attrs["start"] = repr(float(v.start))
        ET.SubElement(variables, "Float64", attrs)


def _model_structure(root: ET.Element, desc: ComponentInterface) -> None:
    """As FMI 2.0's: no direct feedthrough; initially the outputs depend on
    :func:`~gatetwin.fmu.description.initial_dependencies` (a plant: the inputs' equilibrium;
    the PI: its start opening)."""
    structure = ET.SubElement(root, "ModelStructure")
    outs = [str(v.vr) for v in desc.variables if v.causality == "output"]
    for out in outs:
        ET.SubElement(structure, "Output", {"valueReference": out, "dependencies": ""})
    deps = " ".join(str(v.vr) for v in initial_dependencies(desc))
    for out in outs:
        ET.SubElement(structure, "InitialUnknown", {"valueReference": out, "dependencies": deps})
