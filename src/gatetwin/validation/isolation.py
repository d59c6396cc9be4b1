"""Run an FMU in a child process, so that nothing the FMU does can take the harness down.

An FMU is foreign native code. Its ``fmi2DoStep`` may call ``exit()`` or ``abort()``, write
through a null pointer, never return, or return NaN; loaded into the validating process,
the first four end or hang the whole validation with no report. :func:`run_isolated` runs
each record of an FMU in a child process instead, under a wall-clock limit, and turns
whatever ends the child into a one-line cause for that record alone:

* a signal: ``the FMU process died with signal 6 (SIGABRT) during fmi2DoStep at t = …``;
* an exit: ``the FMU called exit(0) during fmi2DoStep at t = …``;
* the limit: ``no result within 30 s (the FMU was in fmi2DoStep at t = …); its process was
  killed``.

The child keeps the FMI call under way, the record sample and the FMU time in a small
shared array (:class:`~gatetwin.validation.fmu_runner.Position`), which is read after the
child is gone. An FMI call that returns an error status is not a crash: the child answers
with the message and :func:`run_isolated` raises it as a
:class:`~gatetwin.errors.ValidationError`, as the in-process run does.

Processes. This process starts one *FMU host* (``python -c``, talking over two pipes of
its own, so an FMU printing on stdout cannot garble it), which imports numpy, fmpy and
this module once and lives until this process ends. For every task the host forks a child,
ready in milliseconds: for :func:`run_isolated` the task is one FMU, whose records the child
runs one at a time; :func:`gatetwin.ssp.simulate_ssp` sends a whole SSP as one task
(:func:`run_task`). A child that died,
exited, overran its limit (killed) or raised fails only the record it was running; the
next record gets a new child. The host never loads an FMU, so it outlives them all, and
it stops (killing its child) as soon as this process goes away. Children never write core
files. Why not :mod:`multiprocessing` from this process with ``spawn`` or ``forkserver``:
both re-import the caller's main module in every child (a script without an
``if __name__ == "__main__"`` guard would fail, one with it would pay its imports per
FMU); and why not one ``subprocess`` per FMU: a fresh interpreter's imports take most of a
second, per FMU and again after every crash. The host needs POSIX (``fork``, inherited
pipes); the FMUs the harness runs are POSIX builds too.

Files. This process extracts the FMU into a temporary folder it owns and removes on every
path, a killed child included; the child only loads the binary from there.

This module runs FMUs and names why a run ended; it computes no metrics.
"""

from __future__ import annotations

import atexit
import math
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import GatetwinError, ValidationError
from gatetwin.validation.fmu_runner import (
    FMU_CALLS,
    SENDING,
    STARTING,
    CommunicationGrid,
    FmuInfo,
    Position,
    simulate_extracted,
)

__all__ = [
    "HOST_GRACE_S",
    "STOP_GRACE_S",
    "TIMEOUT_BASE_S",
    "TIMEOUT_PER_STEP_S",
    "FmuTask",
    "RunRequest",
    "RunResult",
    "check_timeout",
    "default_timeout_s",
    "host_main",
    "run_in_process",
    "run_isolated",
    "run_task",
    "start_host",
]

#: Wall-clock limit of one FMU × record run when none is given: this base, s ...
TIMEOUT_BASE_S = 10.0
#: ... plus this much per communication step, s. Through fmpy a C FMU takes about 10 µs a
#: step and a pythonfmu FMU about 100 µs, so 1 ms leaves a factor of 10 or more for a slow
#: or busy machine; the base covers starting the child and loading the binary.
TIMEOUT_PER_STEP_S = 1e-3
#: How long a child that was asked to stop may take before it is killed, s.
STOP_GRACE_S = 2.0


def default_timeout_s(grid: CommunicationGrid) -> float:
    """The wall-clock limit of a run over ``grid`` when none is given, s.

    ``TIMEOUT_BASE_S + TIMEOUT_PER_STEP_S * grid.n_steps``: 10.75 s for a 750-step record.
    """
    return TIMEOUT_BASE_S + TIMEOUT_PER_STEP_S * grid.n_steps


def check_timeout(timeout_s: float | None) -> None:
    """Refuse a wall-clock limit that is not a finite number of seconds > 0 (None is fine)."""
    if timeout_s is not None and not (0 < timeout_s < math.inf):
        raise ValidationError(f"timeout {timeout_s} s must be a finite number of seconds > 0")


@dataclass(frozen=True)
class RunRequest:
    """One free run: the output to read, the grid and the inputs at every sample.

    Attributes
    ----------
    output : str
        Output variable, e.g. ``"level_3F_mm"``.
    grid : CommunicationGrid
    opening_mm, flow_m3h : ndarray
        Inputs at every sample, mm and m³/h.
    """

    output: str
    grid: CommunicationGrid
    opening_mm: np.ndarray
    flow_m3h: np.ndarray


@dataclass(frozen=True)
class RunResult:
    """How one run in a child ended.

    Attributes
    ----------
    result : Any
        What the task's run returned: for :func:`run_isolated`, the output at every sample
        (None when the run failed).
    failure_cause : str
        Why the run gave no output ("" when it did).
    seconds : float
        Wall-clock time of the run, s (starting the child included).
    """

    result: Any
    failure_cause: str = ""
    seconds: float = math.nan


def run_in_process(info: FmuInfo, requests: Sequence[RunRequest]) -> list[RunResult]:
    """Run every request in this process (no protection; for comparison and debugging)."""
    from gatetwin.fmi_host import unpack_fmu

    results = []
    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        unzip_dir = unpack_fmu(info.path, tmp, str(info.path), ValidationError)
        for r in requests:
            start = time.perf_counter()
            out = simulate_extracted(info, unzip_dir, r.output, r.grid, r.opening_mm,
                                     r.flow_m3h)  # fmt: skip
            results.append(RunResult(out, "", time.perf_counter() - start))
    return results


def run_isolated(
    info: FmuInfo, requests: Sequence[RunRequest], timeout_s: float | None = None
) -> list[RunResult]:
    """Run every request in a child process; one :class:`RunResult` per request, in order.

    Parameters
    ----------
    info : FmuInfo
        From :func:`~gatetwin.validation.fmu_runner.inspect_fmu`.
    requests : sequence of RunRequest
    timeout_s : float, optional
        Wall-clock limit of each run, s; default :func:`default_timeout_s` of its grid.

    Raises
    ------
    ValidationError
        An FMI call returned an error status (the message names the call, the FMU time, the
        record sample and the FMU's last log line), the binary cannot be loaded, or the
        limit is not a positive number.
    """
    from gatetwin.fmi_host import unpack_fmu

    check_timeout(timeout_s)
    limits = [timeout_s if timeout_s is not None else default_timeout_s(r.grid) for r in requests]
    with tempfile.TemporaryDirectory(prefix="gatetwin-validate-") as tmp:
        unzip_dir = unpack_fmu(info.path, tmp, str(info.path), ValidationError)
        answer = run_task(FmuTask(info, unzip_dir), list(requests), limits)
    if isinstance(answer, str):
        raise ValidationError(answer)
    return answer


class FmuTask:
    """What a child runs for :func:`run_isolated`: one extracted FMU, a record at a time.

    A task for :func:`run_task` has this interface: ``name`` (the child's process name),
    ``per_call`` (True: a request's limit bounds each call, see :func:`run_task`),
    ``position(shared)`` (a :class:`Position` over the shared array of ``SLOTS`` floats)
    and ``run(request, position)`` (the request's result, in the child).
    """

    per_call = False
    SLOTS = 3

    def __init__(self, info: FmuInfo, unzip_dir: str) -> None:
        self.info, self.unzip_dir = info, unzip_dir

    @property
    def name(self) -> str:
        return f"gatetwin-validate {self.info.name}"

    def position(self, shared: Any) -> Position:
        return Position(shared)

    def run(self, r: RunRequest, position: Position) -> np.ndarray:
        return simulate_extracted(self.info, self.unzip_dir, r.output, r.grid, r.opening_mm,
                                  r.flow_m3h, position)  # fmt: skip


def run_task(task: Any, requests: list[Any], limits: list[float]) -> list[RunResult] | str:
    """Run each request of ``task`` in a child process of the FMU host, in order.

    ``limits[i]`` bounds request ``i``: its whole run, or, for a task whose ``per_call`` is
    True, each stretch in which the task's position does not move (one FMI call that does
    not return), so a long run of quick calls is never cut. Returns one :class:`RunResult`
    per request, or the message of a :class:`~gatetwin.errors.GatetwinError` the task
    raised (an FMI error status) for the caller to raise as its own kind of error.
    """
    total = None if task.per_call else sum(limits)
    return _host().run((task, requests, limits), total)


def start_host() -> None:
    """Start the FMU host process if it is not running (returns at once).

    Its imports then overlap with whatever this process does before the first run.
    """
    _host()


_HOSTS: list[_Host] = []  # the one running host of this process, if any


def _host() -> _Host:
    if not (_HOSTS and _HOSTS[0].alive):
        for old in _HOSTS:
            old.close()
        _HOSTS[:] = [_Host()]
    return _HOSTS[0]


@atexit.register
def _close_host() -> None:
    for host in _HOSTS:
        host.close()


class _Host:
    """The FMU host process, seen from this process: send a job, wait for its results."""

    def __init__(self) -> None:
        to_host, self._to_host = os.pipe()
        self._from_host, from_host = os.pipe()
        package_root = str(Path(__file__).resolve().parents[2])
        path = os.pathsep.join(p for p in (package_root, os.environ.get("PYTHONPATH")) if p)
        env = {**os.environ, "PYTHONPATH": path, "OPENBLAS_NUM_THREADS": "1",
               "OMP_NUM_THREADS": "1"}  # fmt: skip
        self.process = subprocess.Popen(
            [sys.executable, "-c", _HOST_CODE, str(to_host), str(from_host)],
            pass_fds=(to_host, from_host), stdin=subprocess.DEVNULL, env=env,
        )  # fmt: skip
        os.close(to_host)
        os.close(from_host)
        self.jobs = Connection(self._to_host, readable=False)
        self.answers = Connection(self._from_host, writable=False)
        self.lock = threading.Lock()  # one job at a time, whatever thread sends it

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def run(self, job: tuple[Any, ...], limit_s: float | None) -> list[RunResult] | str:
        """Send one task's job; its results, or an error message to raise. ``limit_s``: how
        long its runs may take in all (None: each run bounds itself, call by call)."""
        wait_s = None if limit_s is None else limit_s + HOST_GRACE_S
        with self.lock:
            try:
                self.jobs.send(job)
                if self._answered(wait_s):
                    return self.answers.recv()
            except (OSError, EOFError):
                pass
            except BaseException:  # interrupted: a later job must not read this one's answer
                self.close()
                raise
            self.close()
        return ("the FMU host process ended" + (f" or gave no answer within {wait_s:g} s"
                if wait_s is not None else "") + " (it was stopped)")  # fmt: skip

    def _answered(self, wait_s: float | None) -> bool:
        """Whether an answer came within ``wait_s`` (None: as long as the host lives; its
        children hold the pipe open, so a dead host gives no end-of-file)."""
        if wait_s is not None:
            return self.answers.poll(wait_s)
        while not self.answers.poll(HOST_GRACE_S):
            if not self.alive:
                return self.answers.poll(0)
        return True

    def close(self) -> None:
        """End the host (closing its pipe ends it; killed if it lingers)."""
        for conn in (self.jobs, self.answers):
            if not conn.closed:
                conn.close()
        try:
            self.process.wait(HOST_GRACE_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


#: How long past the sum of its runs' limits the host may take to answer, or to end, s.
HOST_GRACE_S = 5.0
#: The host's program. It imports only the modules a run needs: ``gatetwin.validation`` is
#: entered as a bare package, without its ``__init__`` (the whole harness: identification,
#: scipy), which makes the host start in a third of the time and its forks a third the size.
_HOST_CODE = """
import importlib.util, sys, types
spec = importlib.util.find_spec("gatetwin.validation")
package = types.ModuleType(spec.name)
package.__path__, package.__spec__ = spec.submodule_search_locations, spec
sys.modules[spec.name] = package
from gatetwin.validation.isolation import host_main
host_main(int(sys.argv[1]), int(sys.argv[2]))
"""


# --------------------------------------------------------------------------- the host


def host_main(jobs_fd: int, answers_fd: int) -> None:
    """The FMU host's loop: for each job (a task, its requests and limits), run the requests
    in children and answer with the results; end when this process's parent goes away."""
    import fmpy.fmi1
    import fmpy.fmi2  # noqa: F401 - imported once here, inherited by every forked child

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # an interrupt is the parent's to handle
    jobs = Connection(jobs_fd, writable=False)
    answers = Connection(answers_fd, readable=False)
    while True:
        try:
            task, requests, limits = jobs.recv()
        except (EOFError, OSError):
            return
        try:
            answers.send(_run_children(task, requests, limits, jobs))
        except _ParentGoneError:
            return
        except GatetwinError as exc:
            answers.send(str(exc))


class _ParentGoneError(Exception):
    """The parent closed its end of the job pipe while a child ran."""


def _run_children(task: Any, requests: list[Any], limits: list[float], parent: Any
                  ) -> list[RunResult]:  # fmt: skip
    results: list[RunResult] = []
    child: _Child | None = None
    try:
        for request, limit in zip(requests, limits, strict=True):
            child = child or _Child(task)
            results.append(child.run(request, limit, parent))
            if results[-1].failure_cause or not child.alive:  # a fresh child for the next
                child.stop()
                child = None
    finally:
        if child is not None:
            child.stop()
    return results


def _context() -> Any:
    return multiprocessing.get_context("fork")  # in the host: one thread, no FMU loaded


class _Child:
    """One child process holding one task (an extracted FMU); runs one request at a time."""

    def __init__(self, task: Any) -> None:
        ctx = _context()
        self.task = task
        self.position = task.position(ctx.RawArray("d", task.SLOTS))
        self.position.values[Position.CALL] = STARTING
        self.conn, child_end = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child_end, task, self.position.values),
                                   name=task.name, daemon=True)  # fmt: skip
        self.process.start()
        child_end.close()

    @property
    def alive(self) -> bool:
        return self.process.is_alive()

    def run(self, request: RunRequest, timeout_s: float, parent: Any) -> RunResult:
        """Send one request and wait at most ``timeout_s`` for its answer (for a per-call
        task: at most ``timeout_s`` while its position stands still).

        Raises :class:`_ParentGoneError` (the child killed) when ``parent`` reaches its end first.
        """
        start = time.perf_counter()
        try:
            self.conn.send(request)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the child is gone already; its exit status says why
        ready = self._wait(parent, timeout_s)
        if parent in ready and self.conn not in ready:
            self.kill()
            raise _ParentGoneError
        if ready:
            answer = self._receive()
            cause = self._answer_cause(answer) if answer is not None else self._exit_cause()
        else:
            where = self.position
            self.kill()
            what = "no FMI call returned" if self.task.per_call else "no result"
            cause = (f"{what} within {timeout_s:g} s (the FMU was in {where.call} "
                     f"{where.at()}); its process was killed")  # fmt: skip
        seconds = time.perf_counter() - start
        if cause:
            return RunResult(None, cause, seconds)
        return RunResult(answer[1] if answer else None, "", seconds)

    def _wait(self, parent: Any, timeout_s: float) -> list[Any]:
        """What became ready within the limit ([] when it passed)."""
        watched = [self.conn, self.process.sentinel, parent]
        before = list(self.position.values)
        while True:
            ready = wait(watched, timeout_s)
            if ready or not self.task.per_call:
                return ready
            now = list(self.position.values)
            if now == before:
                return []  # a whole limit, or up to two, without moving on
            before = now

    def _receive(self) -> tuple[str, Any] | None:
        try:
            return self.conn.recv() if self.conn.poll() else None
        except (EOFError, ConnectionResetError):
            return None

    def _answer_cause(self, answer: tuple[str, Any]) -> str:
        kind, payload = answer
        if kind == "error":
            raise ValidationError(payload)
        return payload if kind == "failed" else ""

    def _exit_cause(self) -> str:
        self.process.join(STOP_GRACE_S)
        code = self.process.exitcode
        where = self.position.text()
        if code is None:
            self.kill()
            return f"the FMU process stopped answering {where}; it was killed"
        if code < 0:
            return f"the FMU process died with signal {-code} ({_signal_name(-code)}) {where}"
        if self.position.call in FMU_CALLS:
            return f"the FMU called exit({code}) {where}"
        return f"the FMU process exited with status {code} {where}"

    def kill(self) -> None:
        self.process.kill()
        self.process.join()

    def stop(self) -> None:
        """Ask the child to end, kill it if it does not, and release its pipe."""
        if self.process.is_alive():
            try:
                self.conn.send(_STOP)
            except (BrokenPipeError, ConnectionResetError):
                pass
            self.process.join(STOP_GRACE_S)
            if self.process.is_alive():
                self.kill()
        self.process.join()
        self.conn.close()
        self.process.close()


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return "unknown signal"


# --------------------------------------------------------------------------- the child


#: What a child is sent to make it end (a request may be anything else, None included).
_STOP = "gatetwin: stop"


def _serve(conn: Any, task: Any, shared: Any) -> None:
    """The child's loop: run each request received, answer, stop on ``_STOP`` or EOF."""
    _no_core_files()
    position = task.position(shared)
    while True:
        try:
            request = conn.recv()
        except EOFError:
            return
        if isinstance(request, str) and request == _STOP:
            return
        conn.send(_answer(task, request, position))


def _answer(task: Any, request: Any, position: Position) -> tuple[str, Any]:
    """``("ok", output)``, ``("error", message)`` for an FMI error status (any gatetwin
    error), or ``("failed", cause)`` for anything else raised while the FMU ran."""
    try:
        out = task.run(request, position)
    except GatetwinError as exc:
        return "error", str(exc)
    except Exception as exc:  # whatever the FMU's side raises fails this record only
        text = " ".join(str(exc).split())
        return "failed", f"the FMU run raised {type(exc).__name__}" + (f": {text}" if text else "")
    position.values[Position.CALL] = SENDING
    return "ok", out


def _no_core_files() -> None:
    try:
        import resource
    except ImportError:  # pragma: no cover - not on Windows
        return
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
