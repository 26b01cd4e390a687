"""orbitsim.ensemble.parallel: the ranges a thread count gets, the aligned group arrays, and over_threads' way
of ending (every range has ended before it returns or raises). The lane kernels' bits whatever the thread
count: test_system_lanes.py, test_system_tangent_lanes.py."""

from __future__ import annotations

import threading
import time

import numba
import numpy as np
import pytest

from orbitsim.ensemble.parallel import aligned_zeros, over_threads, thread_ranges


@pytest.mark.parametrize("n_tasks", [0, 1, 2, 7, 17, 18, 400])
@pytest.mark.parametrize("threads", [1, 2, 3, 16])
def test_ranges_cover_the_tasks_once_in_order_and_nearly_evenly(n_tasks: int, threads: int) -> None:
    ranges = thread_ranges(n_tasks, threads)
    assert len(ranges) == max(1, min(threads, n_tasks))
    assert [i for first, last in ranges for i in range(first, last)] == list(range(n_tasks))
    sizes = [last - first for first, last in ranges]
    assert max(sizes) - min(sizes) <= 1


@pytest.mark.parametrize("shape", [(1,), (17, 1344), (3, 4, 5), (2, 512, 61)])
def test_aligned_zeros_start_a_cache_line(shape: tuple[int, ...]) -> None:
    for _ in range(5):  # whatever the allocator hands out
        a = aligned_zeros(shape)
        assert a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous
        assert a.ctypes.data % 64 == 0 and not a.any()


def _recording(calls: list[tuple[int, int, str]]):
    def task(first, last, scale):
        calls.append((int(first), int(last), threading.current_thread().name))
        assert isinstance(first, np.int64) and isinstance(last, np.int64)  # the kernels' argument types
        return scale

    return task


@pytest.mark.parametrize("threads", [1, 2])
def test_each_range_runs_once_and_the_first_on_the_calling_thread(threads: int) -> None:
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        calls: list[tuple[int, int, str]] = []
        over_threads(_recording(calls), 17, 1.0)
        expected = thread_ranges(17, numba.get_num_threads())
    finally:
        numba.set_num_threads(before)
    assert sorted((first, last) for first, last, _ in calls) == expected
    first_range = [name for first, _, name in calls if first == 0]
    assert first_range == [threading.current_thread().name]


@pytest.mark.parametrize("failing", [0, 1], ids=["calling thread's range", "pool range"])
def test_an_error_in_one_range_is_raised_after_the_other_range_ends(failing: int) -> None:
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two Numba threads")
    ended = []

    def task(first, last):
        if first == failing:
            raise ValueError(f"range {failing} failed")
        time.sleep(0.2)
        ended.append(int(first))

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        with pytest.raises(ValueError, match=f"range {failing} failed"):
            over_threads(task, 2)
    finally:
        numba.set_num_threads(before)
    assert ended == [1 - failing]  # the other range had ended: none is left writing after the raise
