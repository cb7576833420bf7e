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

Node ids are depth-first (the root is 0, a left child directly follows its parent), as the
top-down driver shared with ``saoh`` numbers them (:mod:`lightcuts.trees.topdown`): every subtree
owns a contiguous id range, which lets subtrees be built on several threads with the same result,
and children have larger ids than their parent, so ``build_tree`` fills the nodes in decreasing id
order, sequentially in memory.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import EMPTY_HI, EMPTY_LO, box_grow
from lightcuts.trees.registry import BUILDERS
from lightcuts.trees.topdown import register_split, split_subtrees, top_down

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
def _box_row(b, j):
    """Row j of a (M, 12) box array as (lo, hi) 6-tuples."""
    return ((b[j, 0], b[j, 1], b[j, 2], b[j, 3], b[j, 4], b[j, 5]),
            (b[j, 6], b[j, 7], b[j, 8], b[j, 9], b[j, 10], b[j, 11]))


class _Rows(NamedTuple):
    """What :func:`_split` reads besides (perm, s, e, lo, hi): the (N, 6) points."""
    head: tuple
    tail: tuple


register_split(_Rows, _split, _box_row)


@njit(cache=True, nogil=True)
def _subtrees(pts, perm, tasks, boxes, cut, left, right, light):
    """The subtrees of ``tasks`` over rows of the (N, 6) points, split by :func:`_split`
    (:func:`~lightcuts.trees.topdown.split_subtrees`)."""
    return split_subtrees(_Rows((pts,), ()), perm, tasks, boxes, cut, left, right, light)


def _divisive(position, normal, c):
    """Top-down tree over the 6D points (position, c * normal), (N, 3) float64 each: (left, right,
    light) as (2N-1,) int32 arrays, root 0 (:func:`~lightcuts.trees.topdown.top_down`)."""
    pts, perm, box = _points(position, normal, c)
    return top_down(position.shape[0], lambda *a: _subtrees(pts, perm, *a), box, _PARALLEL_MIN)


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
