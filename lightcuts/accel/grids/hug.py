"""The hierarchy of uniform grids (HUG; Cazals, Drettakis and Puech, Eurographics 1995).

Bottom-up and without a parameter to tune:

1. Filter (2.1): an object is a triangle's box, its length the box diagonal. The filter
   f_1 < ... < f_{m+1} cuts the sorted lengths into ``levels`` slices of equal counts (the
   histogram of the lengths read at its quantiles); an object goes to the level found by binary
   search of its length. Ties merge slices, so there may be fewer levels.
2. Clustering (2.2) per level k below the top: :func:`isolate` splits a set along one axis where the
   gap between its sorted projections and the running right end is >= delta_k = alpha * fbar_k,
   fbar_k = (f_k + f_{k+1}) / 2 (the paper's average length of the level); :func:`cluster3d` applies
   it along x, y, z in turn until a set is stable on all three axes, with the paper's double stack.
   The work of its sorts, sum N_i log N_i / (n log n), is reported (the paper measured 3 to 5).
3. A grid per cluster by the cube-root criterion (lightcuts.accel.grids.grids), and the grid World over the
   top level's objects and every cluster (2 n voxels: it holds the largest object).
4. The hierarchy (2.3, Fig. 9), level by level from the larger sizes down: each cluster's grid goes
   into the finest grid already placed that contains it, and is referenced by every voxel of that
   grid it overlaps.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lightcuts.accel.grids.grid_build import scene_box
from lightcuts.accel.grids.grids import voxel_range, assemble, cube_root_res, fill_grids, grid_inv

#: The paper's defaults: three filter levels, alpha = 0.01.
LEVELS = 3
ALPHA = 0.01


def length_filter(lengths: np.ndarray, levels: int = LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """The filter f (m + 1,) float64, strictly increasing, d_inf in [f_1, f_2), d_sup in [f_m, f_{m+1}),
    cut at the ``levels``-quantiles of ``lengths`` (F,), and each object's level (F,) int64 by binary search."""
    s = np.sort(lengths)
    n = len(s)
    cuts = [s[0]] + [s[(n * k) // levels] for k in range(1, levels)]
    top = s[-1] * (1 + 1e-9) + 1e-300   # so that d_sup < f_{m+1}
    f = np.unique(np.array(cuts + [top]))
    lev = np.searchsorted(f, lengths, side="right") - 1
    return f, np.clip(lev, 0, len(f) - 2).astype(np.int64)


@njit(cache=True)
def _isolate(idx, a, b, lo, hi, axis, delta, cuts):
    """Isolate (2.2.2) on idx[a:b]: sort it by left ends of the projections on ``axis``, sweep with the
    running right end, and write the starts of the pieces after the first into ``cuts``; returns their
    count. Two neighbours are in one piece when the gap is < delta."""
    keys = np.empty(b - a)
    for i in range(a, b):
        keys[i - a] = lo[idx[i], axis]
    order = np.argsort(keys, kind="mergesort")
    part = idx[a:b][order]
    idx[a:b] = part
    k = 0
    right = hi[idx[a], axis]
    for i in range(a + 1, b):
        f = idx[i]
        if lo[f, axis] - right >= delta:
            cuts[k] = i
            k += 1
        right = max(right, hi[f, axis])
    return k


def isolate(lo1: np.ndarray, hi1: np.ndarray, delta: float) -> np.ndarray:
    """Pieces of segments [lo1, hi1] (n,) by :func:`_isolate`: (n,) int64 piece label of each segment."""
    n = len(lo1)
    lo = np.zeros((n, 3))
    hi = np.zeros((n, 3))
    lo[:, 0], hi[:, 0] = lo1, hi1
    idx = np.arange(n, dtype=np.int64)
    cuts = np.empty(max(n, 1), np.int64)
    k = _isolate(idx, 0, n, lo, hi, 0, float(delta), cuts) if n else 0
    label = np.empty(n, np.int64)
    label[idx] = np.searchsorted(cuts[:k], np.arange(n), side="right")
    return label


@njit(cache=True, inline="always")
def _put(st, i, a, b, d, stable):
    st[i, 0] = a
    st[i, 1] = b
    st[i, 2] = d
    st[i, 3] = stable


@njit(cache=True)
def cluster3d(idx, lo, hi, delta):
    """Cluster3d (2.2.2) over the objects idx (n,) (reordered in place) with boxes lo, hi (F, 3).

    The double stack is one array of n records (start, end, last axis, stable axes): potential
    clusters grow from the bottom, clusters from the top. A popped set is isolated along the next
    axis; left whole it gains a stable axis, split its pieces have one (that axis); stable on three
    axes (or a single object) it is a cluster. Returns (starts (c,), ends (c,)) of the clusters in idx
    and the work sum N_i log N_i of the sorts."""
    n = len(idx)
    st = np.empty((max(n, 1), 4), np.int64)
    cuts = np.empty(max(n, 1), np.int64)
    bottom = 0
    top = n
    work = 0.0
    if n:
        _put(st, 0, 0, n, -1, 0)
        bottom = 1
    while bottom > 0:
        bottom -= 1
        a, b, d, stable = st[bottom, 0], st[bottom, 1], st[bottom, 2], st[bottom, 3]
        if b - a == 1:
            top -= 1
            _put(st, top, a, b, d, 3)
            continue
        axis = (d + 1) % 3
        work += (b - a) * math.log(b - a)
        k = _isolate(idx, a, b, lo, hi, axis, delta, cuts)
        if k == 0:
            if stable + 1 == 3:
                top -= 1
                _put(st, top, a, b, axis, 3)
            else:
                _put(st, bottom, a, b, axis, stable + 1)
                bottom += 1
        else:
            s = a
            for j in range(k + 1):
                e = cuts[j] if j < k else b
                _put(st, bottom, s, e, axis, 1)
                bottom += 1
                s = e
    starts = np.empty(n - top, np.int64)
    ends = np.empty(n - top, np.int64)
    for i in range(top, n):
        starts[n - 1 - i] = st[i, 0]
        ends[n - 1 - i] = st[i, 1]
    return starts, ends, work


@njit(cache=True)
def _insert(glo, ghi, gres, voxel0):
    """Fig. 9: grids 1.. (in order) go into the finest grid placed before them that contains them
    (descending from grid 0 through the sub-grids of the voxel holding their low corner) and are
    referenced by every voxel of that grid they overlap. Returns (voxel (S,), grid (S,)) pairs in
    insertion order and each grid's parent (G,)."""
    G = glo.shape[0]
    head = np.full(voxel0[G], -1, np.int64)
    cap = 16
    nxt = np.empty(cap, np.int64)
    pv = np.empty(cap, np.int64)
    pg = np.empty(cap, np.int64)
    npairs = 0
    parent = np.full(G, -1, np.int64)
    for g in range(1, G):
        P = 0
        while True:
            inv = grid_inv(glo[P], ghi[P], gres[P])
            ix, _ = voxel_range(glo[g, 0], glo[g, 0], glo[P, 0], gres[P, 0], inv[0])
            iy, _ = voxel_range(glo[g, 1], glo[g, 1], glo[P, 1], gres[P, 1], inv[1])
            iz, _ = voxel_range(glo[g, 2], glo[g, 2], glo[P, 2], gres[P, 2], inv[2])
            v = voxel0[P] + ix + gres[P, 0] * (iy + gres[P, 1] * iz)
            found = -1
            p = head[v]
            while p >= 0:
                c = pg[p]
                if (glo[c, 0] <= glo[g, 0] and glo[c, 1] <= glo[g, 1] and glo[c, 2] <= glo[g, 2]
                        and ghi[g, 0] <= ghi[c, 0] and ghi[g, 1] <= ghi[c, 1] and ghi[g, 2] <= ghi[c, 2]):
                    found = c
                    break
                p = nxt[p]
            if found < 0:
                break
            P = found
        parent[g] = P
        inv = grid_inv(glo[P], ghi[P], gres[P])
        x0, x1 = voxel_range(glo[g, 0], ghi[g, 0], glo[P, 0], gres[P, 0], inv[0])
        y0, y1 = voxel_range(glo[g, 1], ghi[g, 1], glo[P, 1], gres[P, 1], inv[1])
        z0, z1 = voxel_range(glo[g, 2], ghi[g, 2], glo[P, 2], gres[P, 2], inv[2])
        for iz in range(z0, z1 + 1):
            for iy in range(y0, y1 + 1):
                for ix in range(x0, x1 + 1):
                    if npairs == cap:
                        cap *= 2
                        nxt = np.concatenate((nxt, np.empty(cap - npairs, np.int64)))
                        pv = np.concatenate((pv, np.empty(cap - npairs, np.int64)))
                        pg = np.concatenate((pg, np.empty(cap - npairs, np.int64)))
                    v = voxel0[P] + ix + gres[P, 0] * (iy + gres[P, 1] * iz)
                    pv[npairs] = v
                    pg[npairs] = g
                    nxt[npairs] = head[v]
                    head[v] = npairs
                    npairs += 1
    return pv[:npairs], pg[:npairs], parent


def build_hug(blo: np.ndarray, bhi: np.ndarray, levels: int = LEVELS, alpha: float = ALPHA):
    """The HUG over the boxes lo, hi (F, 3) float64: (GridForest, info dict) with the filter, the
    clustering ratio, the clusters and grids per level."""
    n = len(blo)
    lo, hi = scene_box(blo, bhi)
    if n == 0:
        res = np.ones((1, 3), np.int64)
        f = assemble(lo[None], hi[None], res, np.zeros(1), np.zeros(1, np.int64), np.zeros(0, np.int32),
                     np.zeros(1, np.int64), np.zeros(0, np.int32), 0, "hug")
        return f, {"filter": [], "levels": 0, "clustering_ratio": 0.0, "grids_per_level": [1], "clusters_per_level": []}
    lengths = np.linalg.norm(bhi - blo, axis=1)
    filt, lev = length_filter(lengths, levels)
    m = len(filt) - 1
    top = m - 1
    # Grids: World first, then the clusters of the levels from the top down.
    g_lo, g_hi, g_res, g_level, members = [lo], [hi], [], [top], []
    world_items = np.flatnonzero(lev == top)
    g_res.append(cube_root_res(lo, hi, 2 * len(world_items)))
    members.append(world_items)
    work = 0.0
    clusters_per_level = [0] * m
    clusters_per_level[top] = 1
    for k in range(top - 1, -1, -1):
        idx = np.flatnonzero(lev == k).astype(np.int64)
        if len(idx) == 0:
            continue
        delta = alpha * 0.5 * (filt[k] + filt[k + 1])
        starts, ends, w = cluster3d(idx, blo, bhi, delta)
        work += w
        clusters_per_level[k] = len(starts)
        for s, e in zip(starts, ends):
            it = idx[s:e]
            clo, chi = blo[it].min(axis=0), bhi[it].max(axis=0)
            g_lo.append(clo)
            g_hi.append(chi)
            g_res.append(cube_root_res(clo, chi, len(it)))
            g_level.append(k)
            members.append(it)
    g_lo, g_hi, g_res = np.array(g_lo), np.array(g_hi), np.array(g_res, np.int64)
    item_start = np.zeros(len(members) + 1, np.int64)
    np.cumsum([len(x) for x in members], out=item_start[1:])
    voxel0, off, refs = fill_grids(g_lo, g_hi, g_res, item_start, np.concatenate(members).astype(np.int64), blo, bhi)
    pv, pg, _ = _insert(g_lo, g_hi, g_res, voxel0)
    order = np.argsort(pv, kind="stable")
    counts_subs = np.bincount(pv, minlength=int(voxel0[-1]))
    forest = assemble(g_lo, g_hi, g_res, g_level, np.diff(off), refs, counts_subs, pg[order], n, "hug")
    nlogn = n * math.log(n) if n > 1 else 1.0
    info = {"filter": [float(x) for x in filt], "levels": m, "clustering_ratio": work / nlogn,
            "clusters_per_level": clusters_per_level,
            "grids_per_level": [int((np.asarray(g_level) == k).sum()) for k in range(m)]}
    return forest, info
