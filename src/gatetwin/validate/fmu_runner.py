"""Open an FMI 2.0 or 3.0 co-simulation FMU with fmpy and drive it with a record's inputs.

* :func:`inspect_fmu` checks that a file is an FMU this harness can run (a zip whose
  members all stay inside its folder, with a readable ``modelDescription.xml``, FMI 2.0 or
  3.0 co-simulation, a binary for this platform, Real inputs ``opening_mm`` and ``flow_m3h``)
  and returns its :class:`FmuInfo`;
* :func:`static_findings` runs fmpy's static validator;
* :func:`communication_grid` lays the record's samples on the FMU's communication grid;
* :func:`run_fmu` simulates the FMU freely over that grid, in this process, and returns its
  output at every sample (:mod:`~gatetwin.validate.isolation` runs the same simulation in a
  child process).

Every failure is a :class:`~gatetwin.errors.ValidationError` with a one-line
message; an FMI call that fails is named with its status and the FMU's last log line.
This module runs FMUs; it computes no metrics and decides nothing.
"""

from __future__ import annotations

import hashlib
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import ValidationError
from gatetwin.records import GAP_FACTOR, gauge_of_column
from gatetwin.records.limits import check_unpacked_size, open_regular
from gatetwin.validate.mapping import VariableMap

__all__ = [
    "CALLS",
    "DO_STEP",
    "FMI_VERSIONS",
    "FMU_CALLS",
    "FREE_INSTANCE",
    "GET_REAL",
    "INITIALISE",
    "INPUTS",
    "INSTANTIATE",
    "LOADING",
    "MAX_FMU_STEPS",
    "SENDING",
    "SET_REAL",
    "STARTING",
    "STATUS_NAMES",
    "TERMINATE",
    "CommunicationGrid",
    "FmuInfo",
    "Position",
    "communication_grid",
    "inspect_fmu",
    "output_for_gauge",
    "run_fmu",
    "simulate_extracted",
    "static_findings",
    "unsafe_member",
]

#: FMI versions the harness runs (co-simulation).
FMI_VERSIONS = ("2.0", "3.0")
#: The inputs every gatetwin plant FMU has, in the order they are set.
INPUTS = ("opening_mm", "flow_m3h")
#: FMI 2.0 status names, by value.
STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")
#: Most communication steps the harness asks of an FMU for one record: 1,000,000 steps are
#: 13.9 days at the nominal 1.2 s (the bundled records need at most a few thousand). A record
#: whose grid needs more (a clock jump, a gap of days) is refused before any FMU runs.
MAX_FMU_STEPS = 1_000_000

#: What the FMU is doing, as :class:`Position` records it (``Position.call`` indexes this).
CALLS = (
    "starting the FMU process",
    "loading the binary",
    "fmi2Instantiate",
    "initialisation",
    "fmi2SetReal",
    "fmi2DoStep",
    "fmi2GetReal",
    "fmi2Terminate",
    "fmi2FreeInstance",
    "sending the result",
)
(STARTING, LOADING, INSTANTIATE, INITIALISE, SET_REAL, DO_STEP, GET_REAL, TERMINATE,
 FREE_INSTANCE, SENDING) = range(len(CALLS))  # fmt: skip
#: The calls that run the FMU's own code (from loading its binary to freeing its instance).
FMU_CALLS = CALLS[LOADING : FREE_INSTANCE + 1]


@dataclass(frozen=True)
class FmuInfo:
    """What the harness needs to know about an FMU (read from its model description).

    Attributes
    ----------
    path : str
        The ``.fmu`` file.
    model_identifier : str
        The co-simulation ``modelIdentifier`` (names the binary).
    guid : str
        The FMU's GUID.
    generation_tool : str
        ``generationTool`` of the model description ("" if absent).
    description : str
        The model description's ``description`` attribute ("" if absent).
    inputs, outputs : tuple of str
        Names of the input and output variables.
    value_references : dict[str, int]
        Value reference of every variable, by name.
    sha256 : str
        Hash of the ``.fmu`` file, for provenance.
    """

    path: str
    model_identifier: str
    guid: str
    generation_tool: str
    description: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    value_references: dict[str, int] = field(repr=False)
    sha256: str = ""
    fmi_version: str = "2.0"
    #: FMU value per record value of each mapped column (a foreign FMU's units; empty for
    #: gatetwin's FMUs, whose variables are the record's columns)
    scales: dict[str, float] = field(default_factory=dict, repr=False)
    #: the variable map a foreign FMU was opened with (for the report), else None
    variable_map: dict[str, Any] | None = None

    def scale(self, column: str) -> float:
        """FMU value per record value of ``column`` (1 for gatetwin's own FMUs)."""
        return self.scales.get(column, 1.0)

    @property
    def name(self) -> str:
        """The FMU's file name."""
        return Path(self.path).name

    @property
    def gauges(self) -> tuple[str, ...]:
        """Gauges of the ``level_<G>_mm`` outputs."""
        found = (gauge_of_column(name) for name in self.outputs)
        return tuple(g for g in found if g is not None)

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.name,
            "sha256": self.sha256,
            "model_identifier": self.model_identifier,
            "guid": self.guid,
            "fmi_version": self.fmi_version,
            "generation_tool": self.generation_tool,
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            **({"variable_map": self.variable_map} if self.variable_map else {}),
        }


def unsafe_member(name: str) -> str:
    """Why an archive member name could land outside the folder it is extracted to ("" when
    it cannot): an absolute path, a drive letter, a ``..`` part, a NUL byte."""
    parts = name.replace("\\", "/").split("/")
    if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":"):
        return "is an absolute path"
    if ".." in parts:
        return "climbs out of the FMU's folder ('..')"
    if "\0" in name:
        return "holds a NUL byte"
    return ""


def _archive_names(fmu: Path) -> set[str]:
    try:
        what = "an FMI 2.0 co-simulation FMU"
        with open_regular(fmu, sys.maxsize, what, ValidationError) as handle, \
                zipfile.ZipFile(handle) as archive:  # fmt: skip
            names = archive.namelist()
            check_unpacked_size(archive, str(fmu), ValidationError)
    except (zipfile.BadZipFile, OSError) as exc:
        raise ValidationError(f"{fmu}: not an FMU (not a readable zip archive: {exc})") from None
    for name in names:
        why = unsafe_member(name)
        if why:
            shown = name[:60].encode("unicode_escape", "backslashreplace").decode("ascii")
            raise ValidationError(f"{fmu}: refused: the archive member '{shown}' {why}; "
                                  "an FMU's files stay inside its folder")  # fmt: skip
    return set(names)


def _model_description(fmu: Path) -> Any:
    from fmpy import read_model_description

    try:
        return read_model_description(str(fmu), validate=False)
    except Exception as exc:  # fmpy and lxml raise many kinds; all mean "unreadable"
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise ValidationError(f"{fmu}: modelDescription.xml cannot be read ({text})") from None


def _check_binary(fmu: Path, names: set[str], identifier: str, fmi_version: str) -> None:
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    if fmi_version != "2.0":
        platform = platform_tuple  # FMI 3.0 names binary folders by platform tuple
    if f"binaries/{platform}/{identifier}{sharedLibraryExtension}" in names:
        return
    found = sorted(
        {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") > 1}
    )
    raise ValidationError(
        f"{fmu}: no binary for this platform (expected binaries/{platform}/{identifier}"
        f"{sharedLibraryExtension}; the FMU has binaries for: {', '.join(found) or 'none'})"
    )


def _check_inputs(fmu: Path, variables: list[Any]) -> None:
    inputs = {v.name: v.type for v in variables if v.causality == "input"}
    for name in INPUTS:
        if inputs.get(name) not in ("Real", "Float64"):  # FMI 2.0, FMI 3.0
            raise ValidationError(
                f"{fmu}: no Real input '{name}'; expected inputs {', '.join(INPUTS)} "
                f"(found: {', '.join(sorted(inputs)) or 'none'})"
            )


def inspect_fmu(path: str | Path, variable_map: VariableMap | None = None) -> FmuInfo:
    """Check that ``path`` is an FMU the harness can run, and describe it.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.
    variable_map : VariableMap, optional
        For an FMU whose variables are not the record's columns: the FMU variable (and its
        unit) behind each column (:mod:`gatetwin.validate.mapping`). The returned info then
        names the mapped variables by their columns.

    Returns
    -------
    FmuInfo

    Raises
    ------
    ValidationError
        Missing file, not a zip archive, a member with an absolute path or a ``..`` part,
        no or unreadable ``modelDescription.xml``, not FMI 2.0 or 3.0 co-simulation, no binary for
        this platform, no Real inputs ``opening_mm`` and ``flow_m3h`` (or, with a map, a mapped
        variable missing or of the wrong causality or type).
    """
    fmu = Path(path)
    names = _archive_names(fmu)
    if "modelDescription.xml" not in names:
        raise ValidationError(f"{fmu}: not an FMU (the archive has no modelDescription.xml)")
    md = _model_description(fmu)
    if md.fmiVersion not in FMI_VERSIONS or md.coSimulation is None:
        raise ValidationError(
            f"{fmu}: FMI {md.fmiVersion} without co-simulation; expected an FMI 2.0 or 3.0 "
            "co-simulation FMU"
        )
    identifier = md.coSimulation.modelIdentifier
    _check_binary(fmu, names, identifier, md.fmiVersion)
    variables = list(md.modelVariables)
    if variable_map is not None:
        variables = _mapped(fmu, variables, variable_map)
    _check_inputs(fmu, variables)
    return FmuInfo(
        path=str(fmu),
        model_identifier=identifier,
        guid=md.guid,
        generation_tool=md.generationTool or "",
        description=md.description or "",
        inputs=tuple(v.name for v in variables if v.causality == "input"),
        outputs=tuple(v.name for v in variables if v.causality == "output"),
        value_references={v.name: v.valueReference for v in variables},
        sha256=hashlib.sha256(fmu.read_bytes()).hexdigest(),
        fmi_version=md.fmiVersion,
        scales={c: variable_map.scale(c) for c in variable_map.variables} if variable_map else {},
        variable_map=variable_map.to_dict() if variable_map else None,
    )


@dataclass(frozen=True)
class _Variable:
    """A model variable as the harness sees it (a mapped one under its record column)."""

    name: str
    causality: str
    type: str
    valueReference: int  # noqa: N815 (fmpy's attribute name)


def _mapped(fmu: Path, variables: list[Any], variable_map: VariableMap) -> list[_Variable]:
    """The FMU's variables with each mapped one renamed to its record column (the FMU's own
    variables of the columns' names, if any, step aside)."""
    by_name = {v.name: v for v in variables}
    taken = {*variable_map.variables, *variable_map.variables.values()}
    out = [_Variable(v.name, v.causality, v.type, v.valueReference) for v in variables
           if v.name not in taken]  # fmt: skip
    for column, name in variable_map.variables.items():
        v = by_name.get(name)
        want = "input" if column in INPUTS else "output"
        if v is None or v.causality != want or v.type not in ("Real", "Float64"):
            found = "none" if v is None else f"a {v.type} {v.causality}"
            raise ValidationError(f"{fmu}: the map's [{column}] names {name!r}, which must be "
                                  f"a Real {want} of the FMU (found: {found})")  # fmt: skip
        out.append(_Variable(column, v.causality, v.type, v.valueReference))
    return out


def static_findings(path: str | Path) -> tuple[str, ...]:
    """Problems fmpy's static validator finds in the FMU (empty when none).

    Runs :func:`fmpy.validation.validate_fmu`: the model description against the XML
    schema, variable names, model structure, start values, causality/variability
    combinations and units. Call :func:`inspect_fmu` first: this expects a zip archive.
    """
    from fmpy.validation import validate_fmu

    return tuple(" ".join(str(p).split()) for p in validate_fmu(str(path)))


def output_for_gauge(info: FmuInfo, gauge: str | None) -> str:
    """The output variable to compare: ``level_<gauge>_mm``, or the FMU's only level output.

    Raises
    ------
    ValidationError
        The FMU has no such output, no level output, or several and ``gauge`` is None.
    """
    levels = info.gauges
    if gauge is not None:
        if gauge not in levels:
            raise ValidationError(
                f"{info.path}: no output level_{gauge}_mm (its level outputs: "
                f"{', '.join(f'level_{g}_mm' for g in levels) or 'none'})"
            )
        return f"level_{gauge}_mm"
    if len(levels) == 1:
        return f"level_{levels[0]}_mm"
    if not levels:
        raise ValidationError(
            f"{info.path}: no level_<G>_mm output (outputs: {', '.join(info.outputs) or 'none'})"
        )
    raise ValidationError(
        f"{info.path}: several level outputs ({', '.join(levels)}); choose one with --gauge"
    )


@dataclass(frozen=True)
class CommunicationGrid:
    """A record's samples on the FMU's communication grid.

    Sample ``k`` of the record is communication point ``index[k]`` of the FMU, at FMU time
    ``start_time_s + index[k] * step_s``. Between consecutive samples the FMU makes
    ``steps[k]`` steps of ``step_s``: one normally, several across a logging gap.

    Attributes
    ----------
    start_time_s : float
        FMU start time, s (the record's first time stamp).
    step_s : float
        Communication step, s (the record's nominal sample period).
    steps : ndarray of int
        Steps from sample ``k`` to sample ``k + 1``, length ``n - 1``.
    """

    start_time_s: float
    step_s: float
    steps: np.ndarray

    @property
    def index(self) -> np.ndarray:
        """Communication-point index of every sample."""
        return np.concatenate(([0], np.cumsum(self.steps)))

    @property
    def n_steps(self) -> int:
        """FMU steps in the whole run."""
        return int(np.sum(self.steps))

    @property
    def gaps(self) -> int:
        """Sample intervals that span more than one step (logging gaps)."""
        return int(np.count_nonzero(self.steps > 1))


def communication_grid(
    time_s: np.ndarray, sample_period_s: float, max_steps: int = MAX_FMU_STEPS
) -> CommunicationGrid:
    """Lay samples on a grid of the nominal sample period.

    A time step up to ``GAP_FACTOR`` (1.5) nominal periods is one step: the time stamps'
    jitter of a few milliseconds is not passed on to the FMU (an ARX FMU only accepts whole
    multiples of its period). A longer step is a logging gap and becomes
    ``round(dt / Ts)`` steps (at least 2).

    Parameters
    ----------
    time_s : ndarray
        Sample times, s, strictly increasing.
    sample_period_s : float
        Nominal sample period, s (> 0).
    max_steps : int
        Most steps the grid may have (default :data:`MAX_FMU_STEPS`).

    Raises
    ------
    ValidationError
        The period is not finite and positive, or the grid would need more than
        ``max_steps`` steps (the message names the largest gap and where it starts).
    """
    t = np.asarray(time_s, dtype=float)
    if not (sample_period_s > 0 and np.isfinite(sample_period_s)):
        raise ValidationError(f"sample period {sample_period_s} s must be finite and > 0")
    ratio = np.diff(t) / sample_period_s
    steps = np.where(ratio > GAP_FACTOR, np.maximum(2.0, np.rint(ratio)), 1.0)
    total = float(np.sum(steps))
    if not total <= max_steps:  # NaN too; checked in floats, before any integer overflow
        k = int(np.nanargmax(ratio))
        raise ValidationError(
            f"the FMU would have to make {total:.4g} communication steps of "
            f"{sample_period_s:g} s (more than the {max_steps} allowed); largest gap "
            f"{t[k + 1] - t[k]:.6g} s after t = {t[k]:.6g} s (sample {k})"
        )
    return CommunicationGrid(float(t[0]), float(sample_period_s), steps.astype(np.int64))


class Position:
    """Where an FMU run is: the FMI call under way, the record sample and the FMU time.

    Backed by any mutable sequence of three floats: a list in this process, or a shared
    array a parent process reads after its child died (:mod:`~gatetwin.validate.isolation`).
    """

    __slots__ = ("values",)
    CALL, SAMPLE, TIME_S = range(3)

    def __init__(self, values: Any = None) -> None:
        self.values = values if values is not None else [0.0, 0.0, 0.0]

    @property
    def call(self) -> str:
        """Name of the call under way (see :data:`CALLS`)."""
        index = int(self.values[self.CALL])
        return CALLS[index] if 0 <= index < len(CALLS) else "an unknown call"

    @property
    def sample(self) -> int:
        return int(self.values[self.SAMPLE])

    @property
    def time_s(self) -> float:
        return float(self.values[self.TIME_S])

    def at(self) -> str:
        """``at t = 12 s (record sample 10)``."""
        return f"at t = {self.time_s:.6g} s (record sample {self.sample})"

    def text(self) -> str:
        """``during fmi2DoStep at t = 12 s (record sample 10)``."""
        if self.call not in FMU_CALLS:
            return f"while {self.call}"
        return f"during {self.call} {self.at()}"


@dataclass
class _Session:
    """One instantiated FMU (:class:`gatetwin.fmi_host.Instance`, its log kept) and what the
    harness knows of it."""

    info: FmuInfo
    slave: Any

    def last_problem(self) -> str:
        """The FMU's last logged message of status warning or worse ("" if none)."""
        return self.slave.last_problem()

    def set_inputs(self, opening_mm: float, flow_m3h: float) -> None:
        vrs = [self.info.value_references[name] for name in INPUTS]
        scale = self.info.scale
        self.slave.setReal(vrs, [float(opening_mm) * scale(INPUTS[0]),
                                 float(flow_m3h) * scale(INPUTS[1])])  # fmt: skip


def _open_session(info: FmuInfo, unzip_dir: str, where: Position | None = None) -> _Session:
    from types import SimpleNamespace

    from gatetwin.fmi_host import open_instance

    def instantiating() -> None:
        if where is not None:
            where.values[Position.CALL] = INSTANTIATE

    md = SimpleNamespace(
        fmiVersion=info.fmi_version,
        guid=info.guid,
        coSimulation=SimpleNamespace(modelIdentifier=info.model_identifier),
    )
    return _Session(
        info,
        open_instance(
            md,
            unzip_dir,
            "gatetwin_validate",
            what=info.path,
            error=ValidationError,
            loaded=instantiating,
        ),
    )


def _simulate(
    session: _Session,
    output: str,
    grid: CommunicationGrid,
    opening: np.ndarray,
    flow: np.ndarray,
    position: Position | None = None,
) -> np.ndarray:
    """Run the session over the grid; ``position`` tracks the call, sample and time."""
    from fmpy.fmi1 import FMICallException

    slave, vr = session.slave, [session.info.value_references[output]]
    per_mm = session.info.scale(output)  # FMU output per mm (1 for gatetwin's FMUs)
    where = (position or Position()).values
    call, sample, time_s = Position.CALL, Position.SAMPLE, Position.TIME_S
    where[call], where[sample], where[time_s] = INITIALISE, 0, grid.start_time_s
    out = np.empty(opening.size)
    try:
        slave.setupExperiment(startTime=grid.start_time_s)
        slave.enterInitializationMode()
        session.set_inputs(opening[0], flow[0])
        slave.exitInitializationMode()
        where[call] = GET_REAL
        out[0] = slave.getReal(vr)[0] / per_mm
        t = grid.start_time_s
        for k in range(opening.size - 1):
            where[call], where[sample] = SET_REAL, k + 1
            session.set_inputs(opening[k], flow[k])
            where[call] = DO_STEP
            for _ in range(int(grid.steps[k])):
                where[time_s] = t
                slave.doStep(t, grid.step_s)
                t += grid.step_s
            where[call], where[time_s] = GET_REAL, t
            out[k + 1] = slave.getReal(vr)[0] / per_mm
        where[call] = TERMINATE
        slave.terminate()
    except FMICallException as exc:
        raise _call_error(session, exc, Position(where)) from None
    return out


def _call_error(session: _Session, exc: Any, where: Position) -> ValidationError:
    status = STATUS_NAMES[exc.status] if 0 <= exc.status < len(STATUS_NAMES) else "illegal"
    detail = session.last_problem()
    return ValidationError(
        f"{session.info.path}: {exc.function} returned status {exc.status} ({status}) at FMU "
        f"time {where.time_s:.6g} s, record sample {where.sample}"
        + (f"; FMU log: {detail}" if detail else "")
    )


def simulate_extracted(
    info: FmuInfo,
    unzip_dir: str,
    output: str,
    grid: CommunicationGrid,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
    position: Position | None = None,
) -> np.ndarray:
    """:func:`run_fmu` on an FMU already extracted to ``unzip_dir``, in this process.

    ``position`` (optional) is kept up to date with the FMI call under way, the record
    sample and the FMU time, for whoever must say where the FMU stopped.
    """
    where = position or Position()
    where.values[Position.CALL] = LOADING
    session = _open_session(info, unzip_dir, where)
    try:
        return _simulate(session, output, grid, np.asarray(opening_mm, dtype=float),
                         np.asarray(flow_m3h, dtype=float), where)  # fmt: skip
    finally:
        where.values[Position.CALL] = FREE_INSTANCE
        session.slave.freeInstance()


def run_fmu(
    info: FmuInfo,
    output: str,
    grid: CommunicationGrid,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
) -> np.ndarray:
    """Simulate the FMU freely over ``grid`` and return ``output`` at every sample.

    Protocol (FMI 2.0 co-simulation through :class:`fmpy.fmi2.FMU2Slave`): instantiate,
    ``setupExperiment(startTime=grid.start_time_s)``, enter initialization mode, set the
    first sample's inputs, exit initialization mode, read the output; then for every
    sample ``k`` set its inputs and hold them for the ``grid.steps[k]`` steps of
    ``grid.step_s`` to the next sample (``doStep``), and read the output there. No measured
    output is ever fed back (free run).

    Parameters
    ----------
    info : FmuInfo
        From :func:`inspect_fmu`.
    output : str
        Output variable to read, e.g. ``"level_3F_mm"``.
    grid : CommunicationGrid
        From :func:`communication_grid`.
    opening_mm : ndarray
        Gate opening at every sample, mm (finite).
    flow_m3h : ndarray
        Discharge at every sample, m³/h (finite).

    Returns
    -------
    ndarray
        The output at every sample, mm.

    Raises
    ------
    ValidationError
        The binary cannot be loaded, or an FMI call fails (named, with its status, the
        FMU time, the record sample and the FMU's last warning or error message).
    """
    from fmpy import extract

    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        unzip_dir = extract(info.path, tmp)
        return simulate_extracted(info, unzip_dir, output, grid, opening_mm, flow_m3h)
