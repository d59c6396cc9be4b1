"""Work of ``gatetwin run`` started on local processes by one stage, collected by a later one.

Processes, never threads, for Python work: numba kernels, CasADi solvers and FMU binaries
are not assumed thread-safe, and the GIL serialises pure Python anyway. The processes are
spawned (a fresh interpreter, no fork of this process's threads or locks) and run their
numerical libraries on one thread each (:data:`gatetwin.fleet.execute.POOL_THREADS`): the
processes are the parallelism. A task is a module-level function of one picklable argument;
it computes what it would compute in this process, so the stages' outputs are those of a
run that calls the tasks one after another, here.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any


def available_cpus() -> int:
    """The CPUs this process may use (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


class Background:
    """Tasks a stage starts on spawned processes and a later stage collects, so that work
    which needs only files already written runs while the stages between go on.

    Parameters
    ----------
    workers : int, optional
        Processes of the pool (default :func:`available_cpus`), started at the first
        :meth:`start`.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or available_cpus()
        self._pool: ProcessPoolExecutor | None = None
        self._futures: dict[str, list[Any]] = {}

    def start(self, key: str, task: Callable[[Any], Any], jobs: Sequence[Any]) -> None:
        """Submit ``task(job)`` for every job, to be collected as ``key``."""
        from gatetwin.fleet.execute import POOL_THREADS, spawn_environment

        if self._pool is None:
            context = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context)
        with spawn_environment(POOL_THREADS):  # the pool spawns its processes on submit
            self._futures[key] = [self._pool.submit(task, job) for job in jobs]

    def started(self, key: str) -> bool:
        """Whether ``key`` was started and not collected yet."""
        return key in self._futures

    def results(self, key: str) -> list[Any]:
        """The results of ``key``'s jobs, in order, once all are done (a task's exception is
        raised here)."""
        return [future.result() for future in self._futures.pop(key)]

    def close(self) -> None:
        """Cancel what has not started, wait for what runs (its files are then complete or
        absent before the caller removes the folder) and end the processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._futures.clear()
