"""Pack the closed loop of a model as an SSP 1.0 System Structure package (``.ssp``).

The package holds ``SystemStructure.ssd``, the plant FMU (``resources/plant.fmu``, C
backend), the controller FMU (``resources/controller.fmu``, :mod:`gatetwin.fmu.controller`)
and one parameter set (``resources/closed_loop.ssv``) bound to the system. The system
``closed_loop`` has

* elements ``controller`` then ``plant`` (the order :func:`gatetwin.ssp.simulate_ssp` steps
  them in), connected plant ``level_<gauge>_mm`` → controller ``level_<gauge>_mm`` and
  controller ``opening_mm`` → plant ``opening_mm``;
* inputs ``setpoint_mm`` (→ controller) and ``flow_m3h`` (→ plant and controller), and outputs
  ``level_<gauge>_mm`` and ``opening_mm``;
* the scenario as system parameters: input ``X`` is piecewise constant, ``X.value[k]`` from
  ``X.time_s[k]`` on (``k`` from 1, the first at the start time); set-points are absolute
  levels (the scenario's offsets added to the plant's steady level at the start inputs);
* the controller's parameters (start opening, tuning, limits) in the same parameter set,
  named ``controller.<parameter>``.

SSD and SSV are checked against the SSP 1.0 schemas before anything is written.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from gatetwin.errors import ExportError, OutputError
from gatetwin.fmu.description import UNITS, output_name
from gatetwin.ssp.documents import (
    SSC,
    SSD,
    SSD_SCHEMA,
    SSV_SCHEMA,
    parameter_set_xml,
    schema_problems,
)

if TYPE_CHECKING:
    from gatetwin.fmu.controller import ControllerDescription
    from gatetwin.modelfile import ModelFile
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.loop import Scenario

#: Names inside the package.
SSD_NAME = "SystemStructure.ssd"
PLANT_SOURCE = "resources/plant.fmu"
CONTROLLER_SOURCE = "resources/controller.fmu"
PARAMETERS_SOURCE = "resources/closed_loop.ssv"
#: Controller parameters the parameter set carries.
CONTROLLER_PARAMETERS = ("start_opening_mm", "gain_mm_per_mm", "integral_time_s",
                         "tracking_time_s", "opening_min_mm", "opening_max_mm",
                         "opening_rate_mm_s")  # fmt: skip
#: Unit of each signal the system carries.
SIGNAL_UNITS = {"setpoint_mm": "mm", "flow_m3h": "m3/h"}


def scenario_signals(
    scenario: Scenario, base_level_mm: float
) -> dict[str, list[tuple[float, float]]]:
    """``{input: [(time_s, value), ...]}`` of a scenario: absolute set-points
    (``base_level_mm`` + the offsets, as :func:`gatetwin.mpc.loop.run_closed_loop` forms
    them) and discharges, each from time 0."""
    setpoint = [(0.0, base_level_mm + 0.0)]
    setpoint += [(float(t), base_level_mm + float(v)) for t, v in sorted(scenario.setpoint_changes)]
    flow = [(0.0, float(scenario.flow_m3h))]
    flow += [(float(t), float(v)) for t, v in sorted(scenario.flow_changes)]
    return {"setpoint_mm": setpoint, "flow_m3h": flow}


def _parameters(
    desc: ControllerDescription, signals: dict[str, list[tuple[float, float]]],
    start_opening_mm: float,
) -> list[tuple[str, float, str]]:  # fmt: skip
    units = {v.name: v.unit for v in desc.variables}
    values = {name: desc.start(name) for name in CONTROLLER_PARAMETERS}
    values["start_opening_mm"] = start_opening_mm
    out = [(f"controller.{n}", values[n], units[n]) for n in CONTROLLER_PARAMETERS]
    for name, points in signals.items():
        for k, (t, v) in enumerate(points, start=1):
            out += [(f"{name}.time_s[{k}]", t, "s"), (f"{name}.value[{k}]", v, SIGNAL_UNITS[name])]
    return out


def _connector(parent: object, name: str, kind: str, unit: str) -> None:
    from lxml import etree

    c = etree.SubElement(parent, f"{{{SSD}}}Connector", name=name, kind=kind)
    etree.SubElement(c, f"{{{SSC}}}Real", unit=unit)


def ssd_xml(
    name: str, gauge: str, parameters: list[tuple[str, float, str]], stop_time_s: float,
    description: str,
) -> bytes:  # fmt: skip
    """``SystemStructure.ssd`` of the closed loop (see the module)."""
    from lxml import etree

    level = output_name(gauge)
    root = etree.Element(f"{{{SSD}}}SystemStructureDescription", nsmap={"ssd": SSD, "ssc": SSC},
                         version="1.0", name=name, generationTool="gatetwin")  # fmt: skip
    system = etree.SubElement(root, f"{{{SSD}}}System", name="closed_loop",
                              description=description)  # fmt: skip
    connectors = etree.SubElement(system, f"{{{SSD}}}Connectors")
    for signal, unit in SIGNAL_UNITS.items():
        _connector(connectors, signal, "input", unit)
    _connector(connectors, level, "output", "mm")
    _connector(connectors, "opening_mm", "output", "mm")
    for pname, _, unit in parameters:
        if not pname.startswith("controller."):
            _connector(connectors, pname, "parameter", unit)
    bindings = etree.SubElement(system, f"{{{SSD}}}ParameterBindings")
    etree.SubElement(bindings, f"{{{SSD}}}ParameterBinding", source=PARAMETERS_SOURCE)
    elements = etree.SubElement(system, f"{{{SSD}}}Elements")
    controller = etree.SubElement(elements, f"{{{SSD}}}Component", name="controller",
                                  type="application/x-fmu-sharedlibrary",
                                  source=CONTROLLER_SOURCE)  # fmt: skip
    c_conn = etree.SubElement(controller, f"{{{SSD}}}Connectors")
    for cname, kind, unit in (
        (level, "input", "mm"),
        ("flow_m3h", "input", "m3/h"),
        ("setpoint_mm", "input", "mm"),
        ("opening_mm", "output", "mm"),
    ):
        _connector(c_conn, cname, kind, unit)  # fmt: skip
    for pname, _, unit in parameters:
        if pname.startswith("controller."):
            _connector(c_conn, pname.split(".", 1)[1], "parameter", unit)
    plant = etree.SubElement(
        elements,
        f"{{{SSD}}}Component",
        name="plant",
        type="application/x-fmu-sharedlibrary",
        source=PLANT_SOURCE,
    )
    p_conn = etree.SubElement(plant, f"{{{SSD}}}Connectors")
    for cname, kind, unit in (
        ("opening_mm", "input", "mm"),
        ("flow_m3h", "input", "m3/h"),
        (level, "output", "mm"),
    ):
        _connector(p_conn, cname, kind, unit)  # fmt: skip
    connections = etree.SubElement(system, f"{{{SSD}}}Connections")
    for start, end in ((("plant", level), ("controller", level)),
                       (("controller", "opening_mm"), ("plant", "opening_mm")),
                       ((None, "setpoint_mm"), ("controller", "setpoint_mm")),
                       ((None, "flow_m3h"), ("plant", "flow_m3h")),
                       ((None, "flow_m3h"), ("controller", "flow_m3h")),
                       (("plant", level), (None, level)),
                       (("controller", "opening_mm"), (None, "opening_mm"))):  # fmt: skip
        attrs = {"startConnector": start[1], "endConnector": end[1]}
        attrs.update({"startElement": start[0]} if start[0] else {})
        attrs.update({"endElement": end[0]} if end[0] else {})
        etree.SubElement(connections, f"{{{SSD}}}Connection", attrs)
    units = etree.SubElement(root, f"{{{SSD}}}Units")
    for unit in sorted({u for _, _, u in parameters} | {"mm", "m3/h"}):
        _, exponents, factor = UNITS[unit]
        u = etree.SubElement(units, f"{{{SSC}}}Unit", name=unit)
        base = {k: str(v) for k, v in exponents.items()}
        base.update({"factor": repr(factor)} if factor != 1.0 else {})
        etree.SubElement(u, f"{{{SSC}}}BaseUnit", base)
    etree.SubElement(root, f"{{{SSD}}}DefaultExperiment", startTime="0.0",
                     stopTime=repr(float(stop_time_s)))  # fmt: skip
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_ssp(
    model: ModelFile,
    out_path: str | os.PathLike[str],
    *,
    controller: str = "pi",
    scenario: Scenario | None = None,
    settings: DemoSettings | None = None,
) -> Path:
    """Write the closed loop of ``model`` (plant FMU + controller FMU) as an SSP.

    Parameters
    ----------
    model : ModelFile
        An FOPDT model file (the PI is SIMC-tuned from it).
    out_path : path
        Target ``.ssp``, written atomically.
    controller : {"pi", "mpc"}
        ``"mpc"`` raises :class:`~gatetwin.errors.ExportError` (not packed yet).
    scenario : Scenario, optional
        Default: the demo's ``setpoint_steps`` over 30 minutes
        (:func:`gatetwin.mpc.demo.demo_scenarios`).
    settings : DemoSettings, optional
        The demo's settings (PI limits, start point).

    Raises
    ------
    ExportError
        Unbuilt controller, a model that is not an FOPDT, a failed build.
    OutputError
        The package cannot be written where asked.
    """
    from gatetwin.fmu.controller import check_controller_kind, describe_pi_controller, rest_level_mm
    from gatetwin.mpc.demo import DemoSettings, demo_scenarios

    check_controller_kind(controller)
    if controller != "pi":
        raise ExportError(
            "the SSP packs the PI controller FMU; the MPC controller FMU "
            "(gatetwin export-controller --kind mpc) is not packed into one yet"
        )
    target = Path(out_path)
    if target.suffix.lower() != ".ssp":
        raise ExportError(f"output {target} must end in .ssp")
    s = settings or DemoSettings()
    scn = scenario or demo_scenarios(30.0, s)[0]
    desc = describe_pi_controller(model.plant, f"{model.name}_{controller}", settings=s,
                                  provenance={"model": model.name,
                                              "model_sha256": model.sha256})  # fmt: skip
    base = rest_level_mm(model.plant, scn.opening_mm, scn.flow_m3h)
    parameters = _parameters(desc, scenario_signals(scn, base), scn.opening_mm)
    text = (f"Closed loop of {model.name} with its {controller.upper()} controller, "
            f"scenario {scn.name}; inputs are piecewise constant: X.value[k] from X.time_s[k] "
            "on")  # fmt: skip
    ssd = ssd_xml(f"{model.name}_closed_loop", model.plant.gauge, parameters, scn.duration_s, text)
    ssv = parameter_set_xml("closed_loop", parameters)
    for xml, schema in ((ssd, SSD_SCHEMA), (ssv, SSV_SCHEMA)):
        problems = schema_problems(xml, schema)
        if problems:
            raise ExportError(f"{target}: the written {schema} document is invalid: {problems[0]}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
            _pack(Path(tmp), target, model, desc, ssd, ssv)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write the package ({exc.strerror or exc})") from None
    return target


def _pack(work: Path, target: Path, model: ModelFile, desc: ControllerDescription, ssd: bytes,
          ssv: bytes) -> None:  # fmt: skip
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.c_build import zip_folder
    from gatetwin.fmu.controller import build_controller_fmu
    from gatetwin.fmu.provenance import fmu_provenance

    package = work / "package"
    (package / "resources").mkdir(parents=True)
    (package / SSD_NAME).write_bytes(ssd)
    (package / PARAMETERS_SOURCE).write_bytes(ssv)
    export_fmu(model.plant, package / PLANT_SOURCE, backend="c", model_name=model.name,
               provenance=fmu_provenance(model))  # fmt: skip
    build = work / "controller"
    build.mkdir()
    build_controller_fmu(desc, build, package / CONTROLLER_SOURCE)
    built = work / target.name
    zip_folder(package, built)
    os.replace(built, target)


__all__ = ["CONTROLLER_SOURCE", "PARAMETERS_SOURCE", "PLANT_SOURCE", "SSD_NAME", "scenario_signals",
           "ssd_xml", "write_ssp"]  # fmt: skip
