"""The FMI-facing layer of the pythonfmu slave: every callback answers, none crashes its host.

Spliced into the slave at export (between the BEGIN/END markers of ``slave_template.py``), so it
uses the standard library and pythonfmu only. It is not the plant: ``GuardedSlave`` turns the
plant's refusals into FMI statuses and log lines, and owns the FMU-state handles.

How pythonfmu 0.7.0's C wrapper (``libpythonfmu-export``) treats a callback:

* A Python exception out of any callback becomes ``fmi2Fatal`` with the exception's text, and
  on the way the wrapper releases one reference each to the slave class, the instance and the
  instance's log queue while keeping its pointers to them. Left alone, a few refusals free the
  log queue, the instance or the class under the wrapper: the next call, or a garbage
  collection after ``fmi2FreeInstance``, reads freed memory. :meth:`GuardedSlave._refuse`
  takes those three references beforehand, so the instance survives its refusals intact.
* ``do_step`` returning False is ``fmi2Discard``: a refused step is answered that way, with the
  state unchanged, and never with an exception.
* ``_fmu_state_from_bytes`` and ``_fmu_state_to_bytes`` are called on the class, where no
  instance is known, so they never raise: bytes that are not a state of this model give a
  handle that ``fmi2SetFMUstate`` refuses with the reason.
* ``fmi2FreeFMUstate`` only releases one reference to the state object and does not clear the
  caller's pointer, so a second free of the same pointer releases a reference nobody owns.
  State handles are therefore kept by the class with :data:`PINNED_REFERENCES` references of
  their own (restored whenever a sweep finds some released), and reused once the host has
  freed them: a double free can make a reused handle read as freed, but never frees memory.
* The GUID the host passes to ``fmi2Instantiate`` never reaches Python, so a wrong GUID cannot
  be refused here; ``fmi2Instantiate`` with a resource location that does not hold the slave
  fails inside the wrapper before any of this code runs.
"""

from __future__ import annotations

import ctypes
import json
import sys
from typing import Any, ClassVar

from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

__all__ = [
    "PINNED_REFERENCES",
    "STATE_FORMAT",
    "STATE_VERSION",
    "FmiRefusedError",
    "GuardedSlave",
    "RefusedError",
    "StateHandle",
]

#: References each state handle holds on itself against hosts that free a state twice.
PINNED_REFERENCES = 64
#: ``format`` of a serialised state; ``version`` changes when its layout does.
STATE_FORMAT = "gatetwin-fmu-state"
STATE_VERSION = 1


class RefusedError(Exception):
    """A call the slave refuses; the message says why (no ``fmi2`` prefix)."""


class FmiRefusedError(Exception):
    """Raised to pythonfmu's wrapper to make it answer ``fmi2Fatal`` (its only error path)."""


class StateHandle:
    """What the host holds as an ``fmi2FMUstate``: a state, or the reason there is none."""

    __slots__ = ("payload", "reason")

    def __init__(self) -> None:
        self.payload: dict[str, Any] | None = None
        self.reason = "the FMU state was freed"


def _pin(handle: StateHandle, count: int) -> None:
    for _ in range(count):
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(handle))


class GuardedSlave(Fmi2Slave):
    """Fmi2Slave whose callbacks refuse with a status and a log line instead of crashing.

    A subclass implements the plant: ``_setup(start_time)``, ``_initialize()``,
    ``_step(current_time, step_size)``, ``_read(vr)``, ``_write(vrs, values)`` (validate all,
    then apply), ``_state()``, ``_checked_state(state)`` (a complete validated copy, or
    RefusedError), ``_load_state(state)``, ``_snapshot()``/``_restore(snapshot)`` around steps; each
    raises :class:`RefusedError` with the reason. ``model_guid`` identifies the model's states.
    """

    _handles: ClassVar[list[StateHandle]] = []
    _unheld: ClassVar[int | None] = None
    model_guid: ClassVar[str] = ""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.terminated = False

    # -- refusing ------------------------------------------------------------------------------
    def _refuse(self, function: str, exc: BaseException) -> FmiRefusedError:
        """Log why ``function`` is refused and return the exception to raise to the wrapper."""
        if isinstance(exc, RefusedError):
            message = f"{function}: {exc}"
        else:  # a defect, not a refusal: still an answer, never a crash
            message = f"{function}: internal error {type(exc).__name__}: {exc}"
        self.log(message, Fmi2Status.error, "logStatusError")
        # the wrapper's exception path also releases the queued log messages it forwards: pin
        # them too, or a message is freed while the queue still holds it (heap corruption that
        # showed in some runs only, depending on the hash seed)
        for owned_by_wrapper in (type(self), self, self.log_queue, *self.log_queue):
            ctypes.pythonapi.Py_IncRef(ctypes.py_object(owned_by_wrapper))
        return FmiRefusedError(message)

    def _alive(self, function: str) -> None:
        if self.terminated:
            raise RefusedError(f"the instance was terminated; {function} is not allowed any more")

    # -- the lifecycle ---------------------------------------------------------------------------
    def setup_experiment(self, start_time: float, stop_time: Any = None, tolerance: Any = None):
        try:
            self._alive("fmi2SetupExperiment")
            self._setup(start_time)
        except Exception as exc:
            raise self._refuse("fmi2SetupExperiment", exc) from None

    def enter_initialization_mode(self) -> None:
        try:
            self._alive("fmi2EnterInitializationMode")
        except Exception as exc:
            raise self._refuse("fmi2EnterInitializationMode", exc) from None

    def exit_initialization_mode(self) -> None:
        snapshot = self._snapshot()
        try:
            self._alive("fmi2ExitInitializationMode")
            self._initialize()
        except Exception as exc:
            self._restore(snapshot)
            raise self._refuse("fmi2ExitInitializationMode", exc) from None

    def do_step(self, current_time: float, step_size: float) -> bool:
        snapshot = self._snapshot()
        try:
            self._alive("fmi2DoStep")
            self._step(current_time, step_size)
        except Exception as exc:
            self._restore(snapshot)
            message = (
                str(exc)
                if isinstance(exc, RefusedError)
                else (f"fmi2DoStep: internal error {type(exc).__name__}: {exc}")
            )
            self.log(message, Fmi2Status.error, "logStatusError")  # the plant's words only
            return False
        return True

    def terminate(self) -> None:
        self.terminated = True

    # -- variables -----------------------------------------------------------------------------
    def get_real(self, vrs: list[int]) -> list[float]:
        try:
            return [self._read(vr) for vr in vrs]
        except Exception as exc:
            raise self._refuse("fmi2GetReal", exc) from None

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        try:
            self._alive("fmi2SetReal")
            self._write(vrs, values)
        except Exception as exc:
            raise self._refuse("fmi2SetReal", exc) from None

    def _no_variables(self, function: str, kind: str, vrs: list[int]) -> None:
        if vrs:
            raise self._refuse(
                function,
                RefusedError(f"the model has no {kind} variables (value reference {vrs[0]})"),
            )

    def get_integer(self, vrs: list[int]) -> list[int]:
        self._no_variables("fmi2GetInteger", "Integer", vrs)
        return []

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._no_variables("fmi2SetInteger", "Integer", vrs)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        self._no_variables("fmi2GetBoolean", "Boolean", vrs)
        return []

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._no_variables("fmi2SetBoolean", "Boolean", vrs)

    def get_string(self, vrs: list[int]) -> list[str]:
        self._no_variables("fmi2GetString", "String", vrs)
        return []

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._no_variables("fmi2SetString", "String", vrs)

    # -- FMU states ----------------------------------------------------------------------------
    @classmethod
    def _reference_counts(cls) -> list[int]:
        return [sys.getrefcount(handle) for handle in cls._handles]

    @classmethod
    def _handle(cls, payload: dict[str, Any] | None, reason: str) -> StateHandle:
        """A handle for the host: one the host has freed, reused, or a new pinned one."""
        if cls._unheld is None:  # what a pinned handle nobody else holds counts, measured
            cls._handles.append(StateHandle())
            _pin(cls._handles[-1], PINNED_REFERENCES)
            cls._unheld = cls._reference_counts()[-1]
        free = None
        for handle, count in zip(cls._handles, cls._reference_counts(), strict=True):
            if count < cls._unheld:  # freed more often than handed out: restore the pins
                _pin(handle, cls._unheld - count)
            if count <= cls._unheld:
                handle.payload, handle.reason = None, "the FMU state was freed"
                free = free or handle
        if free is None:
            free = StateHandle()
            _pin(free, PINNED_REFERENCES)
            cls._handles.append(free)
        free.payload, free.reason = payload, reason
        return free

    def _get_fmu_state(self) -> StateHandle:
        try:
            state = json.loads(json.dumps(self._state(), allow_nan=False))
            payload = {"format": STATE_FORMAT, "version": STATE_VERSION,
                       "guid": self.model_guid, "state": state}  # fmt: skip
            return self._handle(payload, "")
        except Exception as exc:
            raise self._refuse("fmi2GetFMUstate", exc) from None

    def _set_fmu_state(self, handle: Any) -> None:
        try:
            self._load_state(self._checked_state(self._payload_state(handle)))
        except Exception as exc:
            raise self._refuse("fmi2SetFMUstate", exc) from None

    def _payload_state(self, handle: Any) -> dict[str, Any]:
        if not isinstance(handle, StateHandle):
            raise RefusedError(f"not an FMU state of this model (a {type(handle).__name__})")
        payload = handle.payload
        if payload is None:
            raise RefusedError(handle.reason)
        if not isinstance(payload, dict) or payload.get("format") != STATE_FORMAT:
            raise RefusedError("not a gatetwin FMU state")
        if payload.get("version") != STATE_VERSION:
            raise RefusedError(f"FMU state version {payload.get('version')!r}, this FMU reads "
                          f"{STATE_VERSION}")  # fmt: skip
        if payload.get("guid") != self.model_guid:
            raise RefusedError(f"the FMU state belongs to the model {payload.get('guid')!r}, not "
                          f"{self.model_guid!r}")  # fmt: skip
        if set(payload) != {"format", "version", "guid", "state"}:
            raise RefusedError(f"FMU state has the keys {sorted(payload)}")
        if not isinstance(payload["state"], dict):
            raise RefusedError("FMU state: 'state' is not an object")
        return payload["state"]

    @classmethod
    def _fmu_state_to_bytes(cls, handle: Any) -> bytes:
        payload = handle.payload if isinstance(handle, StateHandle) else None
        if payload is None:  # refused on restore, with the reason
            return b"{}"
        return json.dumps(payload, allow_nan=False, separators=(",", ":")).encode("utf-8")

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes) -> StateHandle:
        try:
            payload = json.loads(bytes(data).decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            return cls._handle(None, f"the serialised FMU state is not JSON ({exc})")
        if not isinstance(payload, dict):
            return cls._handle(None, "the serialised FMU state is not a JSON object")
        return cls._handle(payload, "")
