"""Run one task per gate (or per record): in this process, on a local process pool, or on a
dask cluster.

Processes, never threads: the FMU binaries and the numba kernels are not assumed
thread-safe. A pool process runs its numerical libraries on one thread each
(:data:`POOL_THREADS`), as a dask nanny starts its workers: the processes are the
parallelism, and a BLAS with a thread per core in every process oversubscribes the cores.
Every mode runs the same task function (:func:`~gatetwin.fleet.gate.identify_gate` for
``gatetwin models``, one record's validation for ``gatetwin validate``) on the same inputs,
so every mode gives the same results. Results come back in completion order (each one
reported to ``progress``); :func:`run_tasks` returns them in the jobs' order.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from gatetwin.errors import GatetwinError

__all__ = [
    "POOL_THREADS",
    "WORKER_POLL_S",
    "Crashed",
    "FleetSettings",
    "Progress",
    "Task",
    "connect",
    "default_workers",
    "map_tasks",
    "run_tasks",
    "shared_pool",
    "spawn_environment",
    "stop_shared_pools",
]

Progress = Callable[[str], None]

#: Threads of the numerical libraries in a local pool's processes, set where the caller's
#: environment does not: one, as dask's nanny (``distributed.nanny.pre-spawn-environ``).
#: With OpenBLAS's default of a thread per core, the gates of an 8-gate district on 2
#: processes of a 2-core machine took up to 3x their serial time (gate002: 3.3 s serially,
#: 11.9 s on the pool), and the pool of 16 gates was no faster than the serial run
#: (``benchmarks/bench_fleet.py``, docs/many-gates.md).
POOL_THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@dataclass(frozen=True)
class FleetSettings:
    """Where the gates run.

    Attributes
    ----------
    scheduler : str | None
        Address of a ``dask.distributed`` scheduler (``tcp://host:8786``); ``None`` for a
        local run.
    workers : int
        Local processes when no scheduler is given; 1 runs every gate in this process.
    connect_timeout_s : float
        How long to wait for the scheduler to answer and for its first worker, s; also how
        long a scheduler may be left with no worker before the jobs it still holds are
        failed (every worker died: nothing would ever run them).
    """

    scheduler: str | None = None
    workers: int = 1
    connect_timeout_s: float = 20.0

    def describe(self) -> str:
        if self.scheduler:
            return f"dask scheduler {self.scheduler}"
        if self.workers <= 1:
            return "serial, one process"
        return f"local process pool, {self.workers} workers"


def default_workers() -> int:
    """Local workers by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


#: How often a dask run with nothing finished asks the scheduler for its workers, s.
WORKER_POLL_S = 1.0
Task = Callable[[Any], Any]
#: What a task whose process died (or could not run it) returns instead: job, exception.
Crashed = Callable[[Any, BaseException], Any]


def _serial(task: Task, jobs: list[Any], crashed: Crashed) -> Iterator[tuple[int, Any]]:
    """In this process, its numerical libraries on one thread as in a pool's processes
    (:data:`POOL_THREADS`): a multi-threaded BLAS splits its sums differently, and a fit's
    last digits, then its stopping point, would depend on the cores and on the mode."""
    from threadpoolctl import threadpool_limits

    del crashed  # in this process an exception is the caller's, as in any serial code
    for k, job in enumerate(jobs):
        with threadpool_limits(limits=1):
            result = task(job)
        yield k, result


@contextlib.contextmanager
def spawn_environment(values: Mapping[str, str]) -> Iterator[None]:
    """``values`` in ``os.environ`` (each one the caller has not set) while processes are
    spawned, so that they start with them; removed again afterwards."""
    added = {k: v for k, v in values.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


#: The local pools :func:`shared_pool` keeps open, by number of workers.
_SHARED: dict[int, ProcessPoolExecutor] = {}


@contextlib.contextmanager
def shared_pool(settings: FleetSettings | None) -> Iterator[None]:
    """Within the block, local pools of ``settings.workers`` processes are one pool, started
    at its first task and shut down at the end: the stages of ``gatetwin run`` share its
    processes, so each process imports the libraries and compiles the numba kernels once
    instead of once per stage. Nothing changes where there is no local pool (serial, dask).
    A pool that has lost a process (during a call or between calls) is replaced at the next
    call."""
    workers = settings.workers if settings and not settings.scheduler else 1
    if workers <= 1 or workers in _SHARED:
        yield
        return
    _SHARED[workers] = _new_pool(workers)
    try:
        yield
    finally:
        _SHARED.pop(workers).shutdown(cancel_futures=True)
        _STOPPED.clear()


def stop_shared_pools() -> None:
    """Cancel the shared pools' waiting tasks and refuse new ones until the block of
    :func:`shared_pool` ends: an interrupted ``gatetwin run`` whose stages run in threads
    lets them end quickly (their tasks refused) before it removes what they write into."""
    _STOPPED.set()
    with _SPAWNING:
        for pool in _SHARED.values():
            pool.shutdown(wait=False, cancel_futures=True)


def _new_pool(workers: int) -> ProcessPoolExecutor:
    # spawn: a fresh interpreter per worker, no fork of this process's threads or locks
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))


#: Held while a pool spawns processes or the shared one is replaced: the stages of a
#: ``gatetwin run`` group submit from threads of their own (the environment a pool spawns
#: with is process-wide).
_SPAWNING = threading.RLock()
#: Set by :func:`stop_shared_pools`: no task is run any more.
_STOPPED = threading.Event()


def _replace_shared(workers: int, broken: ProcessPoolExecutor) -> None:
    with _SPAWNING:
        if _SHARED.get(workers) is broken:
            broken.shutdown(wait=False, cancel_futures=True)
            _SHARED[workers] = _new_pool(workers)


def _pool(task: Task, jobs: list[Any], crashed: Crashed,
          workers: int) -> Iterator[tuple[int, Any]]:  # fmt: skip
    if workers not in _SHARED:
        with _new_pool(min(workers, len(jobs))) as pool:
            yield from _collected(pool, _submit(pool, task, jobs), jobs, crashed, workers)
        return
    pool = _SHARED[workers]
    try:
        futures = _submit(pool, task, jobs)
    except BrokenProcessPool:  # a process of the shared pool died since the last call
        _replace_shared(workers, pool)
        pool = _SHARED[workers]
        futures = _submit(pool, task, jobs)
    yield from _collected(pool, futures, jobs, crashed, workers)


def _submit(pool: ProcessPoolExecutor, task: Task, jobs: list[Any]) -> dict[Any, int]:
    with _SPAWNING, spawn_environment(POOL_THREADS):  # the pool spawns its processes on submit
        return {pool.submit(task, job): k for k, job in enumerate(jobs)}


def _collected(pool: ProcessPoolExecutor, futures: dict[Any, int], jobs: list[Any],
               crashed: Crashed, workers: int) -> Iterator[tuple[int, Any]]:  # fmt: skip
    for future in as_completed(futures):
        k = futures[future]
        try:
            yield k, future.result()
        except Exception as exc:  # a dead worker fails its job only
            if isinstance(exc, BrokenProcessPool):
                _replace_shared(workers, pool)
            yield k, crashed(jobs[k], exc)


def connect(address: str, timeout_s: float) -> Any:
    """A ``distributed.Client`` on ``address`` with at least one worker, or one clear error."""
    try:
        from distributed import Client
    except ImportError:
        raise GatetwinError(
            "--scheduler needs dask.distributed, which is not installed; install it with "
            "pip install 'gatetwin[fleet]'"
        ) from None
    from distributed.comm import resolve_address

    try:
        # an address that does not parse or resolve is refused before a Client exists: a
        # Client that failed half-way blocks the interpreter's exit for 40 s closing itself
        resolve_address(address)
        client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise GatetwinError(
            f"--scheduler {address}: cannot reach the dask scheduler ({' '.join(str(exc).split())})"
        ) from None
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except TimeoutError:
        client.close()
        raise GatetwinError(
            f"--scheduler {address}: the scheduler has no worker after {timeout_s:g} s; start "
            f"one with: dask worker {address}"
        ) from None
    return client


def _quiet_dask_logs() -> contextlib.ExitStack:
    """Silence dask's own log handlers (on stderr) until the returned stack is closed.

    A lost scheduler makes the client log its reconnection attempts; beside gatetwin's one
    line they are noise, and what went wrong is each lost job's reason instead. dask gives
    several of its loggers a handler of their own, so the handlers are silenced, not one
    logger."""
    stack = contextlib.ExitStack()
    loggers = [lg for name, lg in logging.root.manager.loggerDict.items()
               if name.partition(".")[0] == "distributed"
               and isinstance(lg, logging.Logger)]  # fmt: skip
    for handler in {h for lg in loggers for h in lg.handlers}:
        stack.callback(handler.setLevel, handler.level)
        handler.setLevel(logging.CRITICAL + 1)
    return stack


def _dask(task: Task, jobs: list[Any], crashed: Crashed, address: str,
          timeout_s: float) -> Iterator[tuple[int, Any]]:  # fmt: skip
    from distributed import as_completed as dask_completed

    client = connect(address, timeout_s)
    quiet = _quiet_dask_logs()
    try:
        futures = {}
        for k, job in enumerate(jobs):
            key = f"gatetwin-{task.__name__}-{k}-{os.getpid()}-{id(job)}"
            future = client.submit(task, job, pure=False, key=key)
            futures[future.key] = (future, k)
        pending = dask_completed([f for f, _ in futures.values()], loop=client.loop)
        alone_since = None  # when the scheduler was first seen without a worker
        while not pending.is_empty():
            done = pending.next_batch(block=False)
            for future in done:
                k = futures.pop(future.key)[1]
                try:
                    yield k, future.result()
                except Exception as exc:  # a lost worker fails its job only
                    yield k, crashed(jobs[k], exc)
                future.release()
            if done:
                continue
            # nothing finished: wait a little, and give up on the jobs left once the
            # scheduler has had no worker for as long as the first one was waited for
            time.sleep(min(WORKER_POLL_S, timeout_s))
            if client.scheduler_info().get("workers"):
                alone_since = None
            elif alone_since is None:
                alone_since = time.monotonic()
            elif time.monotonic() - alone_since > timeout_s:
                lost = GatetwinError(
                    f"the scheduler {address} has had no worker for {timeout_s:g} s; "
                    "the job was lost with its worker"
                )
                for future, k in sorted(futures.values(), key=lambda fk: fk[1]):
                    future.cancel()
                    yield k, crashed(jobs[k], lost)
                return
    finally:
        try:
            client.close()
        finally:
            quiet.close()


def run_tasks(task: Task, jobs: Iterable[Any], settings: FleetSettings, crashed: Crashed,
              progress: Callable[[int, int, Any], None] | None = None) -> list[Any]:  # fmt: skip
    """``task(job)`` for every job, where ``settings`` says; the results in the jobs' order.

    ``task`` and the jobs must pickle (a module-level function, plain data). A job whose
    worker dies gives ``crashed(job, exception)`` instead (pool and dask; serially an
    exception propagates). ``progress(done, total, result)`` follows completion.
    """
    jobs = list(jobs)
    if not jobs:
        return []
    if _STOPPED.is_set():
        raise GatetwinError("the run was interrupted: no more tasks")
    if settings.scheduler:
        stream = _dask(task, jobs, crashed, settings.scheduler, settings.connect_timeout_s)
    elif settings.workers <= 1 or (len(jobs) == 1 and settings.workers not in _SHARED):
        # one job runs here, unless a shared pool is open: a stage of a group runs in a thread
        # of the run, and its work belongs in a process of its own
        stream = _serial(task, jobs, crashed)
    else:
        stream = _pool(task, jobs, crashed, settings.workers)
    results: list[Any] = [None] * len(jobs)
    for done, (k, res) in enumerate(stream, start=1):
        if progress:
            progress(done, len(jobs), res)
        results[k] = res
    return results


def _kept(job: Any, exc: BaseException) -> BaseException:
    """A task that raised or whose worker was lost: kept as the exception."""
    del job
    return exc


def map_tasks(task: Task, jobs: Iterable[Any], settings: FleetSettings | None,
              what: Callable[[Any], str],
              progress: Callable[[int, int, Any], None] | None = None,
              error: type[GatetwinError] = GatetwinError) -> list[Any]:  # fmt: skip
    """:func:`run_tasks` for work that must all succeed: the results in the jobs' order
    (``settings`` ``None``: one after another in this process).

    Raises
    ------
    GatetwinError
        The first job (in order) that was refused, with its own one-line message, or that
        did not come back from its worker (an ``error``; ``what(job)`` names it, as
        "NAME: its task").
    """
    jobs = list(jobs)
    results = run_tasks(task, jobs, settings or FleetSettings(), _kept, progress)
    for job, result in zip(jobs, results, strict=True):
        if isinstance(result, GatetwinError):
            raise result
        if isinstance(result, BaseException):
            text = " ".join(str(result).split()) or type(result).__name__
            raise error(f"{what(job)} did not come back from the worker ({text})")
    return results
