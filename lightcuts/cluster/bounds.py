r"""Cluster bounds and their unions, as small numba helpers shared by every builder.

A light cluster is bounded by the axis-aligned box ``[lo, hi]`` of its lights' positions (world
units; directional lights: of their unit directions), the box ``[nlo, nhi]`` of their unit normals,
from which its normal cone follows (:func:`~lightcuts.cluster.cones.cone_from_box`), and its summed
intensity. The union of two clusters is bounded by the union of their boxes and the sum of their
intensities, which every builder, the kd-tree and the tree fill compute with these helpers.

Corners and points are 3-tuples of float64, which stay in registers. Every helper but
:func:`points_box` is inlined by numba itself (``inline="always"``): a call is then the same
``min``/``max`` as code written out in place, to LLVM too, so loops that vectorised still do, and
the accessors that take arrays cost no reference counting (docs/performance.md, "Shared
union helpers"). Each ``min(a, b)`` keeps its operands in the order ``a`` (the first cluster) then
``b``, which decides the sign of a zero result: trees are the same bit for bit as with the unions
written out.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.cones import cone_from_box

# The empty box: min/max accumulators before the first point.
EMPTY_LO = (np.inf, np.inf, np.inf)
EMPTY_HI = (-np.inf, -np.inf, -np.inf)


@njit(cache=True, inline="always")
def row3(a, k, col):
    """``(a[k, col], a[k, col + 1], a[k, col + 2])``: a corner, point or normal stored in a row."""
    return a[k, col], a[k, col + 1], a[k, col + 2]


@njit(cache=True, inline="always")
def col3(a, row, k):
    """``(a[row, k], a[row + 1, k], a[row + 2, k])``: the same stored in a column (transposed rows)."""
    return a[row, k], a[row + 1, k], a[row + 2, k]


@njit(cache=True, inline="always")
def set_row3(a, k, col, v):
    """``a[k, col:col + 3] = v`` for a 3-tuple v."""
    a[k, col] = v[0]
    a[k, col + 1] = v[1]
    a[k, col + 2] = v[2]


@njit(cache=True, inline="always")
def box_union(lo_a, hi_a, lo_b, hi_b):
    """``(lo, hi)``: the smallest box containing the boxes ``[lo_a, hi_a]`` and ``[lo_b, hi_b]``."""
    return ((min(lo_a[0], lo_b[0]), min(lo_a[1], lo_b[1]), min(lo_a[2], lo_b[2])),
            (max(hi_a[0], hi_b[0]), max(hi_a[1], hi_b[1]), max(hi_a[2], hi_b[2])))


@njit(cache=True, inline="always")
def box_grow(lo, hi, p):
    """``(lo, hi)``: the box ``[lo, hi]`` grown to contain the point p (the union with ``[p, p]``)."""
    return box_union(lo, hi, p, p)


@njit(cache=True, inline="always")
def box_centre(lo, hi):
    """The centre ``(lo + hi) / 2`` of a box, per axis."""
    return 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])


@njit(cache=True, inline="always")
def union_cone(nlo_a, nhi_a, nlo_b, nhi_b):
    """``(ax, ay, az, cos_half)``: the normal cone of A u B, from the union of the clusters' boxes of
    unit normals (:func:`~lightcuts.cluster.cones.cone_from_box`; not the union of their cones)."""
    nlo, nhi = box_union(nlo_a, nhi_a, nlo_b, nhi_b)
    return cone_from_box(nlo[0], nlo[1], nlo[2], nhi[0], nhi[1], nhi[2])


@njit(cache=True)
def points_box(points, s, e):
    """``(lo, hi)``: the box of the rows s..e-1 of the (N, 3) ``points``; the empty box if s >= e.
    One pass over the rows (numpy's column reductions over an (N, 3) array take several times
    longer)."""
    lo = EMPTY_LO
    hi = EMPTY_HI
    for i in range(s, e):
        lo, hi = box_grow(lo, hi, row3(points, i, 0))
    return lo, hi
