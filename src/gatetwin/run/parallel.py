"""Independent pieces of one ``gatetwin run`` stage on local processes, results in order.

Processes, never threads, for Python work: numba kernels, CasADi solvers and FMU binaries
are not assumed thread-safe, and the GIL serialises pure Python anyway. The processes are
spawned (a fresh interpreter, no fork of this process's threads or locks) and run their
numerical libraries on one thread each (:data:`gatetwin.fleet.execute.POOL_THREADS`): the
processes are the parallelism. A task is a module-level function of one picklable argument;
it computes what it would compute in this process, so the stage's outputs are those of a
run that calls the tasks one after another.
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


def map_in_processes(task: Callable[[Any], Any], jobs: Sequence[Any],
                     workers: int | None = None) -> list[Any]:  # fmt: skip
    """``[task(job) for job in jobs]``, the jobs spread over up to ``workers`` processes
    (default :func:`available_cpus`); in this process when one worker (or one job) is all
    there is. A task's exception is raised here, as the serial loop would raise it."""
    from gatetwin.fleet.execute import POOL_THREADS, spawn_environment

    n = min(workers or available_cpus(), len(jobs))
    if n <= 1:
        return [task(job) for job in jobs]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n, mp_context=context) as pool:
        with spawn_environment(POOL_THREADS):  # the pool spawns its processes on submit
            futures = [pool.submit(task, job) for job in jobs]
        return [future.result() for future in futures]
