"""lightcuts.parallel: the thread pool's run_all and the atomic task counter of kernels."""

import threading

import numpy as np
import pytest
from numba import njit

from lightcuts.parallel import next_task, run_all


@njit(cache=True, nogil=True)
def _take_tasks(tasks, n, hits, spin):
    """Take tasks until none is left; each task adds 1 to its own cell (a plain add: a task taken
    twice shows as 2) after a little work, so that the threads interleave."""
    while True:
        c = next_task(tasks)
        if c >= n:
            break
        x = 0.0
        for i in range(spin):
            x += np.sqrt(i + c)
        hits[c] += 1 if x >= 0.0 else 2


def test_next_task_hands_out_every_task_exactly_once():
    n = 200_000
    for _ in range(3):
        tasks = np.zeros(1, np.int64)
        hits = np.zeros(n, np.int64)
        run_all(lambda _: _take_tasks(tasks, n, hits, 8), range(2))
        assert (hits == 1).all()
        assert tasks[0] >= n + 2   # each thread took one past the end, then stopped


def test_run_all_runs_every_item_and_raises_after_all():
    seen = []
    lock = threading.Lock()

    def fn(item):
        with lock:
            seen.append(item)

    def fail(item):
        raise ValueError(f"item {item}")

    for bad in (3, 0):   # raised on the pool, and on the calling thread
        seen.clear()
        with pytest.raises(ValueError, match="item"):
            run_all(lambda item: fn(item) if item != bad else (fn(-1), fail(item)), range(6))
        assert sorted(seen) == [-1] + [i for i in range(6) if i != bad]
    seen.clear()
    run_all(fn, [5])
    run_all(fn, [])
    assert seen == [5]
