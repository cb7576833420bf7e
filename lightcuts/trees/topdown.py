r"""The top-down split driver of the divisive light-tree builders (``divisive-3d``, ``divisive-6d``,
``saoh``): one stack loop and one thread driver; each builder supplies only how a node's rows split.

Node ids are depth-first: a node over rows s..e-1 split at row m has children ``node + 1`` and
``node + 2 (m - s)``, so every subtree owns a fixed id range and row range whatever order, or
thread, builds it. The top levels are split on one thread into ranges of at most about N / (4
threads) rows, which are then built on the numba threads (the kernels release the GIL); the tree
does not depend on the thread count.

A builder names its split with :func:`register_split`: a NamedTuple class of its own holds the
arrays its split kernel reads, and the loop's calls of :func:`split_node` and :func:`box_row` on
such a state resolve, when the builder's kernel is compiled, to that builder's kernels (numba
overloads, inlined). A jitted function passed as an argument instead would be a constant that
numba cannot cache.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import overload

from lightcuts.parallel import balance, run_all, threads_for


def split_node(state, perm, s, e, lo, hi):
    """``(m, llo, lhi, rlo, rhi)``: rows s..e-1 (box lo, hi as k-tuples) split at row m, and the
    children's boxes; the builder's split kernel (:func:`register_split`), inside numba only."""
    raise NotImplementedError("split_node is resolved inside numba kernels only")


def box_row(state, b, j):
    """``(lo, hi)``: row j of a (M, 2k) box array as k-tuples; the builder's (:func:`register_split`),
    inside numba only."""
    raise NotImplementedError("box_row is resolved inside numba kernels only")


def register_split(state_class, split, row) -> None:
    """Resolve :func:`split_node` and :func:`box_row` on a ``state_class`` state to the builder's kernels.

    state_class : a NamedTuple class with fields ``head`` and ``tail``, tuples of the arrays (and
        flags, scratch) that ``split`` takes before and after ``(perm, s, e, lo, hi)``
    split : njit ``split(*head, perm, s, e, lo, hi, *tail) -> (m, llo, lhi, rlo, rhi)``
    row : njit ``row(b, j) -> (lo, hi)``
    """
    def ours(state):
        return isinstance(state, types.BaseNamedTuple) and state.instance_class is state_class

    @overload(split_node, inline="always")
    def _split_node(state, perm, s, e, lo, hi):
        if ours(state):
            return lambda state, perm, s, e, lo, hi: split(*state.head, perm, s, e, lo, hi, *state.tail)

    @overload(box_row, inline="always")
    def _box_row(state, b, j):
        if ours(state):
            return lambda state, b, j: row(b, j)


@njit(cache=True)
def visit(st_range, st_box, top, node, s, e, lo, hi, perm, left, right, light):
    """Node ``node`` over rows s..e-1 (box lo, hi: k-tuples, ``st_box`` rows 2k wide): a leaf is
    written at once, a larger range goes on the stack at ``top``. Returns the new stack size."""
    if e - s == 1:
        left[node] = -1
        right[node] = -1
        light[node] = perm[s]
        return top
    st_range[top, 0] = node
    st_range[top, 1] = s
    st_range[top, 2] = e
    k = len(lo)
    for d in range(k):
        st_box[top, d] = lo[d]
        st_box[top, k + d] = hi[d]
    return top + 1


# Not cached itself: compiled into, and cached with, each builder's ``_subtrees`` kernel, so that
# an edit of a builder's split invalidates it (numba's cache checks only a kernel's own file; after
# an edit of this file, delete the builders' caches).
@njit
def split_subtrees(state, perm, tasks, boxes, cut, left, right, light):
    """Build the subtrees of ``tasks`` (rows: node, s, e over rows s..e-1; ``boxes`` rows: their lo,
    hi) into left, right, light, each node split by the builder of ``state`` (:func:`split_node`).

    Ranges of 2..cut rows (cut > 0) are not split but returned, as (tasks, boxes), for another call.
    """
    size = 1
    rows = 0
    for j in range(tasks.shape[0]):
        size = max(size, tasks[j, 2] - tasks[j, 1])
        rows += tasks[j, 2] - tasks[j, 1]
    w = boxes.shape[1]
    # Explicit stack, the left child on top: at most one pending right sibling per level, so
    # depth + 1 <= size entries of (node, s, e) and box (lo, hi).
    st_range = np.empty((size, 3), np.int64)
    st_box = np.empty((size, w))
    # Returned ranges are disjoint, of 2 rows or more.
    out_range = np.empty((rows // 2 if cut > 0 else 0, 3), np.int64)
    out_box = np.empty((out_range.shape[0], w))
    n_out = 0
    for j in range(tasks.shape[0]):
        lo, hi = box_row(state, boxes, j)
        # np.int64(0), not 0: a literal would compile a second visit.
        top = visit(st_range, st_box, np.int64(0), tasks[j, 0], tasks[j, 1], tasks[j, 2], lo, hi, perm,
                    left, right, light)
        while top > 0:
            top -= 1
            node = st_range[top, 0]
            s = st_range[top, 1]
            e = st_range[top, 2]
            if e - s <= cut:
                for d in range(3):
                    out_range[n_out, d] = st_range[top, d]
                for d in range(w):
                    out_box[n_out, d] = st_box[top, d]
                n_out += 1
                continue
            lo, hi = box_row(state, st_box, top)
            m, llo, lhi, rlo, rhi = split_node(state, perm, s, e, lo, hi)
            a = node + 1
            b = node + 2 * (m - s)
            left[node] = a
            right[node] = b
            light[node] = -1
            top = visit(st_range, st_box, top, b, m, e, rlo, rhi, perm, left, right, light)
            top = visit(st_range, st_box, top, a, s, m, llo, lhi, perm, left, right, light)
    return out_range[:n_out], out_box[:n_out]


def top_down(n: int, subtrees, box: np.ndarray, parallel_min: int):
    """A top-down tree over n rows: ``(left, right, light)``, (2N-1,) int32 arrays, root 0.

    subtrees : ``subtrees(tasks, boxes, cut, left, right, light) -> (tasks, boxes)``, the builder's
        cached kernel around :func:`split_subtrees`; box : (1, 2k) the rows' box (lo, hi);
        parallel_min : below this many rows the build runs on one thread.
    With more than one numba thread the top levels are split serially, then the subtrees below
    them are built on the threads.
    """
    k = 2 * n - 1
    left = np.empty(k, np.int32)
    right = np.empty(k, np.int32)
    light = np.empty(k, np.int32)
    threads = threads_for(n, parallel_min)
    root = np.array([[0, 0, n]], np.int64)
    # About 4 subtrees per thread or more, for balance: splits need not be at the median.
    cut = n // (4 * threads) if threads > 1 else 0
    tasks, boxes = subtrees(root, box, cut, left, right, light)
    if len(tasks):
        run_all(lambda g: subtrees(tasks[g], boxes[g], 0, left, right, light),
                balance(tasks[:, 2] - tasks[:, 1], threads))
    return left, right, light
