r"""Building the kd-tree (:mod:`lightcuts.cluster.kd_tree`) over the active clusters, and rebuilding it.

A (re)build compacts the active slots, splits the top ``TOP_LEVELS`` levels on one thread, then
handles the 2^TOP_LEVELS subtrees below them independently (their splits, their rows gathered into
the workspace in leaf order, their bounds), in turn (:func:`kd_build`) or on the numba threads
(:func:`kd_build_threaded`), with the same result. Each node splits at the median of its clusters'
centres along the longest side of its cell (the parent's cell cut at the parent's split, as in a
classic kd-tree), so the tree is balanced and needs no pass over a node's points to choose an axis.
Node bounds are exact over the node's clusters, then rounded outwards to float32.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import points_box, set_row3
from lightcuts.cluster.kd_tree import (I_ACTIVE, I_BUILT, I_FIRST_LEAF, I_LEAFSIZE, N_AXIS, N_EMIN, N_HMIN, N_IMIN,
                                       N_LMAX, N_SPLIT, NE_MIN, NH_MIN, NL_MAX, NODE_WIDTH, NORMAL_WIDTH, S_HI, S_I,
                                       S_LO, S_NHI, S_NLO, SLOT_DATA, SLOT_WIDTH, TOP_LEVELS, KdTree, KdWork)
from lightcuts.parallel import on_threads
from lightcuts.rounding import down32, up32

# Traversal stack entries of a search: at most two per level, and the tree has at most ~40 levels.
_STACK = 128
# Smallest (re)build worth starting threads for.
_PARALLEL_BUILD_MIN = 50000


@njit(cache=True)
def _depth(n, leafsize):
    """Levels below the root so that every leaf holds at most ``leafsize`` of n points (median splits)."""
    d = 0
    while (n + (1 << d) - 1) >> d > leafsize:
        d += 1
    return d


@njit(cache=True)
def _rows_f64(m, width):
    """(m, width) float64 rows starting on a 64-byte boundary (numba aligns arrays to 32 bytes)."""
    buf = np.empty(m * width + 8)
    off = ((64 - buf.ctypes.data % 64) % 64) // 8
    return buf[off:off + m * width].reshape((m, width))


@njit(cache=True)
def _rows_f32(m, width):
    """(m, width) float32 rows starting on a 64-byte boundary."""
    buf = np.empty(m * width + 16, np.float32)
    off = ((64 - buf.ctypes.data % 64) % 64) // 4
    return buf[off:off + m * width].reshape((m, width))


@njit(cache=True)
def _select(keys, idx, axis, lo, hi, kth):
    """Partial sort of rows lo..hi (inclusive) of ``keys`` (n, 3) and ``idx`` by ``keys[:, axis]`` so
    that row kth holds its sorted value, smaller-or-equal values before it, larger-or-equal after
    (Wirth's selection with a median-of-three pivot; equal keys split evenly, no quadratic case).
    A swap moves one 24-byte row of keys, in one cache line mostly."""
    while lo < hi:
        a = keys[lo, axis]
        b = keys[kth, axis]
        c = keys[hi, axis]
        if a > b:
            a, b = b, a
        if b > c:
            b = c
            if a > b:
                b = a
        pivot = b
        i = lo
        j = hi
        while i <= j:
            while keys[i, axis] < pivot:
                i += 1
            while pivot < keys[j, axis]:
                j -= 1
            if i <= j:
                for r in range(3):
                    t = keys[i, r]
                    keys[i, r] = keys[j, r]
                    keys[j, r] = t
                t2 = idx[i]
                idx[i] = idx[j]
                idx[j] = t2
                i += 1
                j -= 1
        if j < kth:
            lo = i
        if kth < i:
            hi = j


@njit(cache=True)
def _leaf_bounds(slot_f, s0, s1, node_s, node_n, k):
    """Exact bounds of the slots s0..s1-1 (all active) into node k, rounded outwards to float32."""
    for t in range(3):
        hmin = np.inf
        lmax = -np.inf
        emin = np.inf
        nhmin = np.inf
        nlmax = -np.inf
        nemin = np.inf
        for s in range(s0, s1):
            lo = slot_f[s, S_LO + t]
            hi = slot_f[s, S_HI + t]
            hmin = min(hmin, hi)
            lmax = max(lmax, lo)
            emin = min(emin, hi - lo)
            lo = slot_f[s, S_NLO + t]
            hi = slot_f[s, S_NHI + t]
            nhmin = min(nhmin, hi)
            nlmax = max(nlmax, lo)
            nemin = min(nemin, hi - lo)
        node_s[k, N_HMIN + t] = down32(hmin)
        node_s[k, N_LMAX + t] = up32(lmax)
        node_s[k, N_EMIN + t] = down32(emin)
        node_n[k, NH_MIN + t] = down32(nhmin)
        node_n[k, NL_MAX + t] = up32(nlmax)
        node_n[k, NE_MIN + t] = down32(nemin)
    imin = np.inf
    for s in range(s0, s1):
        imin = min(imin, slot_f[s, S_I])
    node_s[k, N_IMIN] = down32(imin)


@njit(cache=True)
def _split_node(keys, idx, rs, re, cell, node_s, k):
    """Node k's split: the median of its range's centres along the longest side of its cell; sets
    its children's ranges and cells. Touches only node k's range of ``keys`` and ``idx``."""
    s = rs[k]
    e = re[k]
    mid = (s + e) // 2
    axis = np.int64(0)  # not the literal 0: a Literal[int](0) _select would compile too
    for t in range(1, 3):
        if cell[k, 3 + t] - cell[k, t] > cell[k, 3 + axis] - cell[k, axis]:
            axis = t
    if e - s > 1:
        _select(keys, idx, axis, s, e - 1, mid)
    split = keys[mid, axis] if mid < e else cell[k, axis]
    node_s[k, N_AXIS] = axis
    node_s[k, N_SPLIT] = split
    for child in range(2 * k + 1, 2 * k + 3):
        for t in range(6):
            cell[child, t] = cell[k, t]
    cell[2 * k + 1, 3 + axis] = split
    cell[2 * k + 2, axis] = split
    rs[2 * k + 1] = s
    re[2 * k + 1] = mid
    rs[2 * k + 2] = mid
    re[2 * k + 2] = e


@njit(cache=True)
def _join_bounds(node_s, node_n, node_cnt, k):
    """Node k's bounds and count from its two children's (float32 min/max is exact)."""
    a = 2 * k + 1
    b = a + 1
    for t in range(3):
        node_s[k, N_HMIN + t] = min(node_s[a, N_HMIN + t], node_s[b, N_HMIN + t])
        node_s[k, N_LMAX + t] = max(node_s[a, N_LMAX + t], node_s[b, N_LMAX + t])
        node_s[k, N_EMIN + t] = min(node_s[a, N_EMIN + t], node_s[b, N_EMIN + t])
        node_n[k, NH_MIN + t] = min(node_n[a, NH_MIN + t], node_n[b, NH_MIN + t])
        node_n[k, NL_MAX + t] = max(node_n[a, NL_MAX + t], node_n[b, NL_MAX + t])
        node_n[k, NE_MIN + t] = min(node_n[a, NE_MIN + t], node_n[b, NE_MIN + t])
    node_s[k, N_IMIN] = min(node_s[a, N_IMIN], node_s[b, N_IMIN])
    node_cnt[k] = node_cnt[a] + node_cnt[b]


@njit(cache=True)
def _levels(info):
    """``(top, below)`` of the tree of the last (re)build: the levels split before the rest is cut
    into 2^top independent subtrees, and the levels of each subtree below its root."""
    depth = _depth(info[I_BUILT], info[I_LEAFSIZE])
    top = min(depth, TOP_LEVELS)
    return top, depth - top


@njit(cache=True)
def kd_build_start(kd, work):
    """First part of a (re)build: compact the active slots, split the top levels of the tree.

    Returns ``(rs, re, cell)``, each node's slot range and cell, for :func:`kd_build_subtrees`.
    """
    slot_f, slot_id, node_s, info = kd.slot_f, kd.slot_id, kd.node_s, kd.info
    keys, idx = work.keys, work.idx
    # Compact: active rows to the front (only the old leaf ranges hold rows). n starts as a typed
    # zero: a literal 0 would make numba compile an extra specialisation of _depth for it.
    n = np.int64(0)
    for s in range(info[I_BUILT]):
        if slot_id[s] >= 0:
            if s != n:
                for t in range(SLOT_DATA):
                    slot_f[n, t] = slot_f[s, t]
                slot_id[n] = slot_id[s]
            n += 1
    depth = _depth(n, info[I_LEAFSIZE])
    first_leaf = (1 << depth) - 1
    n_nodes = 2 * first_leaf + 1
    info[I_FIRST_LEAF] = first_leaf
    info[I_BUILT] = n
    info[I_ACTIVE] = n
    for s in range(n):
        idx[s] = s
        for t in range(3):
            keys[s, t] = 0.5 * (slot_f[s, S_LO + t] + slot_f[s, S_HI + t])
    rs = np.empty(n_nodes, np.int64)
    re = np.empty(n_nodes, np.int64)
    rs[0] = 0
    re[0] = n
    # Each node's cell (its parent's cell cut at the parent's split) picks the split axis: its
    # longest side, as in a classic kd-tree, without a pass over the node's points.
    cell = np.empty((n_nodes, 6))
    lo, hi = points_box(keys, 0, n)
    set_row3(cell, 0, 0, lo)
    set_row3(cell, 0, 3, hi)
    for k in range((1 << _levels(info)[0]) - 1):
        _split_node(keys, idx, rs, re, cell, node_s, k)
    return rs, re, cell


@njit(cache=True, nogil=True)
def kd_build_subtrees(kd, work, rs, re, cell, s, e):
    """Second part of a (re)build, for the subtrees s..e-1 below the top levels (2^levels of them,
    disjoint in nodes and slots, so threads may take different ones): their splits, their rows
    gathered into the workspace in leaf order, their leaves' ranges."""
    slot_f, slot_id, slot_leaf, node_s, leaf_start, info = (kd.slot_f, kd.slot_id, kd.slot_leaf, kd.node_s,
                                                            kd.leaf_start, kd.info)
    keys, idx, slot_tmp, id_tmp = work.keys, work.idx, work.slot_tmp, work.id_tmp
    first_leaf = info[I_FIRST_LEAF]
    top, below = _levels(info)
    for j in range(s, e):
        root = (1 << top) - 1 + j
        for level in range(below):
            first = ((root + 1) << level) - 1
            for k in range(first, first + (1 << level)):
                _split_node(keys, idx, rs, re, cell, node_s, k)
        # Row u of the rebuilt tree is the old row idx[u]: a gather, which each subtree does for its
        # own rows (an in-place permutation would follow cycles across subtrees).
        for u in range(rs[root], re[root]):
            v = idx[u]
            for t in range(SLOT_DATA):
                slot_tmp[u, t] = slot_f[v, t]
            id_tmp[u] = slot_id[v]
        leaf0 = ((root + 1) << below) - 1
        for leaf in range(leaf0, leaf0 + (1 << below)):
            leaf_start[leaf - first_leaf] = rs[leaf]
            for u in range(rs[leaf], re[leaf]):
                slot_leaf[u] = leaf


@njit(cache=True, nogil=True)
def kd_build_bounds(kd, work, rs, re, s, e):
    """Third part of a (re)build, for the subtrees s..e-1 (after every gather): rows back from the
    workspace, ``slot_of``, every node bound of the subtrees."""
    slot_f, slot_id, slot_of, info = kd.slot_f, kd.slot_id, kd.slot_of, kd.info
    node_s, node_n, node_cnt = kd.node_s, kd.node_n, kd.node_cnt
    slot_tmp, id_tmp = work.slot_tmp, work.id_tmp
    top, below = _levels(info)
    for j in range(s, e):
        root = (1 << top) - 1 + j
        for u in range(rs[root], re[root]):
            for t in range(SLOT_DATA):
                slot_f[u, t] = slot_tmp[u, t]
            slot_id[u] = id_tmp[u]
            slot_of[id_tmp[u]] = u
        leaf0 = ((root + 1) << below) - 1
        for leaf in range(leaf0, leaf0 + (1 << below)):
            _leaf_bounds(slot_f, rs[leaf], re[leaf], node_s, node_n, leaf)
            node_cnt[leaf] = re[leaf] - rs[leaf]
        for level in range(below - 1, -1, -1):
            first = ((root + 1) << level) - 1
            for k in range(first, first + (1 << level)):
                _join_bounds(node_s, node_n, node_cnt, k)


@njit(cache=True)
def kd_build_finish(kd):
    """Last part of a (re)build: the top levels' bounds, the leaf table's end, the empty slots."""
    slot_id, node_s, node_n, node_cnt, leaf_start, info = (kd.slot_id, kd.node_s, kd.node_n, kd.node_cnt,
                                                           kd.leaf_start, kd.info)
    n = info[I_BUILT]
    for k in range((1 << _levels(info)[0]) - 2, -1, -1):
        _join_bounds(node_s, node_n, node_cnt, k)
    leaf_start[info[I_FIRST_LEAF] + 1] = n
    for s in range(n, slot_id.shape[0]):
        slot_id[s] = -1


@njit(cache=True)
def kd_build(kd, work):
    """(Re)build the kd-tree over the active slots, in place, on this thread.

    kd, work : the KdTree and KdWork from :func:`kd_new`; the active slots are compacted to the front,
        reordered into kd leaves, and every node bound is recomputed exactly (then rounded
        outwards). :func:`kd_build_threaded` does the same on the numba threads.
    """
    rs, re, cell = kd_build_start(kd, work)
    subtrees = np.int64(1) << _levels(kd.info)[0]
    kd_build_subtrees(kd, work, rs, re, cell, 0, subtrees)
    kd_build_bounds(kd, work, rs, re, 0, subtrees)
    kd_build_finish(kd)


def kd_build_threaded(kd, work, parallel_min: int = _PARALLEL_BUILD_MIN) -> None:
    """:func:`kd_build` with its subtrees on the numba threads (the same tree, whatever their number),
    for trees of at least ``parallel_min`` active clusters."""
    rs, re, cell = kd_build_start(kd, work)
    info = kd.info
    subtrees = 1 << int(_levels(info)[0])
    min_n = 2 if info[I_BUILT] >= parallel_min else subtrees + 1
    on_threads(kd_build_subtrees, subtrees, min_n, kd, work, rs, re, cell)
    on_threads(kd_build_bounds, subtrees, min_n, kd, work, rs, re)
    kd_build_finish(kd)


@njit(cache=True)
def kd_new(lo, hi, normal, intensity, order, leafsize):
    """The kd-tree over N single-item clusters (cluster i = item ``order[i]``), and its build workspace.

    lo, hi : (N, 3) float64 each item's box (a light: its position twice; a triangle: its bounding
        box); normal : (N, 3) float64 (its box of normals is the point); intensity : (N,) float64;
        order : (N,) int64 permutation; leafsize : int >= 2
    Returns ``(kd, work)``, a :class:`~lightcuts.cluster.kd_tree.KdTree` (``slot_of`` has room for the
    2N-1 cluster ids of a full tree) and a :class:`~lightcuts.cluster.kd_tree.KdWork`. The tree is not
    built yet: build it with :func:`kd_build` or :func:`kd_build_threaded` (kd_build is not called
    here, so that a caller of kd_new alone does not compile it).
    """
    n = lo.shape[0]
    slot_f = _rows_f64(n, SLOT_WIDTH)
    slot_id = np.empty(n, np.int32)
    slot_of = np.full(max(2 * n - 1, 1), -1, np.int32)
    for i in range(n):
        j = order[i]
        for t in range(3):
            slot_f[i, S_LO + t] = lo[j, t]
            slot_f[i, S_HI + t] = hi[j, t]
            slot_f[i, S_NLO + t] = normal[j, t]
            slot_f[i, S_NHI + t] = normal[j, t]
        slot_f[i, S_I] = intensity[j]
        slot_id[i] = i
    depth = _depth(n, leafsize)
    n_nodes = (2 << depth) - 1
    info = np.zeros(4, np.int64)
    info[I_BUILT] = n
    info[I_LEAFSIZE] = leafsize
    kd = KdTree(slot_f, slot_id, slot_of, np.empty(n, np.int32), _rows_f32(n_nodes, np.int64(NODE_WIDTH)),
                _rows_f32(n_nodes, np.int64(NORMAL_WIDTH)), np.zeros(n_nodes, np.int32),
                np.zeros((1 << depth) + 1, np.int64), info, np.empty(_STACK, np.int64), np.empty(_STACK), np.empty(leafsize))
    work = KdWork(np.empty((n, 3)), np.empty(n, np.int32), np.empty((n, SLOT_WIDTH)), np.empty(n, np.int32))
    return kd, work
