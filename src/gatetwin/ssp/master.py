"""gatetwin's fixed-step co-simulation master for an SSP of FMI 2.0 co-simulation FMUs.

What it runs: one system of FMU components (no nested systems, no system inputs: what
drives the loop is a component, such as the scenario FMU of :mod:`gatetwin.ssp.write`), Real
connectors, connections without transformations and parameter sets bound to the system
(``<element>.<name>`` sets a component's variable). Anything else is refused with one line
naming it.

How it steps (fixed step ``h``, the controller's sample period when an element has a
``sample_period_s`` parameter, else the first FMU's default step), at each communication
point ``t_k = start + k h``, by one of two schemes (:data:`SCHEMES`):

* ``gauss-seidel`` (the default): the components are stepped in document order, each one's
  inputs set from the current values of their sources just before its ``doStep(t_k, h)`` and
  its outputs read just after. With the controller listed before the plant and the scenario
  last (as :func:`~gatetwin.ssp.write.write_ssp` lists them) this is
  :func:`gatetwin.mpc.loop.run_closed_loop`: ``u_k = C(y_k, r_k)``, then the plant holds
  ``u_k`` over ``[t_k, t_k + h]``.
* ``jacobi``: every component's inputs are set from the values at ``t_k``, every component
  steps, then every output is read; the plant then holds ``u_k`` over ``[t_k + h, t_k + 2h]``
  (one sample later). This is how engines that step the components together run the same
  package (fmpy's SSP runner, ecos); SSP 1.0 leaves the master algorithm to the engine.

Initialisation: every component is instantiated, set up at the start time and put into
initialisation mode; the bound parameters are set; the connections are propagated as many
times as there are components (outputs read in initialisation mode: each one's value at
rest), then each component leaves initialisation mode in document order.

Isolation: the FMUs are foreign native code, so by default the whole run happens in a child
process of the FMU host of :mod:`gatetwin.validation.isolation`. An FMU that calls ``exit()``
or ``abort()``, writes through a null pointer, or does not return from a call within the
limit (``timeout_s``, each call: a long run of quick steps is never cut) ends the run with
one line naming the cause, the component, the call, the communication step and the time;
nothing is written.

The result (:class:`SspRun`) holds, per communication point, every component input as the
component received it for the step from that point, and the outputs of
every monitor (a component no other component reads from, such as the observer) as they
stand after its step from that point.
"""

from __future__ import annotations

import math
import shutil
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import SspError
from gatetwin.records.limits import check_unpacked_size, open_regular
from gatetwin.ssp.documents import NS, SSD_SCHEMA, read_parameter_set, schema_problems
from gatetwin.validation.fmu_runner import (
    DO_STEP,
    FREE_INSTANCE,
    GET_REAL,
    INITIALISE,
    INSTANTIATE,
    LOADING,
    MAX_FMU_STEPS,
    SET_REAL,
    TERMINATE,
    Position,
)

#: How the components are stepped at each communication point (see the module).
SCHEMES = ("gauss-seidel", "jacobi")
#: Largest number of communication steps one run takes: 13.9 days at the controllers' 1.2 s,
#: as many as validate asks of an FMU for one record
#: (:data:`gatetwin.validation.fmu_runner.MAX_FMU_STEPS`). The run's columns are held in
#: memory (8 bytes a value: 64 MB for the eight columns of a closed loop at the limit).
MAX_STEPS = MAX_FMU_STEPS
#: Wall-clock limit of one FMI call when none is given, s: the base limit of a validation run
#: (:data:`gatetwin.validation.isolation.TIMEOUT_BASE_S`), which covers starting a process and
#: loading a binary; a gatetwin FMU's step takes microseconds to milliseconds.
TIMEOUT_S = 10.0


@dataclass(frozen=True)
class SspComponent:
    """One FMU of the system: name, source in the package, connectors ``{name: kind}``."""

    name: str
    source: str
    connectors: dict[str, str]


@dataclass(frozen=True)
class SspSystem:
    """What the master reads from an SSD (see the module)."""

    name: str
    components: tuple[SspComponent, ...]
    #: (start element, start connector, end element, end connector)
    connections: tuple[tuple[str, str, str, str], ...]
    parameter_sources: tuple[str, ...]
    start_time_s: float
    stop_time_s: float


@dataclass(frozen=True, eq=False)
class SspRun:
    """A run of :func:`simulate_ssp`: ``columns[name][k]`` at ``time_s[k]``.

    Columns are ``<element>.<input>`` (what the component received for the step from
    ``time_s[k]``) and a monitor's ``<element>.<output>`` (its value
    after the step from ``time_s[k]``).
    """

    time_s: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    step_s: float = math.nan

    def iae(self, measured: str, reference: str) -> float:
        """``∫|measured − reference| dt`` over the run, as :func:`gatetwin.mpc.loop.loop_metrics`
        sums it (per communication point times the step)."""
        return float(np.sum(np.abs(self.columns[measured] - self.columns[reference])) * self.step_s)

    def to_csv(self) -> str:
        names = list(self.columns)
        lines = [",".join(["time_s", *names])]
        for k, t in enumerate(self.time_s):
            row = [t, *(self.columns[n][k] for n in names)]
            lines.append(",".join(repr(float(x)) for x in row))
        return "\n".join(lines) + "\n"


class SspPosition(Position):
    """Where a run is: the FMI call under way, the communication step, the time and the
    component (an index into ``names``)."""

    __slots__ = ("names",)
    COMPONENT = 3
    SLOTS = 4

    def __init__(self, values: Any = None, names: tuple[str, ...] = ()) -> None:
        super().__init__(values if values is not None else [0.0] * self.SLOTS)
        self.names = names

    def on(self, call: int, component: int) -> None:
        self.values[self.CALL], self.values[self.COMPONENT] = call, component

    def at(self) -> str:
        """``at t = 12 s (communication step 10, component plant)``."""
        k = int(self.values[self.COMPONENT])
        name = self.names[k] if 0 <= k < len(self.names) else "?"
        return f"at t = {self.time_s:.6g} s (communication step {self.sample}, component {name})"


def _float(value: str | None, what: str, where: str) -> float:
    try:
        out = float(value) if value is not None else math.nan
    except ValueError:
        out = math.nan
    if not math.isfinite(out):
        raise SspError(f"{where}: {what} {value!r} is not a finite number")
    return out


def _components(system: Any, where: str) -> list[SspComponent]:
    """The system's elements: FMU components only, each name once."""
    from lxml import etree

    components: list[SspComponent] = []
    for c in system.iterfind("ssd:Elements/*", NS):
        kind = c.get("type", "application/x-fmu-sharedlibrary")
        if etree.QName(c).localname != "Component" or kind != "application/x-fmu-sharedlibrary":
            raise SspError(f"{where}: element {c.get('name')} is not an FMU component")
        if any(seen.name == c.get("name") for seen in components):
            raise SspError(f"{where}: two components are named {c.get('name')!r}")
        connectors = {k.get("name"): k.get("kind") for k in c.iterfind("ssd:Connectors/*", NS)}
        components.append(SspComponent(c.get("name"), c.get("source"), connectors))
    return components


def read_ssd(xml: bytes, where: str) -> SspSystem:
    """The system of an SSD document, checked against the SSP 1.0 schema and the subset the
    master runs."""
    from lxml import etree

    problems = schema_problems(xml, SSD_SCHEMA)
    if problems:
        raise SspError(f"{where}: not an SSP 1.0 system structure: {problems[0]}")
    root = etree.fromstring(xml)
    system = root.find("ssd:System", NS)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise SspError(f"{where}: nested systems are not run by this master")
    components = _components(system, where)
    connections = []
    for c in system.iterfind("ssd:Connections/ssd:Connection", NS):
        if len(c):
            raise SspError(f"{where}: connection to {c.get('endConnector')} has a "
                           "transformation; this master runs plain connections")  # fmt: skip
        if c.get("startElement") is None or c.get("endElement") is None:
            raise SspError(f"{where}: the connection to {c.get('endConnector')} joins a "
                           "system connector; this master runs connections between "
                           "components")  # fmt: skip
        connections.append((c.get("startElement"), c.get("startConnector"),
                            c.get("endElement"), c.get("endConnector")))  # fmt: skip
    inputs = [k.get("name") for k in system.iterfind("ssd:Connectors/ssd:Connector", NS)
              if k.get("kind") == "input"]  # fmt: skip
    if inputs:
        raise SspError(f"{where}: system input {inputs[0]} has no value here; this master runs "
                       "systems driven by their components (a signal-source FMU)")  # fmt: skip
    sources = tuple(b.get("source") for b in system.iterfind(
        "ssd:ParameterBindings/ssd:ParameterBinding", NS))  # fmt: skip
    if any(s is None for s in sources):
        raise SspError(f"{where}: only parameter bindings with a source file are run")
    experiment = root.find("ssd:DefaultExperiment", NS)
    if experiment is None or experiment.get("stopTime") is None:
        raise SspError(f"{where}: DefaultExperiment with a stopTime is needed")
    start = _float(experiment.get("startTime", "0.0"), "startTime", where)
    stop = _float(experiment.get("stopTime"), "stopTime", where)
    if not stop > start:
        raise SspError(f"{where}: stopTime {stop} must lie after startTime {start}")
    return SspSystem(system.get("name"), tuple(components), tuple(connections), sources,
                     start, stop)  # fmt: skip


class _Master:
    """The FMUs of one run and the values on their connectors."""

    def __init__(self, system: SspSystem, folder: Path, parameters: dict[str, float],
                 where: str, position: SspPosition) -> None:  # fmt: skip
        self.system, self.where, self.position = system, where, position
        self.index = {c.name: i for i, c in enumerate(system.components)}
        self.values: dict[tuple[str | None, str], float] = {}
        self.slaves: dict[str, Any] = {}
        self.vrs: dict[str, dict[str, int]] = {}
        self.steps: dict[str, float] = {}
        self.parameters = parameters
        try:
            for c in system.components:
                self._instantiate(c, folder)
            self._check_connections()
        except BaseException:
            self.close()  # the instances made so far
            raise

    def _instantiate(self, c: SspComponent, folder: Path) -> None:
        from fmpy import read_model_description

        from gatetwin.fmi_host import open_instance, unpack_fmu

        path = folder / "package" / c.source
        unzipped = unpack_fmu(path, folder / f"fmu_{len(self.slaves)}",
                              f"{self.where}: component {c.name}", SspError)  # fmt: skip
        try:
            md = read_model_description(unzipped)
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions on bad FMUs
            raise SspError(f"{self.where}: component {c.name}: {c.source} is not an FMU "
                           f"({' '.join(str(exc).split())[:200]})") from None  # fmt: skip
        if md.fmiVersion != "2.0" or md.coSimulation is None:
            raise SspError(f"{self.where}: component {c.name}: not an FMI 2.0 co-simulation FMU")
        self.vrs[c.name] = {v.name: v.valueReference for v in md.modelVariables
                            if v.type == "Real"}  # fmt: skip
        missing = [n for n in c.connectors if n not in self.vrs[c.name]]
        if missing:
            raise SspError(f"{self.where}: component {c.name} has no Real variable {missing[0]}")
        if "sample_period_s" in self.vrs[c.name]:
            period = next(v for v in md.modelVariables if v.name == "sample_period_s").start
            self.steps[c.name] = float(period)
        elif md.defaultExperiment is not None and md.defaultExperiment.stepSize:
            self.steps.setdefault("", float(md.defaultExperiment.stepSize))
        self.position.on(LOADING, self.index[c.name])
        self.slaves[c.name] = open_instance(
            md, unzipped, c.name, what=f"{self.where}: component {c.name}", error=SspError,
            logging_on=False, loaded=lambda: self.position.on(INSTANTIATE, self.index[c.name]),
        )  # fmt: skip

    def last_problem(self, name: str) -> str:
        """The component's last logged message of status warning or worse ("" if none)."""
        return self.slaves[name].last_problem()[:300] if name in self.slaves else ""

    def _check_connections(self) -> None:
        connectors = {(c.name, n) for c in self.system.components for n in c.connectors}
        for start_el, start_c, end_el, end_c in self.system.connections:
            for element, connector in ((start_el, start_c), (end_el, end_c)):
                if element is not None and (element, connector) not in connectors:
                    raise SspError(f"{self.where}: a connection names {element}.{connector}, "
                                   "which no component declares")  # fmt: skip

    def step_size_s(self, override: float | None) -> float:
        if override is not None:
            return float(override)
        periods = [v for k, v in self.steps.items() if k]
        h = periods[0] if periods else self.steps.get("")
        if h is None or not h > 0:
            raise SspError(f"{self.where}: no step size (no sample_period_s and no default "
                           "experiment step in the FMUs); give one")  # fmt: skip
        return h

    def inputs_of(self, name: str) -> dict[str, float]:
        """The values this component's inputs receive now (those whose source is known)."""
        out = {}
        for start_el, start_c, end_el, end_c in self.system.connections:
            if end_el == name and (start_el, start_c) in self.values:
                out[end_c] = self.values[(start_el, start_c)]
        return out

    def push_inputs(self, name: str) -> dict[str, float]:
        inputs = self.inputs_of(name)
        if inputs:
            self.position.on(SET_REAL, self.index[name])
            vr = self.vrs[name]
            self.slaves[name].setReal([vr[n] for n in inputs], list(inputs.values()))
        return inputs

    def pull_outputs(self, c: SspComponent) -> None:
        outs = [n for n, kind in c.connectors.items() if kind == "output"]
        if outs:
            self.position.on(GET_REAL, self.index[c.name])
            values = self.slaves[c.name].getReal([self.vrs[c.name][n] for n in outs])
            for n, v in zip(outs, values, strict=True):
                if not math.isfinite(v):
                    raise SspError(f"{self.where}: output {n} not finite ({v}) "
                                   f"{self.position.at()}")  # fmt: skip
                self.values[(c.name, n)] = float(v)

    def apply_parameters(self) -> None:
        for c in self.system.components:
            own = {k.split(".", 1)[1]: v for k, v in self.parameters.items()
                   if k.startswith(c.name + ".")}  # fmt: skip
            unknown = [n for n in own if n not in self.vrs[c.name]]
            if unknown:
                raise SspError(f"{self.where}: parameter {c.name}.{unknown[0]}: no such "
                               "variable in the FMU")  # fmt: skip
            if own:
                self.position.on(SET_REAL, self.index[c.name])
                vr = self.vrs[c.name]
                self.slaves[c.name].setReal([vr[n] for n in own], list(own.values()))

    def monitors(self) -> set[str]:
        """Components whose outputs no other component reads."""
        read = {start for start, _, end, _ in self.system.connections
                if start is not None and end is not None}  # fmt: skip
        return {c.name for c in self.system.components} - read

    def close(self) -> None:
        for name, slave in self.slaves.items():
            self.position.on(FREE_INSTANCE, self.index[name])
            try:
                slave.freeInstance()
            except Exception:  # noqa: BLE001, S110 - freeing is all that is left to do
                pass


def _initialize(m: _Master, start: float) -> None:
    m.position.values[Position.TIME_S] = start
    for name, slave in m.slaves.items():
        m.position.on(INITIALISE, m.index[name])
        slave.setupExperiment(startTime=start)
        slave.enterInitializationMode()
    m.apply_parameters()
    for _ in m.system.components:  # propagate through the loop: each pass reaches one further
        for c in m.system.components:
            m.push_inputs(c.name)
            m.pull_outputs(c)
    for c in m.system.components:
        m.push_inputs(c.name)
        m.position.on(INITIALISE, m.index[c.name])
        m.slaves[c.name].exitInitializationMode()
        m.pull_outputs(c)


def _log_outputs(m: _Master, c: SspComponent, log: Any, k: int) -> None:
    for connector, kind in c.connectors.items():
        if kind == "output":
            log(f"{c.name}.{connector}", k, m.values[(c.name, connector)])


def _step(m: _Master, t: float, h: float, jacobi: bool, log: Any) -> None:
    """One communication step from ``t``: every component's inputs set (and logged), its
    ``doStep``; its outputs read at once (Gauss-Seidel) or after every step (Jacobi)."""
    for c in m.system.components:
        for connector, value in m.push_inputs(c.name).items():
            log(f"{c.name}.{connector}", value)
        m.position.on(DO_STEP, m.index[c.name])
        m.slaves[c.name].doStep(currentCommunicationPoint=t, communicationStepSize=h)
        if not jacobi:
            m.pull_outputs(c)
    if jacobi:
        for c in m.system.components:
            m.pull_outputs(c)


def _run(m: _Master, h: float, scheme: str) -> SspRun:
    start, stop = m.system.start_time_s, m.system.stop_time_s
    steps = (stop - start) / h
    if not 0.5 <= steps < MAX_STEPS + 0.5:
        raise SspError(f"{m.where}: {steps:.6g} steps of {h:.6g} s from {start:.6g} to "
                       f"{stop:.6g} s; need 1 to {MAX_STEPS}")  # fmt: skip
    n = int(round(steps))
    columns: dict[str, np.ndarray] = {}

    def log(name: str, k: int, value: float) -> None:
        if name not in columns:
            columns[name] = np.full(n, np.nan)
        columns[name][k] = value

    times = start + np.arange(n) * h
    monitors = m.monitors()
    where = m.position.values
    for k in range(n):
        t = float(times[k])
        where[Position.SAMPLE], where[Position.TIME_S] = k, t
        _step(m, t, h, scheme == "jacobi", lambda name, value, k=k: log(name, k, value))
        for c in m.system.components:
            if c.name in monitors:
                _log_outputs(m, c, log, k)
    for name, slave in m.slaves.items():
        m.position.on(TERMINATE, m.index[name])
        slave.terminate()
    return SspRun(times, columns, h)


def simulate_ssp(
    ssp_path: str | Path, *, out_csv: str | Path | None = None, step_size_s: float | None = None,
    timeout_s: float | None = None, isolate: bool = True, scheme: str = "gauss-seidel",
) -> SspRun:  # fmt: skip
    """Run the system of an SSP with gatetwin's master (see the module); write ``out_csv``.

    ``timeout_s`` bounds each FMI call (default :data:`TIMEOUT_S`); ``isolate=False`` runs
    the FMUs in this process, unprotected (for debugging); ``scheme`` is one of
    :data:`SCHEMES`.

    Raises
    ------
    SspError
        The package, its SSD, a parameter set or an FMU is not what the master runs, an FMU
        refuses a call (the message names the component and the time), or an FMU ends or
        stalls its process (the cause named).
    """
    from gatetwin._io import write_text_atomic

    path = Path(ssp_path)
    where = str(path)
    limit = TIMEOUT_S if timeout_s is None else float(timeout_s)
    if not 0 < limit < math.inf:
        raise SspError(f"timeout {timeout_s} s must be a finite number of seconds > 0")
    if scheme not in SCHEMES:
        raise SspError(f"scheme {str(scheme)[:40]!r} is not one of {', '.join(SCHEMES)}")
    with tempfile.TemporaryDirectory(prefix="gatetwin-ssp-") as tmp:
        folder = Path(tmp)
        system, parameters = _unpack(path, folder, where)
        task = SspTask(system, folder, parameters, where, step_size_s, scheme)
        if isolate:
            from gatetwin.validation.isolation import run_task

            answer = run_task(task, [None], [limit])
            if isinstance(answer, str):
                raise SspError(answer)
            if answer[0].failure_cause:
                raise SspError(f"{where}: {answer[0].failure_cause}")
            run = answer[0].result
        else:
            run = task.run(None, task.position(None))
    if out_csv is not None:
        write_text_atomic(out_csv, run.to_csv())
    return run


class SspTask:
    """One run of an unpacked package, as a task of
    :func:`gatetwin.validation.isolation.run_task` (each FMI call bounded)."""

    per_call = True
    SLOTS = SspPosition.SLOTS
    name = "gatetwin-simulate-ssp"

    def __init__(self, system: SspSystem, folder: Path, parameters: dict[str, float],
                 where: str, step_size_s: float | None, scheme: str = "gauss-seidel",
                 ) -> None:  # fmt: skip
        self.system, self.folder, self.parameters = system, folder, parameters
        self.where, self.step_size_s, self.scheme = where, step_size_s, scheme

    def position(self, shared: Any) -> SspPosition:
        return SspPosition(shared, tuple(c.name for c in self.system.components))

    def run(self, _request: Any, position: SspPosition) -> SspRun:
        from fmpy.fmi1 import FMICallException

        master = _Master(self.system, self.folder, self.parameters, self.where, position)
        try:
            h = master.step_size_s(self.step_size_s)
            _initialize(master, self.system.start_time_s)
            return _run(master, h, self.scheme)
        except FMICallException as exc:
            name = position.names[int(position.values[position.COMPONENT])]
            detail = master.last_problem(name)
            raise SspError(
                f"{self.where}: an FMU refused a call ({exc}) {position.at()}"
                + (f"; FMU log: {detail}" if detail else "")
            ) from None
        finally:
            master.close()


def _unpack(path: Path, folder: Path, where: str) -> tuple[SspSystem, dict[str, float]]:
    try:
        with open_regular(path, sys.maxsize, "an SSP package (.ssp)", SspError) as handle, \
                zipfile.ZipFile(handle) as zf:  # fmt: skip
            names = set(zf.namelist())
            check_unpacked_size(zf, where, SspError)
            if "SystemStructure.ssd" not in names:
                raise SspError(f"{where}: no SystemStructure.ssd in the package")
            ssd = zf.read("SystemStructure.ssd")
            system = read_ssd(ssd, f"{where}: SystemStructure.ssd")
            parameters: dict[str, float] = {}
            for source in system.parameter_sources:
                if source not in names:
                    raise SspError(f"{where}: parameter set {source} is not in the package")
                parameters.update(read_parameter_set(zf.read(source), f"{where}: {source}"))
            for c in system.components:
                if c.source not in names:
                    raise SspError(f"{where}: component {c.name}: no file {c.source} in the "
                                   "package")  # fmt: skip
                target = (folder / "package" / c.source).resolve()
                if (folder / "package").resolve() not in target.parents:
                    raise SspError(f"{where}: component {c.name}: source {c.source} points "
                                   "outside the package")  # fmt: skip
                target.parent.mkdir(parents=True, exist_ok=True)
                with zf.open(c.source) as src, open(target, "wb") as dst:
                    shutil.copyfileobj(src, dst)
    except (zipfile.BadZipFile, OSError) as exc:
        raise SspError(f"{where}: cannot read the package ({exc})") from None
    return system, parameters


__all__ = ["SCHEMES", "TIMEOUT_S", "SspComponent", "SspPosition", "SspRun",
           "SspSystem", "SspTask", "read_ssd", "simulate_ssp"]  # fmt: skip
