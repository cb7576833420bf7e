"""Running ``nogil`` numba kernels on the numba threads from Python threads.

Several passes (divisive subtrees, the tree fill, the forest, the agglomerative builder's searches
and kd-tree builds, the VPL tracer, the render) split their work into independent ranges or tasks.
They run as ``@njit(nogil=True)`` kernels on a thread pool rather than as ``parallel=True`` kernels,
whose compilation costs seconds more on the first call; the result never depends on the thread
count, since every task writes its own outputs. Kernels whose tasks differ in cost (pixels, light
paths) take them one at a time from a shared counter (:func:`next_task`).
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ThreadPoolExecutor, wait

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic


def threads_for(n: int, min_n: int) -> int:
    """The numba thread count for n items, or 1 below ``min_n`` (thread start-up would cost more)."""
    return numba.get_num_threads() if n >= min_n else 1


# One pool for the process, its threads started on first use and kept (the agglomerative builder makes
# over a hundred calls per tree; docs/performance.md has the cost of a call). The calling thread takes
# the first item itself, so the pool needs one thread fewer than numba.
_POOL = ThreadPoolExecutor(max(1, numba.config.NUMBA_NUM_THREADS - 1), thread_name_prefix="lightcuts")


def run_all(fn, items) -> None:
    """``fn(item)`` for every item: the first on this thread, the others on the shared pool. ``fn``
    must not call run_all itself: it would wait for workers that wait for it. Keeping one item on
    the calling thread saves a hand-over per call; a ``prange`` kernel would cost less per call but
    compiles its callees again (docs/performance.md, "Narratives moved from docstrings")."""
    items = list(items)
    futures = [_POOL.submit(fn, item) for item in items[1:]]
    try:
        if items:
            fn(items[0])
    finally:
        wait(futures)
    for f in futures:
        f.result()


def on_threads(kernel, n: int, min_n: int, *args) -> None:
    """``kernel(*args, s, e)`` over [0, n) cut into one equal range per thread (:func:`threads_for`)."""
    threads = threads_for(n, min_n)
    cuts = np.linspace(0, n, threads + 1).astype(np.int64)
    run_all(lambda t: kernel(*args, cuts[t], cuts[t + 1]), range(threads))


def on_counter(kernel, n: int, min_n: int, *args) -> None:
    """``kernel(*args, tasks)`` on every thread (:func:`threads_for` of n items), ``tasks`` a fresh
    shared counter (int64 (1,), zero) from which each takes its work with :func:`next_task`."""
    tasks = np.zeros(1, np.int64)
    run_all(lambda _: kernel(*args, tasks), range(threads_for(n, min_n)))


@intrinsic
def next_task(typingctx, counter):
    """In a kernel: atomically ``counter[0] += 1``, returning the value before (an int64 array of
    one element, zero at the start). Threads that take tasks this way share them dynamically; a
    task's output must not depend on which thread ran it."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None

    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        return builder.atomic_rmw("add", a.data, ir.Constant(ir.IntType(64), 1), "monotonic")

    return types.int64(counter), codegen


def balance(sizes: np.ndarray, threads: int) -> list[np.ndarray]:
    """Task indices per thread, for tasks of the given sizes: largest first, each to the least
    loaded thread (threads left without a task are dropped)."""
    load = [0] * threads
    groups = [[] for _ in range(threads)]
    for j in np.argsort(-np.asarray(sizes), kind="stable"):
        w = load.index(min(load))
        groups[w].append(j)
        load[w] += int(sizes[j])
    return [np.array(g, np.int64) for g in groups if g]


@contextlib.contextmanager
def num_threads(n: int):
    """A block run with ``n`` numba threads (the count before is restored on exit)."""
    before = numba.get_num_threads()
    numba.set_num_threads(n)
    try:
        yield n
    finally:
        numba.set_num_threads(before)
