"""Pack the closed loop of a model as an SSP 1.0 System Structure package (``.ssp``).

The package holds ``SystemStructure.ssd``, the plant FMU (``resources/plant.fmu``, C
backend), the controller FMU (``resources/controller.fmu``: the PI of
:mod:`gatetwin.fmu.controller` or the MPC of :mod:`gatetwin.fmu.mpc_controller`), optionally
the observer FMU (``resources/observer.fmu``, :mod:`gatetwin.fmu.observer_fmu`), the
scenario FMU (``resources/scenario.fmu``, :mod:`gatetwin.fmu.signal_source`) and one
parameter set (``resources/closed_loop.ssv``) bound to the system. The system
``closed_loop`` has

* elements ``controller``, ``observer`` (if packed), ``plant`` and ``scenario``, in the order
  :func:`gatetwin.ssp.simulate_ssp` steps them in, connected plant ``level_<gauge>_mm`` →
  controller ``level_<gauge>_mm``, controller ``opening_mm`` → plant ``opening_mm``, scenario
  ``setpoint_mm`` → controller and scenario ``flow_m3h`` → plant and controller;
* the observer reads what is measured at the gate: plant ``level_<gauge>_mm``, controller
  ``opening_mm`` (the opening held from this sample on) and the scenario's ``flow_m3h``;
  nothing reads its outputs (the master logs them);
* no connectors of its own: the scenario is a component, so an engine needs nothing
  outside the standard to run the loop (and ecos, which reads connections between
  components only, runs it);
* the scenario's tables (``scenario.X_table.time_s[k]``, ``scenario.X_table.value[k]`` and
  ``scenario.X_table.linear``, 0: ``X`` held at ``value[k]`` from ``time_s[k]`` on, ``k``
  from 1, the first at the start time; the set-points are absolute levels, the scenario's
  offsets added to the plant's steady level at the start inputs) and the controller's
  parameters (``controller.<parameter>``: the PI's start opening, tuning and limits; the
  MPC's start opening) in the parameter set, each equal to the FMU's own start value, so an
  engine that does not apply parameter bindings runs the same loop (the plant FMU's inputs
  and the controllers' start opening start at the scenario's first point for the same
  reason);
* a default experiment from 0 to the scenario's end.

The scenario is the last element: a master stepping the elements in document order
(Gauss-Seidel) then gives the controller the set-point at the point its step starts from;
one stepping them together (Jacobi) does so in any order.

The MPC and the observer cover a scheduled FOPDT without effect blocks: for a model with
effect blocks they are built on its FOPDT with the blocks dropped when asked
(``without_effects``), while the plant FMU keeps them.

SSD and SSV are checked against the SSP 1.0 schemas before anything is written
(:func:`write_package`, which also writes the package atomically). The document's parts
(:func:`system_document`, :func:`component_element`, :func:`connection_elements`,
:func:`finished_document`) and :func:`write_package` also pack the observer on a measured
record (:mod:`gatetwin.ssp.observed_record`).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
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
from gatetwin.ssp.master import MAX_STEPS

if TYPE_CHECKING:
    from collections.abc import Callable

    from gatetwin.fmu.controller import ControllerDescription
    from gatetwin.fmu.signal_source import SignalSourceDescription, TableSignal
    from gatetwin.modelfile import ModelFile
    from gatetwin.mpc.demo import DemoSettings
    from gatetwin.mpc.loop import Scenario
    from gatetwin.plant.model import FopdtPlant

#: Names inside the package.
SSD_NAME = "SystemStructure.ssd"
PLANT_SOURCE = "resources/plant.fmu"
CONTROLLER_SOURCE = "resources/controller.fmu"
PARAMETERS_SOURCE = "resources/closed_loop.ssv"
OBSERVER_SOURCE = "resources/observer.fmu"
SCENARIO_SOURCE = "resources/scenario.fmu"
#: Controller parameters the parameter set carries (the PI's; the MPC's: the start opening).
CONTROLLER_PARAMETERS = ("start_opening_mm", "gain_mm_per_mm", "integral_time_s",
                         "tracking_time_s", "opening_min_mm", "opening_max_mm",
                         "opening_rate_mm_s")  # fmt: skip


def observer_outputs() -> tuple[tuple[str, str], ...]:
    """The observer FMU's outputs (:data:`gatetwin.mpc.online.OUTPUTS`) with their units: mm
    for the ``_mm`` ones, 1 for the others (imported here: the observer loads casadi)."""
    from gatetwin.mpc.online import OUTPUTS

    return tuple((name, "mm" if name.endswith("_mm") else "1") for name in OUTPUTS)


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


def _pi_parameters(desc: ControllerDescription, start_opening_mm: float
                   ) -> list[tuple[str, float, str]]:  # fmt: skip
    """The PI's parameters the parameter set carries, as ``(name, value, unit)``."""
    units = {v.name: v.unit for v in desc.variables}
    values = {name: desc.start(name) for name in CONTROLLER_PARAMETERS}
    values["start_opening_mm"] = start_opening_mm
    return [(n, values[n], units[n]) for n in CONTROLLER_PARAMETERS]


def table_signals(signals: dict[str, list[tuple[float, float]]]) -> tuple[TableSignal, ...]:
    """The scenario FMU's signals (held between knots) of :func:`scenario_signals`."""
    from gatetwin.fmu.signal_source import TableSignal

    return tuple(
        TableSignal(name, SIGNAL_UNITS[name], tuple(t for t, _ in points),
                    tuple(v for _, v in points))
        for name, points in signals.items()
    )  # fmt: skip


def _parameters(
    controller: list[tuple[str, float, str]], scenario: SignalSourceDescription
) -> list[tuple[str, float, str]]:
    """The parameter set: the controller's, then the scenario FMU's (its start values)."""
    from gatetwin.fmu.signal_source import parameter_values

    out = [(f"controller.{n}", value, unit) for n, value, unit in controller]
    return out + [(f"scenario.{n}", value, unit) for n, value, unit in parameter_values(scenario)]


def _connector(parent: object, name: str, kind: str, unit: str) -> None:
    from lxml import etree

    c = etree.SubElement(parent, f"{{{SSD}}}Connector", name=name, kind=kind)
    etree.SubElement(c, f"{{{SSC}}}Real", unit=unit)


def component_element(elements: object, name: str, source: str,
                      connectors: list[tuple[str, str, str]]) -> object:  # fmt: skip
    """Add the FMU component ``name`` (its file ``source`` in the package) with its
    ``(name, kind, unit)`` connectors to an SSD's ``Elements``; the element."""
    from lxml import etree

    component = etree.SubElement(elements, f"{{{SSD}}}Component", name=name,
                                 type="application/x-fmu-sharedlibrary",
                                 source=source)  # fmt: skip
    holder = etree.SubElement(component, f"{{{SSD}}}Connectors")
    for cname, kind, unit in connectors:
        _connector(holder, cname, kind, unit)
    return component


def scenario_connectors(signals: dict[str, str], parameters: list[tuple[str, float, str]]
                        ) -> list[tuple[str, str, str]]:  # fmt: skip
    """The scenario component's connectors: each signal ``{name: unit}`` out, then its
    parameters (the ``scenario.`` ones of the parameter set)."""
    out = [(name, "output", unit) for name, unit in signals.items()]
    return out + [(p.split(".", 1)[1], "parameter", unit) for p, _, unit in parameters
                  if p.startswith("scenario.")]  # fmt: skip


def observer_connectors(
    level: str, outputs: tuple[tuple[str, str], ...] | None = None
) -> list[tuple[str, str, str]]:
    """The observer component's connectors: the measured level (``level``), opening and
    discharge in, its ``outputs`` (name, unit) out (default: the schedule observer's,
    :func:`observer_outputs`)."""
    inputs = [(level, "input", "mm"), ("opening_mm", "input", "mm"),
              ("flow_m3h", "input", "m3/h")]  # fmt: skip
    outs = observer_outputs() if outputs is None else outputs
    return inputs + [(cname, "output", unit) for cname, unit in outs]


def _observer_element(elements: object, level: str) -> None:
    component_element(elements, "observer", OBSERVER_SOURCE, observer_connectors(level))


def _connections(system: object, level: str, observer: bool) -> None:
    links = [(("plant", level), ("controller", level)),
             (("controller", "opening_mm"), ("plant", "opening_mm")),
             (("scenario", "setpoint_mm"), ("controller", "setpoint_mm")),
             (("scenario", "flow_m3h"), ("plant", "flow_m3h")),
             (("scenario", "flow_m3h"), ("controller", "flow_m3h"))]  # fmt: skip
    if observer:
        links += [(("plant", level), ("observer", level)),
                  (("controller", "opening_mm"), ("observer", "opening_mm")),
                  (("scenario", "flow_m3h"), ("observer", "flow_m3h"))]  # fmt: skip
    connection_elements(system, links)


def connection_elements(system: object,
                        links: list[tuple[tuple[str, str], tuple[str, str]]]) -> None:  # fmt: skip
    """Add the system's ``Connections``: one for each ``((start element, connector), (end
    element, connector))``."""
    from lxml import etree

    connections = etree.SubElement(system, f"{{{SSD}}}Connections")
    for start, end in links:
        etree.SubElement(connections, f"{{{SSD}}}Connection", startElement=start[0],
                         startConnector=start[1], endElement=end[0],
                         endConnector=end[1])  # fmt: skip


def _units(root: object, used: set[str]) -> None:
    from lxml import etree

    units = etree.SubElement(root, f"{{{SSD}}}Units")
    for unit in sorted(used):
        _, exponents, factor = UNITS[unit]
        u = etree.SubElement(units, f"{{{SSC}}}Unit", name=unit)
        base = {k: str(v) for k, v in exponents.items()}
        base.update({"factor": repr(factor)} if factor != 1.0 else {})
        etree.SubElement(u, f"{{{SSC}}}BaseUnit", base)


def ssd_xml(
    name: str, gauge: str, parameters: list[tuple[str, float, str]], stop_time_s: float,
    description: str, *, observer: bool = False,
) -> bytes:  # fmt: skip
    """``SystemStructure.ssd`` of the closed loop (see the module), with the observer's
    element and connections if ``observer``."""
    from lxml import etree

    level = output_name(gauge)
    root, system, elements = system_document(name, "closed_loop", description,
                                             PARAMETERS_SOURCE)  # fmt: skip
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
    if observer:
        _observer_element(elements, level)
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
    component_element(elements, "scenario", SCENARIO_SOURCE,
                      scenario_connectors(SIGNAL_UNITS, parameters))  # fmt: skip
    _connections(system, level, observer)
    used = {u for _, _, u in parameters} | {"mm", "m3/h"}
    return finished_document(root, used | ({u for _, u in observer_outputs()} if observer
                                           else set()), stop_time_s)  # fmt: skip


def system_document(name: str, system_name: str, description: str,
                    parameters_source: str) -> tuple[object, object, object]:  # fmt: skip
    """An SSD's root with one system ``system_name`` bound to the parameter set
    ``parameters_source``: ``(root, system, its Elements)``."""
    from lxml import etree

    root = etree.Element(f"{{{SSD}}}SystemStructureDescription", nsmap={"ssd": SSD, "ssc": SSC},
                         version="1.0", name=name, generationTool="gatetwin")  # fmt: skip
    system = etree.SubElement(root, f"{{{SSD}}}System", name=system_name,
                              description=description)  # fmt: skip
    bindings = etree.SubElement(system, f"{{{SSD}}}ParameterBindings")
    etree.SubElement(bindings, f"{{{SSD}}}ParameterBinding", source=parameters_source)
    return root, system, etree.SubElement(system, f"{{{SSD}}}Elements")


def finished_document(root: object, units: set[str], stop_time_s: float) -> bytes:
    """The SSD's bytes once its ``Units`` (each of ``units``) and its default experiment
    (from 0 to ``stop_time_s``) are added."""
    from lxml import etree

    _units(root, units)
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
    observer: bool = False,
    without_effects: bool = False,
) -> Path:
    """Write the closed loop of ``model`` (plant FMU + controller FMU) as an SSP.

    Parameters
    ----------
    model : ModelFile
        An FOPDT model file (the PI is SIMC-tuned from it, the MPC and the observer use its
        schedule).
    out_path : path
        Target ``.ssp``, written atomically.
    controller : {"pi", "mpc"}
        The PI (:mod:`gatetwin.fmu.controller`) or the MPC
        (:mod:`gatetwin.fmu.mpc_controller`, with ``settings.mpc``: its horizon sets the
        build's cost).
    scenario : Scenario, optional
        Default: the demo's ``setpoint_steps`` over 30 minutes
        (:func:`gatetwin.mpc.demo.demo_scenarios`).
    settings : DemoSettings, optional
        The demo's settings (PI limits, MPC settings, start point).
    observer : bool
        Also pack the observer FMU, reading the measured level, opening and discharge.
    without_effects : bool
        Build the MPC and the observer on the model's FOPDT with its effect blocks dropped
        (they do not cover them; a model with effect blocks is refused otherwise). The plant
        FMU keeps them.

    Raises
    ------
    ExportError
        Unknown controller, a model that is not an FOPDT, effect blocks the MPC or the
        observer does not cover, a failed build.
    OutputError
        The package cannot be written where asked.
    """
    from gatetwin.fmu.controller import check_controller_kind, describe_pi_controller, rest_level_mm
    from gatetwin.fmu.signal_source import describe_signal_source
    from gatetwin.mpc.demo import DemoSettings, demo_scenarios

    check_controller_kind(controller)
    target = ssp_target(out_path)
    s = settings or DemoSettings()
    scn = scenario or demo_scenarios(30.0, s)[0]
    period = s.mpc.sample_period_s if controller == "mpc" else s.pi.sample_period_s
    if not scn.duration_s / period < MAX_STEPS + 0.5:
        raise ExportError(f"a scenario of {scn.duration_s:.6g} s is {scn.duration_s / period:.6g} "
                          f"steps of the controller's {period:g} s; simulate-ssp runs at most "
                          f"{MAX_STEPS}")  # fmt: skip
    covered = _covered_plant(model, controller, observer, without_effects)
    desc = None
    if controller == "pi":
        desc = describe_pi_controller(model.plant, f"{model.name}_{controller}", settings=s,
                                      provenance={"model": model.name,
                                                  "model_sha256": model.sha256},
                                      start_opening_mm=scn.opening_mm)  # fmt: skip
        own = _pi_parameters(desc, scn.opening_mm)
    else:
        own = [("start_opening_mm", float(scn.opening_mm), "mm")]
    base = rest_level_mm(model.plant, scn.opening_mm, scn.flow_m3h)
    signals = table_signals(scenario_signals(scn, base))
    scenario_fmu = describe_signal_source(signals, f"{model.name}_scenario", period,
                                          {"model": model.name})  # fmt: skip
    parameters = _parameters(own, scenario_fmu)
    text = (f"Closed loop of {model.name} with its {controller.upper()} controller"
            f"{' and its observer' if observer else ''}, scenario {scn.name} (the scenario "
            "component: X held at X_table.value[k] from X_table.time_s[k] on)")  # fmt: skip
    ssd = ssd_xml(f"{model.name}_closed_loop", model.plant.gauge, parameters, scn.duration_s,
                  text, observer=observer)  # fmt: skip
    ssv = parameter_set_xml("closed_loop", parameters)
    parts = _Parts(model, desc, covered, s, observer, signals, scenario_fmu,
                   float(scn.opening_mm))  # fmt: skip
    return write_package(target, ssd, ssv, lambda work, package: _pack(work, package, parts))


def ssp_target(out_path: str | os.PathLike[str]) -> Path:
    """``out_path`` as a package's path; :class:`ExportError` unless it ends in ``.ssp``."""
    target = Path(out_path)
    if target.suffix.lower() != ".ssp":
        raise ExportError(f"output {target} must end in .ssp")
    return target


def write_package(target: Path, ssd: bytes, ssv: bytes, members: Callable[[Path, Path], None],
                  parameters_source: str = PARAMETERS_SOURCE) -> Path:  # fmt: skip
    """Check ``ssd`` and ``ssv`` against the SSP 1.0 schemas, then write the package
    ``target`` atomically: the two documents (:data:`SSD_NAME`, ``parameters_source``) and
    what ``members(work, package)`` puts in the folder ``package`` (``work``: a scratch
    folder beside it).

    Raises
    ------
    ExportError
        A document the schemas refuse; what ``members`` raises.
    OutputError
        The package cannot be written where asked.
    """
    from gatetwin.fmu.c_build import zip_folder

    for xml, schema in ((ssd, SSD_SCHEMA), (ssv, SSV_SCHEMA)):
        problems = schema_problems(xml, schema)
        if problems:
            raise ExportError(f"{target}: the written {schema} document is invalid: {problems[0]}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
            work = Path(tmp)
            package = work / "package"
            (package / "resources").mkdir(parents=True)
            (package / SSD_NAME).write_bytes(ssd)
            (package / parameters_source).write_bytes(ssv)
            members(work, package)
            built = work / target.name
            zip_folder(package, built)
            os.replace(built, target)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write the package ({exc.strerror or exc})") from None
    return target


def _covered_plant(model: ModelFile, controller: str, observer: bool,
                   without_effects: bool) -> FopdtPlant | None:  # fmt: skip
    """The plant the MPC and the observer are built on (None when neither is packed)."""
    from dataclasses import replace

    from gatetwin.plant.model import FopdtPlant

    if controller != "mpc" and not observer:
        return None
    what = "the MPC controller" if controller == "mpc" else "the observer"
    plant = model.plant
    if not isinstance(plant, FopdtPlant):
        raise ExportError(f"{what} needs a scheduled FOPDT model; got a {plant.kind} model")
    if plant.effects and not without_effects:
        kinds = ", ".join(e["kind"] for e in plant.effects)
        raise ExportError(f"{what} does not cover effect blocks (the model has {kinds}); "
                          "--without-effects builds it on the model's FOPDT alone")  # fmt: skip
    return replace(plant, effects=())


@dataclass(frozen=True)
class _Parts:
    """What goes into the package besides the documents."""

    model: ModelFile
    pi: ControllerDescription | None
    covered: FopdtPlant | None
    settings: DemoSettings
    observer: bool
    signals: tuple[TableSignal, ...]
    scenario: SignalSourceDescription
    start_opening_mm: float


def _pack(work: Path, package: Path, parts: _Parts) -> None:
    """The closed loop's FMUs into ``package``."""
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.fmu.signal_source import build_signal_source

    model = parts.model
    # at rest where the scenario starts, also for an engine that sets no input before
    # initialising the FMUs
    flow = next(s.values[0] for s in parts.signals if s.name == "flow_m3h")
    export_fmu(model.plant, package / PLANT_SOURCE, backend="c", model_name=model.name,
               provenance=fmu_provenance(model),
               start_inputs=(parts.start_opening_mm, flow))  # fmt: skip
    if parts.pi is not None:
        from gatetwin.fmu.controller import build_controller_fmu

        build = work / "controller"
        build.mkdir()
        build_controller_fmu(parts.pi, build, package / CONTROLLER_SOURCE)
    else:
        from gatetwin.fmu.mpc_controller import export_mpc_controller

        export_mpc_controller(parts.covered, package / CONTROLLER_SOURCE,
                              settings=parts.settings.mpc, model_name=f"{model.name}_mpc",
                              start_opening_mm=parts.start_opening_mm)  # fmt: skip
    if parts.observer:
        from gatetwin.fmu.controller_settings import sample_period_s
        from gatetwin.fmu.observer_fmu import export_observer

        export_observer(parts.covered, package / OBSERVER_SOURCE,
                        model_name=f"{model.name}_observer",
                        sample_period_s=sample_period_s(model))  # fmt: skip
    (work / "scenario").mkdir()
    build_signal_source(parts.scenario, work / "scenario", package / SCENARIO_SOURCE)


__all__ = ["CONTROLLER_SOURCE", "OBSERVER_SOURCE", "PARAMETERS_SOURCE", "PLANT_SOURCE",
           "SCENARIO_SOURCE", "SSD_NAME", "component_element", "connection_elements",
           "finished_document", "observer_connectors", "observer_outputs", "scenario_connectors",
           "scenario_signals", "ssd_xml", "ssp_target", "system_document", "table_signals",
           "write_package", "write_ssp"]  # fmt: skip
