"""``gatetwin.run.parallel``: a stage's independent pieces on local processes, in order."""

from __future__ import annotations

import math
import operator
import os

import pytest

from gatetwin.run.parallel import available_cpus, map_in_processes


def test_results_come_back_in_the_jobs_order_from_other_processes() -> None:
    jobs = [16.0, 1.0, 81.0, 4.0, 9.0]
    assert map_in_processes(math.sqrt, jobs, workers=2) == [4.0, 1.0, 9.0, 2.0, 3.0]
    pids = map_in_processes(operator.call, [os.getpid] * 4, workers=2)
    assert os.getpid() not in pids and 1 <= len(set(pids)) <= 2


def test_one_worker_or_one_job_runs_here() -> None:
    assert map_in_processes(operator.call, [os.getpid], workers=2) == [os.getpid()]
    assert map_in_processes(operator.call, [os.getpid] * 2, workers=1) == [os.getpid()] * 2
    assert map_in_processes(math.sqrt, []) == []


def test_a_task_error_is_raised_here_as_the_serial_loop_raises_it() -> None:
    with pytest.raises(ValueError, match="math domain error"):
        map_in_processes(math.sqrt, [4.0, -1.0], workers=2)


def test_available_cpus_is_a_positive_count() -> None:
    assert 1 <= available_cpus() <= (os.cpu_count() or 1)
