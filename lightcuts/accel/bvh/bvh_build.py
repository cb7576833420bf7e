"""Binned SAH topology builder for the triangle BVH (Wald 2007, as Walter et al. 2008 compare with).

Top-down: at each node the triangles' centroid box is cut along its longest axis into ``BINS`` (16)
equal bins; of the 15 planes between bins the one of least ``SA(L) N(L) + SA(R) N(R)`` (boxes of the
triangles' own boxes on each side) is taken. A node of one triangle is a leaf. Where all centroids
coincide the triangles are halved by index. The result is a topology in the builders' convention
(lightcuts.accel.bvh.bvh, :func:`~lightcuts.accel.bvh.bvh.from_topology`): leaves 0..F-1 hold triangles
0..F-1, internal nodes F..2F-2.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Bins along the split axis.
BINS = 16


@njit(cache=True)
def _area(lo0, lo1, lo2, hi0, hi1, hi2):
    e0, e1, e2 = hi0 - lo0, hi1 - lo1, hi2 - lo2
    return 2.0 * (e0 * e1 + e1 * e2 + e2 * e0)


@njit(cache=True)
def _binned_sah(lo, hi, left, right, prim):
    n = lo.shape[0]
    cen = 0.5 * (lo + hi)
    idx = np.arange(n)
    for i in range(n):
        left[i] = -1
        right[i] = -1
        prim[i] = i
    # Work items: [start, end) of idx, parent node (-1: the root) and side (0 left, 1 right).
    st_start = np.empty(n, np.int64)
    st_end = np.empty(n, np.int64)
    st_parent = np.empty(n, np.int64)
    st_side = np.empty(n, np.int64)
    st_start[0], st_end[0], st_parent[0], st_side[0] = 0, n, -1, 0
    top = 1
    next_internal = n
    root = -1
    bin_lo = np.empty((BINS, 3))
    bin_hi = np.empty((BINS, 3))
    bin_n = np.empty(BINS, np.int64)
    acc_lo = np.empty(3)
    acc_hi = np.empty(3)
    left_area = np.empty(BINS)
    left_n = np.empty(BINS, np.int64)
    while top > 0:
        top -= 1
        s, e, par, side = st_start[top], st_end[top], st_parent[top], st_side[top]
        if e - s == 1:
            node = idx[s]
        else:
            node = next_internal
            next_internal += 1
            prim[node] = -1
            # Centroid box and its longest axis.
            cmin = np.full(3, np.inf)
            cmax = np.full(3, -np.inf)
            for j in range(s, e):
                for a in range(3):
                    c = cen[idx[j], a]
                    cmin[a] = min(cmin[a], c)
                    cmax[a] = max(cmax[a], c)
            axis = 0
            for a in range(1, 3):
                if cmax[a] - cmin[a] > cmax[axis] - cmin[axis]:
                    axis = a
            extent = cmax[axis] - cmin[axis]
            mid = s + (e - s) // 2
            if extent > 0.0:
                scale = BINS / extent
                bin_lo[:] = np.inf
                bin_hi[:] = -np.inf
                bin_n[:] = 0
                for j in range(s, e):
                    t = idx[j]
                    b = min(BINS - 1, int((cen[t, axis] - cmin[axis]) * scale))
                    bin_n[b] += 1
                    for a in range(3):
                        bin_lo[b, a] = min(bin_lo[b, a], lo[t, a])
                        bin_hi[b, a] = max(bin_hi[b, a], hi[t, a])
                # Sweep from the left: area and count of bins [0, k) for k = 1..BINS-1.
                acc_lo[:] = np.inf
                acc_hi[:] = -np.inf
                cnt = 0
                for k in range(1, BINS):
                    cnt += bin_n[k - 1]
                    for a in range(3):
                        acc_lo[a] = min(acc_lo[a], bin_lo[k - 1, a])
                        acc_hi[a] = max(acc_hi[a], bin_hi[k - 1, a])
                    left_n[k] = cnt
                    left_area[k] = _area(acc_lo[0], acc_lo[1], acc_lo[2], acc_hi[0], acc_hi[1], acc_hi[2]) \
                        if cnt else 0.0
                # Sweep from the right, keeping the cheapest plane (the lowest k on ties).
                acc_lo[:] = np.inf
                acc_hi[:] = -np.inf
                cnt = 0
                best_k = -1
                best = np.inf
                for k in range(BINS - 1, 0, -1):
                    cnt += bin_n[k]
                    for a in range(3):
                        acc_lo[a] = min(acc_lo[a], bin_lo[k, a])
                        acc_hi[a] = max(acc_hi[a], bin_hi[k, a])
                    if cnt == 0 or left_n[k] == 0:
                        continue
                    cost = left_area[k] * left_n[k] + cnt * _area(acc_lo[0], acc_lo[1], acc_lo[2],
                                                                  acc_hi[0], acc_hi[1], acc_hi[2])
                    if cost <= best:
                        best = cost
                        best_k = k
                # Partition idx[s:e] stably: bins < best_k first.
                tmp = idx[s:e].copy()
                w = s
                for j in range(e - s):
                    if min(BINS - 1, int((cen[tmp[j], axis] - cmin[axis]) * scale)) < best_k:
                        idx[w] = tmp[j]
                        w += 1
                for j in range(e - s):
                    if min(BINS - 1, int((cen[tmp[j], axis] - cmin[axis]) * scale)) >= best_k:
                        idx[w] = tmp[j]
                        w += 1
                mid = s + left_n[best_k]
            # Right child pushed first: the left subtree is built first.
            st_start[top], st_end[top], st_parent[top], st_side[top] = mid, e, node, 1
            st_start[top + 1], st_end[top + 1], st_parent[top + 1], st_side[top + 1] = s, mid, node, 0
            top += 2
        if par < 0:
            root = node
        elif side == 0:
            left[par] = node
        else:
            right[par] = node
    return root


def build_binned_sah(lo, hi):
    """Binned-SAH topology over triangle boxes lo, hi (F, 3) float64:
    ``(left, right, prim (2F-1,) int32, root int)``; see the module docstring."""
    lo = np.ascontiguousarray(lo, np.float64)
    hi = np.ascontiguousarray(hi, np.float64)
    n = len(lo)
    m = max(2 * n - 1, 0)
    left, right, prim = (np.empty(m, np.int32) for _ in range(3))
    if n == 0:
        return left, right, prim, -1
    root = _binned_sah(lo, hi, left, right, prim)
    return left, right, prim, int(root)
