r"""Divisive (top-down) builders: ``divisive-3d`` and ``divisive-6d`` (Walter et al. 2008, section 5).

Each node's lights are split, as in the paper, at the middle of the longest axis of the box of their
points (not at the median), in 3D (positions) or 6D (positions plus normals scaled by the
metric's c, so that a spread of normals weighs like a spread of c in space). The metric itself is
not used. Points strictly below the middle go left. A split that leaves one side empty (all points
identical, or a box so thin that its middle rounds onto an end) falls back to an even split by index,
so the tree is always binary with 2N-1 nodes and terminates for any input.

Node ids are depth-first (the root is 0): every subtree owns a contiguous id range.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.trees.registry import BUILDERS


@njit(cache=True)
def _box(pts, s, e, lo, hi):
    """Box of rows s..e-1 of pts into lo, hi."""
    for d in range(pts.shape[1]):
        lo[d] = np.inf
        hi[d] = -np.inf
    for t in range(s, e):
        for d in range(pts.shape[1]):
            v = pts[t, d]
            lo[d] = min(lo[d], v)
            hi[d] = max(hi[d], v)


@njit(cache=True)
def _split(pts, perm, s, e, lo, hi, llo, lhi, rlo, rhi):
    """Split rows s..e-1 (box lo, hi) at the middle of the box's longest axis; return the split row.

    Rows move with their light index in ``perm``, so later scans are sequential. The pass also
    computes both children's boxes into llo, lhi and rlo, rhi: each level reads each point once.
    """
    dims = pts.shape[1]
    axis = 0
    for d in range(dims):
        if hi[d] - lo[d] > hi[axis] - lo[axis]:
            axis = d
        llo[d] = np.inf
        lhi[d] = -np.inf
        rlo[d] = np.inf
        rhi[d] = -np.inf
    mid = 0.5 * (lo[axis] + hi[axis])
    # Rows below mid first (Lomuto): each row is classified once, when the scan reaches it, and
    # joins its side's box. A range with nothing below mid is left in its order, so the fallback
    # below splits it by index.
    i = s
    for t in range(s, e):
        if pts[t, axis] < mid:
            for d in range(dims):
                v = pts[t, d]
                pts[t, d] = pts[i, d]
                pts[i, d] = v
                llo[d] = min(llo[d], v)
                lhi[d] = max(lhi[d], v)
            q = perm[t]
            perm[t] = perm[i]
            perm[i] = q
            i += 1
        else:
            for d in range(dims):
                rlo[d] = min(rlo[d], pts[t, d])
                rhi[d] = max(rhi[d], pts[t, d])
    if i == s or i == e:
        i = s + (e - s) // 2
        _box(pts, s, i, llo, lhi)
        _box(pts, i, e, rlo, rhi)
    return i


@njit(cache=True)
def _build_range(pts, perm, root, s0, e0, lo0, hi0, left, right, light):
    """Subtree over rows s0..e0-1 (box lo0, hi0) with node ids root .. root + 2 (e0 - s0) - 2.

    Ids are depth-first: a node with id r over rows s..e-1 split at row m has children r + 1 and
    r + 2 (m - s), so every subtree owns a fixed id range whatever order the ranges are built in.
    """
    dims = pts.shape[1]
    size = e0 - s0
    # At most one pending sibling per level is on the stack: depth + 1 <= size entries.
    st_node = np.empty(size, np.int64)
    st_s = np.empty(size, np.int64)
    st_e = np.empty(size, np.int64)
    st_lo = np.empty((size, dims))
    st_hi = np.empty((size, dims))
    st_node[0] = root
    st_s[0] = s0
    st_e[0] = e0
    st_lo[0] = lo0
    st_hi[0] = hi0
    top = 1
    llo = np.empty(dims)
    lhi = np.empty(dims)
    rlo = np.empty(dims)
    rhi = np.empty(dims)
    while top > 0:
        top -= 1
        node = st_node[top]
        s = st_s[top]
        e = st_e[top]
        if e - s == 1:
            light[node] = perm[s]
            continue
        m = _split(pts, perm, s, e, st_lo[top], st_hi[top], llo, lhi, rlo, rhi)
        left[node] = node + 1
        right[node] = node + 2 * (m - s)
        st_node[top] = node + 1
        st_s[top] = s
        st_e[top] = m
        st_lo[top] = llo
        st_hi[top] = lhi
        st_node[top + 1] = node + 2 * (m - s)
        st_s[top + 1] = m
        st_e[top + 1] = e
        st_lo[top + 1] = rlo
        st_hi[top + 1] = rhi
        top += 2


@njit(cache=True)
def _divisive(points):
    """Top-down tree over (N, D) points; returns (left, right, light) as (2N-1,) int32 arrays, root 0.

    Serial: a parallel version (serial top levels, then one task per subtree) was no faster on the
    shared 2-core machine this was measured on, and compiles slower.
    """
    n, dims = points.shape
    k = 2 * n - 1
    left = np.full(k, -1, np.int32)
    right = np.full(k, -1, np.int32)
    light = np.full(k, -1, np.int32)
    pts = points.copy()
    perm = np.arange(n)
    lo = np.empty(dims)
    hi = np.empty(dims)
    _box(pts, 0, n, lo, hi)
    _build_range(pts, perm, 0, 0, n, lo, hi, left, right, light)
    return left, right, light


@BUILDERS.register("divisive-3d")
def divisive_3d(position, normal, luminance, light_type, metric, c, seed):
    """Split at the middle of the longest axis of the positions' box (directional: directions')."""
    left, right, light = _divisive(np.ascontiguousarray(position, np.float64))
    return left, right, light, 0


@BUILDERS.register("divisive-6d")
def divisive_6d(position, normal, luminance, light_type, metric, c, seed):
    """Split at the middle of the longest axis in 6D: positions plus normals scaled by c."""
    points = np.concatenate([np.asarray(position, np.float64), c * np.asarray(normal, np.float64)], axis=1)
    left, right, light = _divisive(np.ascontiguousarray(points))
    return left, right, light, 0
