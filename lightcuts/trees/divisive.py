r"""Divisive (top-down) builders: ``divisive-3d`` and ``divisive-6d`` (Walter et al. 2008, section 5).

Each node's lights are split, as in the paper, at the middle of the longest axis of the box of their
points (not at the median), in 3D (positions) or 6D (positions plus normals scaled by the
metric's c, so that a spread of normals weighs like a spread of c in space). The metric itself is
not used. Points strictly below the middle go left. A split that leaves one side empty (all points
identical, or a box so thin that its middle rounds onto an end) falls back to an even split by index,
so the tree is always binary with 2N-1 nodes and terminates for any input.

Both builders run one kernel on 6D points ``(position, c * normal)``; divisive-3d passes c = 0.
Zero normal columns never have the strictly longest extent (ties go to the lowest axis), so that is
exactly the 3D split, and one compiled kernel serves both.

Node ids are depth-first (the root is 0, a left child directly follows its parent): every subtree
owns a contiguous id range, which lets subtrees be built on several threads with the same result,
and children have larger ids than their parent, so ``build_tree`` fills the nodes in decreasing id
order, sequentially in memory.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import EMPTY_HI, EMPTY_LO, box_grow
from lightcuts.parallel import balance, run_all, threads_for
from lightcuts.trees.registry import BUILDERS

# Below this many lights the build runs on one thread (thread start-up would cost more).
_PARALLEL_MIN = 20000
# The empty 6D box: min/max accumulators before the first point.
_EMPTY_LO = EMPTY_LO + EMPTY_LO
_EMPTY_HI = EMPTY_HI + EMPTY_HI


# The kernels keep 6D points and boxes in 6-tuples rather than small arrays: tuples stay in
# registers, while a store into the point array could alias a small array and force a memory
# round trip per coordinate (docs/performance.md, "tree build, fill and divisive partition").

@njit(cache=True)
def _row(pts, t):
    """Row t of the (N, 6) points as a 6-tuple."""
    return pts[t, 0], pts[t, 1], pts[t, 2], pts[t, 3], pts[t, 4], pts[t, 5]


@njit(cache=True)
def _grow(lo, hi, v):
    """The 6D box (lo, hi) grown to contain point v (6-tuples): its box of positions and its box of
    scaled normals, each grown by v's half."""
    plo, phi = box_grow(lo[:3], hi[:3], v[:3])
    nlo, nhi = box_grow(lo[3:], hi[3:], v[3:])
    return plo + nlo, phi + nhi


@njit(cache=True)
def _box(pts, s, e):
    """Box (lo, hi) of rows s..e-1 of pts."""
    lo = _EMPTY_LO
    hi = _EMPTY_HI
    for t in range(s, e):
        lo, hi = _grow(lo, hi, _row(pts, t))
    return lo, hi


@njit(cache=True)
def _split(pts, perm, s, e, lo, hi):
    """Split rows s..e-1 (box lo, hi) at the middle of the box's longest axis.

    Returns the split row m and the boxes of rows s..m-1 and m..e-1. Rows move with their light
    index in ``perm``, so later scans are sequential, and one pass both partitions and bounds the
    children: each level reads each point once.
    """
    axis = 0
    ext = hi[0] - lo[0]
    for d in range(1, 6):
        if hi[d] - lo[d] > ext:
            axis = d
            ext = hi[d] - lo[d]
    mid = 0.5 * (lo[axis] + hi[axis])
    llo = rlo = _EMPTY_LO
    lhi = rhi = _EMPTY_HI
    # Rows below mid first (Lomuto): each row is classified once, when the scan reaches it, and
    # joins its side's box. A range with nothing below mid is left in its order, so the fallback
    # below splits it by index. Row order matters only to that fallback, but there it decides the
    # clusters, so a faster partition with another order would change trees over duplicate points.
    i = s
    for t in range(s, e):
        v = _row(pts, t)
        if pts[t, axis] < mid:
            for d in range(6):
                pts[t, d] = pts[i, d]
                pts[i, d] = v[d]
            q = perm[t]
            perm[t] = perm[i]
            perm[i] = q
            i += 1
            llo, lhi = _grow(llo, lhi, v)
        else:
            rlo, rhi = _grow(rlo, rhi, v)
    if i == s or i == e:
        i = s + (e - s) // 2
        llo, lhi = _box(pts, s, i)
        rlo, rhi = _box(pts, i, e)
    return i, llo, lhi, rlo, rhi


@njit(cache=True)
def _points(position, normal, c):
    """The (N, 6) points (position, c * normal), their box as a (1, 12) row (lo, hi), and the
    identity (N,) int32 light order."""
    n = position.shape[0]
    pts = np.empty((n, 6))
    perm = np.empty(n, np.int32)
    lo = _EMPTY_LO
    hi = _EMPTY_HI
    for t in range(n):
        for d in range(3):
            pts[t, d] = position[t, d]
            pts[t, 3 + d] = c * normal[t, d]
        lo, hi = _grow(lo, hi, _row(pts, t))
        perm[t] = t
    box = np.empty((1, 12))
    for d in range(6):
        box[0, d] = lo[d]
        box[0, 6 + d] = hi[d]
    return pts, perm, box


@njit(cache=True)
def visit(st_range, st_box, top, node, s, e, lo, hi, perm, left, right, light):
    """Node ``node`` over rows s..e-1 (box lo, hi: k-tuples, ``st_box`` rows 2k wide): a leaf is
    written at once, a larger range goes on the stack at ``top``. Returns the new stack size.
    (Shared with lightcuts.trees.saoh, whose boxes are 3D.)"""
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


@njit(cache=True, nogil=True)
def _subtrees(pts, perm, tasks, boxes, cut, left, right, light):
    """Build the subtrees of ``tasks`` (rows: node, s, e over rows s..e-1 of pts; ``boxes`` rows:
    their lo, hi) into left, right, light.

    A node with id r over rows s..e-1 split at row m has children r + 1 and r + 2 (m - s), so each
    subtree owns a fixed id range and row range whatever order, or thread, builds it. Ranges of
    2..cut rows (cut > 0) are not split but returned, as (tasks, boxes), for another call.
    """
    size = 1
    rows = 0
    for j in range(tasks.shape[0]):
        size = max(size, tasks[j, 2] - tasks[j, 1])
        rows += tasks[j, 2] - tasks[j, 1]
    # Explicit stack, the left child on top: at most one pending right sibling per level, so
    # depth + 1 <= size entries of (node, s, e) and box (lo, hi).
    st_range = np.empty((size, 3), np.int64)
    st_box = np.empty((size, 12))
    # Returned ranges are disjoint, of 2 rows or more.
    out_range = np.empty((rows // 2 if cut > 0 else 0, 3), np.int64)
    out_box = np.empty((out_range.shape[0], 12))
    n_out = 0
    for j in range(tasks.shape[0]):
        lo = (boxes[j, 0], boxes[j, 1], boxes[j, 2], boxes[j, 3], boxes[j, 4], boxes[j, 5])
        hi = (boxes[j, 6], boxes[j, 7], boxes[j, 8], boxes[j, 9], boxes[j, 10], boxes[j, 11])
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
                for d in range(12):
                    out_box[n_out, d] = st_box[top, d]
                n_out += 1
                continue
            lo = (st_box[top, 0], st_box[top, 1], st_box[top, 2], st_box[top, 3], st_box[top, 4], st_box[top, 5])
            hi = (st_box[top, 6], st_box[top, 7], st_box[top, 8], st_box[top, 9], st_box[top, 10], st_box[top, 11])
            m, llo, lhi, rlo, rhi = _split(pts, perm, s, e, lo, hi)
            a = node + 1
            b = node + 2 * (m - s)
            left[node] = a
            right[node] = b
            light[node] = -1
            top = visit(st_range, st_box, top, b, m, e, rlo, rhi, perm, left, right, light)
            top = visit(st_range, st_box, top, a, s, m, llo, lhi, perm, left, right, light)
    return out_range[:n_out], out_box[:n_out]


def _divisive(position, normal, c):
    """Top-down tree over the 6D points (position, c * normal), (N, 3) float64 each.

    Returns (left, right, light) as (2N-1,) int32 arrays, root 0. With more than one numba thread
    the top levels are split serially, then the subtrees below them are built on the threads
    (the kernels release the GIL); the tree does not depend on the thread count.
    """
    n = position.shape[0]
    k = 2 * n - 1
    left = np.empty(k, np.int32)
    right = np.empty(k, np.int32)
    light = np.empty(k, np.int32)
    pts, perm, box = _points(position, normal, c)
    threads = threads_for(n, _PARALLEL_MIN)
    root = np.array([[0, 0, n]], np.int64)
    # About 4 subtrees per thread or more, for balance: splits are at the middle, not the median.
    cut = n // (4 * threads) if threads > 1 else 0
    tasks, boxes = _subtrees(pts, perm, root, box, cut, left, right, light)
    if len(tasks):
        run_all(lambda g: _subtrees(pts, perm, tasks[g], boxes[g], 0, left, right, light),
                balance(tasks[:, 2] - tasks[:, 1], threads))
    return left, right, light


@BUILDERS.register("divisive-3d", reads=(), compare_row=4)
def divisive_3d(position, normal, luminance, light_type, metric, c, seed):
    """Split at the middle of the longest axis of the positions' box (directional: directions')."""
    left, right, light = _divisive(np.ascontiguousarray(position, np.float64),
                                   np.ascontiguousarray(normal, np.float64), 0.0)
    return left, right, light, 0


@BUILDERS.register("divisive-6d", reads=("c",), compare_row=3, compare_baseline=True)
def divisive_6d(position, normal, luminance, light_type, metric, c, seed):
    """Split at the middle of the longest axis in 6D: positions plus normals scaled by c."""
    left, right, light = _divisive(np.ascontiguousarray(position, np.float64),
                                   np.ascontiguousarray(normal, np.float64), float(c))
    return left, right, light, 0
