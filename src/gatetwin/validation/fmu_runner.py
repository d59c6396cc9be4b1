"""Open an FMI 2.0 or 3.0 co-simulation FMU with fmpy and drive it with a record's inputs.

* :func:`inspect_fmu` checks that a file is an FMU this harness can run (a zip whose
  members all stay inside its folder, with a readable ``modelDescription.xml``, FMI 2.0 or
  3.0 co-simulation, a binary for this platform, Real inputs ``opening_mm`` and ``flow_m3h``)
  and returns its :class:`FmuInfo`;
* :func:`static_findings` runs fmpy's static validator;
* :func:`communication_grid` lays the record's samples on the FMU's communication grid;
* :func:`run_fmu` simulates the FMU freely over that grid, in this process, and returns its
  output at every sample (:mod:`~gatetwin.validation.isolation` runs the same simulation in a
  child process).

Every failure is a :class:`~gatetwin.errors.ValidationError` with a one-line
message; an FMI call that fails is named with its status and the FMU's last log line.
This module runs FMUs; it computes no metrics and decides nothing. The checks before a run
(:func:`inspect_fmu`, :func:`static_findings`, :func:`output_for_gauge`) live in
:mod:`gatetwin.validation.fmu_inspect` and are importable from here too.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import ValidationError
from gatetwin.records import GAP_FACTOR
from gatetwin.validation.fmu_inspect import (
    FMI_VERSIONS,
    INPUTS,
    FmuInfo,
    inspect_fmu,
    output_for_gauge,
    static_findings,
    unsafe_member,
)

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
    array a parent process reads after its child died (:mod:`~gatetwin.validation.isolation`).
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

    def inputs(self, opening_mm: float, flow_m3h: float) -> tuple[list[int], list[float]]:
        """The inputs' value references and their values in the FMU's units."""
        vrs = [self.info.value_references[name] for name in INPUTS]
        scale = self.info.scale
        return vrs, [float(opening_mm) * scale(INPUTS[0]), float(flow_m3h) * scale(INPUTS[1])]

    def set_inputs(self, opening_mm: float, flow_m3h: float) -> None:
        self.slave.setReal(*self.inputs(opening_mm, flow_m3h))


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
        slave.initialise(grid.start_time_s, session.inputs(opening[0], flow[0]))
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
    from gatetwin.fmi_host import unpack_fmu

    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        unzip_dir = unpack_fmu(info.path, tmp, str(info.path), ValidationError)
        return simulate_extracted(info, unzip_dir, output, grid, opening_mm, flow_m3h)
