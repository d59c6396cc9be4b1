"""``gatetwin.run.parallel``: work started on local processes, collected later, in order."""

from __future__ import annotations

import math
import operator
import os

import pytest

from gatetwin.run.parallel import Background, available_cpus


def test_results_come_back_in_the_jobs_order_from_other_processes() -> None:
    background = Background(workers=2)
    try:
        background.start("roots", math.sqrt, [16.0, 1.0, 81.0, 4.0, 9.0])
        background.start("pids", operator.call, [os.getpid] * 4)
        assert background.started("roots") and not background.started("other")
        assert background.results("roots") == [4.0, 1.0, 9.0, 2.0, 3.0]
        pids = background.results("pids")
        assert os.getpid() not in pids and 1 <= len(set(pids)) <= 2
        assert not background.started("roots")  # collected once
    finally:
        background.close()


def test_a_task_error_is_raised_where_the_results_are_collected() -> None:
    background = Background(workers=2)
    try:
        background.start("roots", math.sqrt, [4.0, -1.0])
        with pytest.raises(ValueError, match="math domain error"):
            background.results("roots")
    finally:
        background.close()


def test_close_without_start_and_twice_is_harmless() -> None:
    background = Background()
    background.close()
    background.start("roots", math.sqrt, [4.0])
    background.close()
    background.close()
    assert not background.started("roots")


def test_available_cpus_is_a_positive_count() -> None:
    assert 1 <= available_cpus() <= (os.cpu_count() or 1)
    assert Background().workers == available_cpus()
