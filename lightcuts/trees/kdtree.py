r"""A kd-tree over the active clusters for findBestMatch (Walter, Bala, Kulkarni, Pingali 2008, sec. 3.1).

The agglomerative builders repeatedly ask for the active cluster B that minimises the metric
d(A u B) (:mod:`lightcuts.trees.metrics`). This module answers with a branch-and-bound search over
a kd-tree whose points are the clusters' box centres; every kd node carries enough to bound
d(A u B) from below for every B under it.

Storage (flat arrays; a "slot" holds one active cluster)
---------------------------------------------------------
- ``slot_f`` (S, 16) float64, rows aligned to 64 bytes: the cluster's spatial box ``lo, hi``
  (columns 0-5) and scalar intensity (6) in the first cache line -- all that the first test of a
  pair reads -- then its box of unit normals ``nlo, nhi`` (7-12).
- ``slot_id`` (S,) int32: the cluster in the slot, -1 for an empty slot.
- ``slot_of`` (2N-1,) int32: cluster id -> slot, -1 when the cluster is not active.
- ``slot_leaf`` (S,) int32: the kd leaf (node index) that owns the slot.
- ``node_s`` (M, 16) float32, one 64-byte line per node, per axis: the smallest upper end ``hmin``
  (0-2) and the largest lower end ``lmax`` (3-5) of the clusters' boxes, their smallest extent
  ``emin`` (6-8); the smallest intensity ``imin`` (9); split value (10) and axis (11), which only
  order the search.
- ``node_n`` (M, 9) float32: the same three for the boxes of normals, ``nhmin, nlmax, nemin``; read
  only when the spatial part of a bound does not prune.
- ``node_cnt`` (M,) int32: active clusters under the node (0: skip it).
- ``leaf_start`` (L+1,) int64: leaf ``first_leaf + j`` owns slots ``leaf_start[j] .. [j+1]-1``, of
  which the first ``node_cnt[first_leaf + j]`` hold its active clusters (a search never meets an
  empty slot).
- ``info`` (4,) int64: ``first_leaf``, clusters at the last (re)build, leaf size, active clusters.
- ``stack_node``, ``stack_lb``: the search's traversal stack; ``dbuf`` (leaf size,): one leaf's
  metric values without the cone term.

Node values are float32 rounded outwards (minima down, maxima up), so they stay valid bounds at
half the memory traffic; the search is bound by the latency of node and slot rows.

The tree is implicit and balanced (children of node k are 2k+1 and 2k+2, all leaves at one depth),
split at the median of the centres along the longest side of the node's cell. Merging A and B into
C writes C into the slot of whichever of A, B has its centre nearer C's; the other slot is filled
by the last active slot of its leaf, and the counts on its path drop by one. No bound needs an
update: C's upper ends, extents and intensity are >= those of the cluster whose slot it takes, its
lower ends <=, so ``hmin``, ``emin``, ``imin`` (minima) and ``lmax`` (a maximum) still hold, as
they do when a cluster is removed (they only become loose). A batch of merges with distinct
clusters (a round of the locally-ordered builder) does those whose two clusters lie in one subtree
below the top levels on the threads, a subtree per task (:func:`kd_merge_batch`), then the others,
then the counts of the top levels. When the active clusters fall to half of those at the last
build, the tree is rebuilt over them (amortised O(N log N) in all), which restores tight bounds. A
(re)build splits the top three levels, then handles the eight subtrees below them independently
(splits, rows gathered into the workspace in leaf order, bounds), in turn (:func:`kd_build`) or on
the numba threads (:func:`kd_build_threaded`), with the same result.

Lower bound of d(A u B) over the clusters B under a node
--------------------------------------------------------
Per axis, with A's box ``[loA, hiA]`` (extent ea) and B's ``[lo, hi]``, the union's extent is
``U = max(hiA, hi) - min(loA, lo)``. Over the node ``hi >= hmin``, ``lo <= lmax`` and
``hi - lo >= emin``, so

    U >= max(ea, emin, max(hiA, hmin) - min(loA, lmax)).

(This is at least as tight as bounding by a box of centres and a minimum extent, which implies
``hi >= cmin + emin/2`` and ``lo <= cmax - emin/2``, and unlike that box it needs no update when
clusters merge.) Every built-in metric grows with each extent (walter: L^2 = sum of squared
extents; surface area: 2(ex ey + ey ez + ez ex) of non-negative extents) and with the intensity
(I_A + I_B >= I_A + imin), so the metric of a box with these extents bounds it from below.

The cone term: the box-of-normals cone is not monotone under union, so no cluster's cone is used.
Instead: the union's box of normals has on each axis an extent Dk bounded below exactly as U above;
the box is the bounding box of actual unit normals, so two normals of A u B differ by Dk on that
axis, hence are at least D = max_k Dk apart, at an angle >= 2 asin(D/2); any cone containing both
has half-angle beta >= asin(D/2), i.e. ``cos(beta) <= sqrt(1 - D^2/4)``. The metric is evaluated
with that cosine (S and 1 - cos(beta) only grow as cos(beta) falls). (The same cosine from a pair's
own normal spread would bound the pair's d, but it spared only 2% of the pairs left after the
first pass their cone, and cost more than it saved.)

Rounding: the metric is a composition of monotone floating-point operations, so a bound holds as
computed when its inputs do. The bound's extents are computed as the pair's own are, from ends
that are <= (upper) and >= (lower) the pair's, and rounding is monotone, so each is <= the pair's
extent as computed; float32 node values are rounded outwards. The cone cosine is raised by
``_COS_SLACK``, which covers :func:`~lightcuts.trees.cones.cone_from_box`'s rounding and that of
the spread. Bounds may be loose, never too tight: the search returns exactly the minimum of the
metric as computed (``tests/test_agglomerative.py`` checks it against a brute-force scan).

Cost (200K Cornell-box VPLs, oriented, walter2008): about 25 node bounds and 3 leaves (about 54
active slots) per search; bounds are loose mostly because the neighbourhood of A meets several
leaves, not because of their form (the box-of-ends form above opens 4% fewer nodes than boxes of
centres). Leaves of 32 clusters, scanned in two passes (the metric without its cone term for the
whole leaf, then the survivors), cost less than deeper trees of smaller leaves. The clusters of
one leaf search much the same neighbourhood, so :func:`kd_search_range` searches them together
(:func:`kd_search_groups`): one traversal for the group, whose node bounds hold for all its
members at once, and for each leaf it reaches, one cheap bound per member (vectorised over the
members) before that member scans it. With the locally-ordered builder's rounds (13 clusters per
group on average) that is 4.5 node bounds, 12 member bounds and 3.1 leaf scans per search, and 40%
less search time; copying each reached leaf's boxes as columns, so that the scans' first pass
vectorises, saved another 12-15%.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.parallel import next_task, on_threads
from lightcuts.rounding import down32, up32
from lightcuts.trees.cones import cone_from_box
from lightcuts.trees.metrics import metric_eval

# Slot row columns (float64): the first cache line holds what the first test of a pair reads.
S_LO, S_HI, S_I, S_NLO, S_NHI = 0, 3, 6, 7, 10
SLOT_DATA = 13
SLOT_WIDTH = 16
# Spatial node row columns (float32, one cache line).
N_HMIN, N_LMAX, N_EMIN, N_IMIN, N_SPLIT, N_AXIS = 0, 3, 6, 9, 10, 11
NODE_WIDTH = 16
# Normal node row columns (float32).
NH_MIN, NL_MAX, NE_MIN = 0, 3, 6
NORMAL_WIDTH = 9
# info entries.
I_FIRST_LEAF, I_BUILT, I_LEAFSIZE, I_ACTIVE = 0, 1, 2, 3

# Default clusters per kd leaf: with dense leaves and the two-pass scan, 32 builds 200K and 800K Cornell VPLs
# about 15% faster than 8 and 5-10% faster than 16; 48 and 64 are within noise at 200K, slower at 800K.
LEAF_SIZE = 32
# Traversal stack entries: at most two per level, and the tree has at most ~40 levels.
_STACK = 128
# Added to the cone-cosine bound: exceeds cone_from_box's rounding except for boxes whose centre is
# within ~1e-7 of the origin, whose cones are near the full sphere anyway.
_COS_SLACK = 1e-9
# A (re)build splits this many levels on one thread, then hands the 2^levels subtrees below to
# threads (from kd_build_threaded) or does them in turn (kd_build): the same tree either way.
_TOP_LEVELS = 3
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
    axis = 0
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
    top = min(depth, _TOP_LEVELS)
    return top, depth - top


@njit(cache=True)
def kd_build_start(kd, work):
    """First part of a (re)build: compact the active slots, split the top levels of the tree.

    Returns ``(rs, re, cell)``, each node's slot range and cell, for :func:`kd_build_subtrees`.
    """
    slot_f, slot_id, slot_of, slot_leaf, node_s, node_n, node_cnt, leaf_start, info = kd[:9]
    keys, idx = work[0], work[1]
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
    for t in range(3):
        cell[0, t] = np.inf
        cell[0, 3 + t] = -np.inf
        for u in range(n):
            cell[0, t] = min(cell[0, t], keys[u, t])
            cell[0, 3 + t] = max(cell[0, 3 + t], keys[u, t])
    for k in range((1 << _levels(info)[0]) - 1):
        _split_node(keys, idx, rs, re, cell, node_s, k)
    return rs, re, cell


@njit(cache=True, nogil=True)
def kd_build_subtrees(kd, work, rs, re, cell, s, e):
    """Second part of a (re)build, for the subtrees s..e-1 below the top levels (2^levels of them,
    disjoint in nodes and slots, so threads may take different ones): their splits, their rows
    gathered into the workspace in leaf order, their leaves' ranges."""
    slot_f, slot_id, slot_leaf, node_s, leaf_start, info = kd[0], kd[1], kd[3], kd[4], kd[7], kd[8]
    keys, idx, slot_tmp, id_tmp = work
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
    slot_f, slot_id, slot_of, node_s, node_n, node_cnt, info = kd[0], kd[1], kd[2], kd[4], kd[5], kd[6], kd[8]
    slot_tmp, id_tmp = work[2], work[3]
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
    slot_id, node_s, node_n, node_cnt, leaf_start, info = kd[1], kd[4], kd[5], kd[6], kd[7], kd[8]
    n = info[I_BUILT]
    for k in range((1 << _levels(info)[0]) - 2, -1, -1):
        _join_bounds(node_s, node_n, node_cnt, k)
    leaf_start[info[I_FIRST_LEAF] + 1] = n
    for s in range(n, slot_id.shape[0]):
        slot_id[s] = -1


@njit(cache=True)
def kd_build(kd, work):
    """(Re)build the kd-tree over the active slots, in place, on this thread.

    kd, work : the tuples from :func:`kd_new`; the active slots are compacted to the front,
        reordered into kd leaves, and every node bound is recomputed exactly (then rounded
        outwards). :func:`kd_build_threaded` does the same on the numba threads.
    """
    rs, re, cell = kd_build_start(kd, work)
    subtrees = np.int64(1) << _levels(kd[8])[0]
    kd_build_subtrees(kd, work, rs, re, cell, 0, subtrees)
    kd_build_bounds(kd, work, rs, re, 0, subtrees)
    kd_build_finish(kd)


def kd_build_threaded(kd, work, parallel_min: int = _PARALLEL_BUILD_MIN) -> None:
    """:func:`kd_build` with its subtrees on the numba threads (the same tree, whatever their number),
    for trees of at least ``parallel_min`` active clusters."""
    rs, re, cell = kd_build_start(kd, work)
    info = kd[8]
    subtrees = 1 << int(_levels(info)[0])
    min_n = 2 if info[I_BUILT] >= parallel_min else subtrees + 1
    on_threads(kd_build_subtrees, subtrees, min_n, kd, work, rs, re, cell)
    on_threads(kd_build_bounds, subtrees, min_n, kd, work, rs, re)
    kd_build_finish(kd)


@njit(cache=True)
def kd_new(position, normal, luminance, order, leafsize):
    """The kd-tree over N single-light clusters (cluster i = light ``order[i]``), and its build workspace.

    position, normal : (N, 3) float64; luminance : (N,) float64; order : (N,) int64 permutation;
    leafsize : int >= 2
    Returns ``(kd, work)``: ``kd = (slot_f, slot_id, slot_of, slot_leaf, node_s, node_n, node_cnt,
    leaf_start, info, stack_node, stack_lb, dbuf)`` as described in the module docstring
    (``slot_of`` has room for the 2N-1 cluster ids of a full tree), ``work = (keys, idx, slot_tmp,
    id_tmp)``. The tree is not built yet: build it with :func:`kd_build` or :func:`kd_build_threaded`
    (kd_build is not called here, so that a caller of kd_new alone does not compile it).
    """
    n = position.shape[0]
    slot_f = _rows_f64(n, SLOT_WIDTH)
    slot_id = np.empty(n, np.int32)
    slot_of = np.full(max(2 * n - 1, 1), -1, np.int32)
    for i in range(n):
        j = order[i]
        for t in range(3):
            slot_f[i, S_LO + t] = position[j, t]
            slot_f[i, S_HI + t] = position[j, t]
            slot_f[i, S_NLO + t] = normal[j, t]
            slot_f[i, S_NHI + t] = normal[j, t]
        slot_f[i, S_I] = luminance[j]
        slot_id[i] = i
    depth = _depth(n, leafsize)
    n_nodes = (2 << depth) - 1
    info = np.zeros(4, np.int64)
    info[I_BUILT] = n
    info[I_LEAFSIZE] = leafsize
    kd = (slot_f, slot_id, slot_of, np.empty(n, np.int32), _rows_f32(n_nodes, NODE_WIDTH),
          _rows_f32(n_nodes, NORMAL_WIDTH), np.zeros(n_nodes, np.int32), np.zeros((1 << depth) + 1, np.int64), info,
          np.empty(_STACK, np.int64), np.empty(_STACK), np.empty(leafsize))
    work = (np.empty((n, 3)), np.empty(n, np.int32), np.empty((n, SLOT_WIDTH)), np.empty(n, np.int32))
    return kd, work


@njit(cache=True)
def _cone_cos_bound(spread):
    """Upper bound of cos(beta) for any cone holding unit normals that differ by ``spread`` on one axis."""
    if spread <= 0.0:
        return 1.0
    return min(1.0, np.sqrt(max(0.0, 1.0 - 0.25 * spread * spread)) + _COS_SLACK)


@njit(cache=True)
def _union_extent(qlo, qhi, hmin, lmax, emin):
    """Lower bound of one axis' extent of A u B, A = [qlo, qhi], over B = [lo, hi] with hi >= hmin,
    lo <= lmax, hi - lo >= emin (float32 bounds, widened to float64 exactly)."""
    return max(qhi - qlo, np.float64(emin), max(qhi, np.float64(hmin)) - min(qlo, np.float64(lmax)))


@njit(cache=True)
def kd_best_match(kd, a, metric_id, has_cone, use_cone, c):
    """findBestMatch(A): the active cluster B != A minimising d(A u B).

    kd : the tree (:func:`kd_new`); a : active cluster id; metric_id, has_cone : as for
        :func:`~lightcuts.trees.metrics.metric_eval`; use_cone : compute the union's cone (oriented
        lights and a metric with a cone term); c : cone-term scale.
    Returns ``(b, d)``; ``(-1, inf)`` if A is the only active cluster.

    d is the metric as the builders define it: union box, box-of-normals cone of the union, summed
    intensity. Among equal d the smallest id found wins; nodes whose bound equals the best d are
    pruned, so which of several tied clusters is returned depends on the tree.

    Reads the tree only, writing nothing but the traversal stack and leaf buffer in ``kd``, so
    searches on several threads need only their own copies of those three (:func:`kd_scratch`).
    The loop calls only scalar helpers: in numba an array passed to a helper costs two atomic
    reference-count updates per call, which was 40% of the search time.

    :func:`kd_search_groups` with a group of one finds the same, along the same traversal; it is not
    used for this because its per-group set-up (member rows, leaf columns, scratch passed per call)
    made the heap builder, which searches one cluster at a time, 20-35% slower.
    """
    slot_f, slot_id, slot_of, slot_leaf, node_s, node_n, node_cnt, leaf_start, info, stack_node, stack_lb, dbuf = kd
    first_leaf = info[I_FIRST_LEAF]
    sa = slot_of[a]
    qlo0 = slot_f[sa, S_LO]
    qlo1 = slot_f[sa, S_LO + 1]
    qlo2 = slot_f[sa, S_LO + 2]
    qhi0 = slot_f[sa, S_HI]
    qhi1 = slot_f[sa, S_HI + 1]
    qhi2 = slot_f[sa, S_HI + 2]
    qnlo0 = slot_f[sa, S_NLO]
    qnlo1 = slot_f[sa, S_NLO + 1]
    qnlo2 = slot_f[sa, S_NLO + 2]
    qnhi0 = slot_f[sa, S_NHI]
    qnhi1 = slot_f[sa, S_NHI + 1]
    qnhi2 = slot_f[sa, S_NHI + 2]
    qi = slot_f[sa, S_I]
    qc0 = 0.5 * (qlo0 + qhi0)
    qc1 = 0.5 * (qlo1 + qhi1)
    qc2 = 0.5 * (qlo2 + qhi2)
    best = np.int64(-1)
    best_d = np.inf
    # Bottom-up: A's own leaf first (its neighbours give a tight bound at once), then, climbing to
    # the root, each sibling subtree on the way, top-down with the child on A's side of the split
    # first. A node's bound is computed when it is popped (stack_lb < 0), against the best d then.
    # Every pruned node has a bound >= the best d at that time >= the final best d.
    up = slot_leaf[sa]
    stack_node[0] = up
    stack_lb[0] = 0.0
    sp = 1
    while True:
        while sp > 0:
            sp -= 1
            k = stack_node[sp]
            lb = stack_lb[sp]
            if lb < 0.0:
                u0 = _union_extent(qlo0, qhi0, node_s[k, N_HMIN], node_s[k, N_LMAX], node_s[k, N_EMIN])
                u1 = _union_extent(qlo1, qhi1, node_s[k, N_HMIN + 1], node_s[k, N_LMAX + 1], node_s[k, N_EMIN + 1])
                u2 = _union_extent(qlo2, qhi2, node_s[k, N_HMIN + 2], node_s[k, N_LMAX + 2], node_s[k, N_EMIN + 2])
                intensity = qi + np.float64(node_s[k, N_IMIN])
                lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, 1.0, has_cone, c)
                if use_cone and lb < best_d:
                    spread = max(
                        _union_extent(qnlo0, qnhi0, node_n[k, NH_MIN], node_n[k, NL_MAX], node_n[k, NE_MIN]),
                        _union_extent(qnlo1, qnhi1, node_n[k, NH_MIN + 1], node_n[k, NL_MAX + 1],
                                      node_n[k, NE_MIN + 1]),
                        _union_extent(qnlo2, qnhi2, node_n[k, NH_MIN + 2], node_n[k, NL_MAX + 2],
                                      node_n[k, NE_MIN + 2]))
                    lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, _cone_cos_bound(spread),
                                     has_cone, c)
            if lb >= best_d:
                continue
            if k < first_leaf:
                l = 2 * k + 1
                r = l + 1
                axis = int(node_s[k, N_AXIS])
                qc = qc0 if axis == 0 else (qc1 if axis == 1 else qc2)
                if qc >= node_s[k, N_SPLIT]:
                    l, r = r, l
                if node_cnt[r] > 0:
                    stack_node[sp] = r
                    stack_lb[sp] = -1.0
                    sp += 1
                if node_cnt[l] > 0:
                    stack_node[sp] = l
                    stack_lb[sp] = -1.0
                    sp += 1
                continue
            # Two passes over the leaf: first the metric without its cone term for every slot (no
            # branches, so the loads of all rows overlap), then only the slots it does not prune.
            s0 = leaf_start[k - first_leaf]
            cnt = node_cnt[k]
            for i in range(cnt):
                s = s0 + i
                dbuf[i] = metric_eval(metric_id, qi + slot_f[s, S_I], min(qlo0, slot_f[s, S_LO]),
                                      min(qlo1, slot_f[s, S_LO + 1]), min(qlo2, slot_f[s, S_LO + 2]),
                                      max(qhi0, slot_f[s, S_HI]), max(qhi1, slot_f[s, S_HI + 1]),
                                      max(qhi2, slot_f[s, S_HI + 2]), 1.0, has_cone, c)
            for i in range(cnt):
                d = dbuf[i]
                if d > best_d:
                    continue
                s = s0 + i
                b = slot_id[s]
                if b == a:
                    continue
                if use_cone:
                    lo0 = min(qlo0, slot_f[s, S_LO])
                    lo1 = min(qlo1, slot_f[s, S_LO + 1])
                    lo2 = min(qlo2, slot_f[s, S_LO + 2])
                    hi0 = max(qhi0, slot_f[s, S_HI])
                    hi1 = max(qhi1, slot_f[s, S_HI + 1])
                    hi2 = max(qhi2, slot_f[s, S_HI + 2])
                    intensity = qi + slot_f[s, S_I]
                    nlo0 = min(qnlo0, slot_f[s, S_NLO])
                    nlo1 = min(qnlo1, slot_f[s, S_NLO + 1])
                    nlo2 = min(qnlo2, slot_f[s, S_NLO + 2])
                    nhi0 = max(qnhi0, slot_f[s, S_NHI])
                    nhi1 = max(qnhi1, slot_f[s, S_NHI + 1])
                    nhi2 = max(qnhi2, slot_f[s, S_NHI + 2])
                    ax, ay, az, cos_half = cone_from_box(nlo0, nlo1, nlo2, nhi0, nhi1, nhi2)
                    d = metric_eval(metric_id, intensity, lo0, lo1, lo2, hi0, hi1, hi2, cos_half, has_cone, c)
                if d < best_d or (d == best_d and b < best):
                    best = b
                    best_d = d
        if up == 0:
            break
        sib = up + 1 if up & 1 else up - 1
        up = (up - 1) >> 1
        if node_cnt[sib] > 0:
            stack_node[0] = sib
            stack_lb[0] = -1.0
            sp = 1
    return best, best_d


@njit(cache=True)
def _group_extent(gemin, ghmin, glmax, hmin, lmax, emin):
    """Lower bound of one axis' extent of A u B over every A of a group (extent >= gemin, hi >= ghmin,
    lo <= glmax) and every B under a node (float32 bounds, widened exactly)."""
    return max(gemin, np.float64(emin), max(ghmin, np.float64(hmin)) - min(glmax, np.float64(lmax)))


@njit(cache=True, nogil=True)
def kd_search_groups(kd, todo, n_todo, first, last, out_best, out_best_d, metric_id, has_cone, use_cone, c,
                     gq, gb, gd, mb, lt):
    """findBestMatch for the clusters of the groups that start in ``todo[first:last]`` (a group: a run of
    ``todo[:n_todo]`` in one kd leaf, at most a leaf size long), each group in one traversal.

    Writes ``out_best[a], out_best_d[a]`` = :func:`kd_best_match` of each such cluster a (the same minimum d;
    among tied clusters the one found may differ). Groups depend on ``todo`` only, not on first and last.
    One call for many groups: a call taking the kd tuple costs a reference-count update per array,
    atomic operations that the threads of a round would contend for. Scratch, with ``kd`` a thread's own
    (:func:`kd_scratch`): gq (SLOT_WIDTH, >= g1 - g0) float64, the members' rows as columns; gb, gd,
    mb (>= g1 - g0,) int64, float64, float64; lt (S_I + 1, leaf size) float64, a leaf's boxes and
    intensities as columns.

    The members' searches share their node bounds: a node is opened unless it bounds d(A u B) from
    below for every member A at once, by the bound of the module docstring with A's box replaced by
    the group's ``hi >= min hi``, ``lo <= max lo``, ``extent >= min extent`` (and the same for the
    normal boxes), against the largest best d of the group. A leaf it reaches costs each member whose
    own bound does not prune it one scan. The scans are most of the time (by cycle counts at 200K
    VPLs, 71% before the leaf's boxes were copied as columns for them, 29 points of it the second
    pass): the copy lets the first pass vectorise (12-15% less search time).
    """
    slot_f, slot_id, slot_of, slot_leaf, node_s, node_n, node_cnt, leaf_start, info, stack_node, stack_lb, dbuf = kd
    first_leaf = info[I_FIRST_LEAF]
    cap = info[I_LEAFSIZE]
    # The first group that starts at or after first: groups are cut from the start of each run.
    g0 = first
    while g0 > 0 and slot_leaf[slot_of[todo[g0 - 1]]] == slot_leaf[slot_of[todo[first]]]:
        g0 -= 1
    while g0 < last:
        # The group todo[g0:g1]: the run of clusters in g0's kd leaf, at most cap long.
        run_leaf = slot_leaf[slot_of[todo[g0]]]
        g1 = g0 + 1
        while g1 < n_todo and g1 - g0 < cap and slot_leaf[slot_of[todo[g1]]] == run_leaf:
            g1 += 1
        if g0 < first:  # a group that starts before first: the caller whose range holds its start does it
            g0 = g1
            continue
        g = g1 - g0
        gh0 = gh1 = gh2 = np.inf
        gl0 = gl1 = gl2 = -np.inf
        ge0 = ge1 = ge2 = np.inf
        gnh0 = gnh1 = gnh2 = np.inf
        gnl0 = gnl1 = gnl2 = -np.inf
        gne0 = gne1 = gne2 = np.inf
        gi = np.inf
        gc0 = gc1 = gc2 = 0.0
        for i in range(g):
            s = slot_of[todo[g0 + i]]
            for t in range(SLOT_DATA):
                gq[t, i] = slot_f[s, t]
            gb[i] = -1
            gd[i] = np.inf
            gl0 = max(gl0, gq[S_LO, i])
            gl1 = max(gl1, gq[S_LO + 1, i])
            gl2 = max(gl2, gq[S_LO + 2, i])
            gh0 = min(gh0, gq[S_HI, i])
            gh1 = min(gh1, gq[S_HI + 1, i])
            gh2 = min(gh2, gq[S_HI + 2, i])
            ge0 = min(ge0, gq[S_HI, i] - gq[S_LO, i])
            ge1 = min(ge1, gq[S_HI + 1, i] - gq[S_LO + 1, i])
            ge2 = min(ge2, gq[S_HI + 2, i] - gq[S_LO + 2, i])
            gnl0 = max(gnl0, gq[S_NLO, i])
            gnl1 = max(gnl1, gq[S_NLO + 1, i])
            gnl2 = max(gnl2, gq[S_NLO + 2, i])
            gnh0 = min(gnh0, gq[S_NHI, i])
            gnh1 = min(gnh1, gq[S_NHI + 1, i])
            gnh2 = min(gnh2, gq[S_NHI + 2, i])
            gne0 = min(gne0, gq[S_NHI, i] - gq[S_NLO, i])
            gne1 = min(gne1, gq[S_NHI + 1, i] - gq[S_NLO + 1, i])
            gne2 = min(gne2, gq[S_NHI + 2, i] - gq[S_NLO + 2, i])
            gi = min(gi, gq[S_I, i])
            gc0 += gq[S_LO, i] + gq[S_HI, i]
            gc1 += gq[S_LO + 1, i] + gq[S_HI + 1, i]
            gc2 += gq[S_LO + 2, i] + gq[S_HI + 2, i]
        gc0 /= 2 * g
        gc1 /= 2 * g
        gc2 /= 2 * g
        home = slot_leaf[slot_of[todo[g0]]]
        thr = np.inf
        # As kd_best_match: the home leaf, then the sibling subtrees on the climb to the root.
        up = home
        stack_node[0] = up
        stack_lb[0] = 0.0
        sp = 1
        while True:
            while sp > 0:
                sp -= 1
                k = stack_node[sp]
                lb = stack_lb[sp]
                if lb < 0.0:
                    u0 = _group_extent(ge0, gh0, gl0, node_s[k, N_HMIN], node_s[k, N_LMAX], node_s[k, N_EMIN])
                    u1 = _group_extent(ge1, gh1, gl1, node_s[k, N_HMIN + 1], node_s[k, N_LMAX + 1],
                                       node_s[k, N_EMIN + 1])
                    u2 = _group_extent(ge2, gh2, gl2, node_s[k, N_HMIN + 2], node_s[k, N_LMAX + 2],
                                       node_s[k, N_EMIN + 2])
                    intensity = gi + np.float64(node_s[k, N_IMIN])
                    lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, 1.0, has_cone, c)
                    if use_cone and lb < thr:
                        spread = max(
                            _group_extent(gne0, gnh0, gnl0, node_n[k, NH_MIN], node_n[k, NL_MAX], node_n[k, NE_MIN]),
                            _group_extent(gne1, gnh1, gnl1, node_n[k, NH_MIN + 1], node_n[k, NL_MAX + 1],
                                          node_n[k, NE_MIN + 1]),
                            _group_extent(gne2, gnh2, gnl2, node_n[k, NH_MIN + 2], node_n[k, NL_MAX + 2],
                                          node_n[k, NE_MIN + 2]))
                        lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, _cone_cos_bound(spread),
                                         has_cone, c)
                if lb >= thr:
                    continue
                if k < first_leaf:
                    l = 2 * k + 1
                    r = l + 1
                    axis = int(node_s[k, N_AXIS])
                    qc = gc0 if axis == 0 else (gc1 if axis == 1 else gc2)
                    if qc >= node_s[k, N_SPLIT]:
                        l, r = r, l
                    if node_cnt[r] > 0:
                        stack_node[sp] = r
                        stack_lb[sp] = -1.0
                        sp += 1
                    if node_cnt[l] > 0:
                        stack_node[sp] = l
                        stack_lb[sp] = -1.0
                        sp += 1
                    continue
                s0 = leaf_start[k - first_leaf]
                cnt = node_cnt[k]
                # Each member's own bound for the leaf first, all at once (no branches: the loop vectorises).
                if k != home:
                    h0 = np.float64(node_s[k, N_HMIN])
                    h1 = np.float64(node_s[k, N_HMIN + 1])
                    h2 = np.float64(node_s[k, N_HMIN + 2])
                    l0 = np.float64(node_s[k, N_LMAX])
                    l1 = np.float64(node_s[k, N_LMAX + 1])
                    l2 = np.float64(node_s[k, N_LMAX + 2])
                    e0 = np.float64(node_s[k, N_EMIN])
                    e1 = np.float64(node_s[k, N_EMIN + 1])
                    e2 = np.float64(node_s[k, N_EMIN + 2])
                    imin = np.float64(node_s[k, N_IMIN])
                    for m in range(g):
                        mb[m] = metric_eval(metric_id, gq[S_I, m] + imin, 0.0, 0.0, 0.0,
                                            _union_extent(gq[S_LO, m], gq[S_HI, m], h0, l0, e0),
                                            _union_extent(gq[S_LO + 1, m], gq[S_HI + 1, m], h1, l1, e1),
                                            _union_extent(gq[S_LO + 2, m], gq[S_HI + 2, m], h2, l2, e2), 1.0,
                                            has_cone, c)
                # The leaf's boxes and intensities as columns (once per leaf, for all its scans): a
                # scan's first pass then reads consecutive values and vectorises.
                transposed = False
                for m in range(g):
                    best_d = gd[m]
                    if k != home and mb[m] >= best_d:
                        continue
                    if not transposed:
                        for i in range(cnt):
                            s = s0 + i
                            for t in range(S_I + 1):
                                lt[t, i] = slot_f[s, t]
                        transposed = True
                    a = todo[g0 + m]
                    best = gb[m]
                    qlo0 = gq[S_LO, m]
                    qlo1 = gq[S_LO + 1, m]
                    qlo2 = gq[S_LO + 2, m]
                    qhi0 = gq[S_HI, m]
                    qhi1 = gq[S_HI + 1, m]
                    qhi2 = gq[S_HI + 2, m]
                    qi = gq[S_I, m]
                    for i in range(cnt):
                        dbuf[i] = metric_eval(metric_id, qi + lt[S_I, i], min(qlo0, lt[S_LO, i]),
                                              min(qlo1, lt[S_LO + 1, i]), min(qlo2, lt[S_LO + 2, i]),
                                              max(qhi0, lt[S_HI, i]), max(qhi1, lt[S_HI + 1, i]),
                                              max(qhi2, lt[S_HI + 2, i]), 1.0, has_cone, c)
                    for i in range(cnt):
                        d = dbuf[i]
                        if d > best_d:
                            continue
                        s = s0 + i
                        b = slot_id[s]
                        if b == a:
                            continue
                        if use_cone:
                            lo0 = min(qlo0, slot_f[s, S_LO])
                            lo1 = min(qlo1, slot_f[s, S_LO + 1])
                            lo2 = min(qlo2, slot_f[s, S_LO + 2])
                            hi0 = max(qhi0, slot_f[s, S_HI])
                            hi1 = max(qhi1, slot_f[s, S_HI + 1])
                            hi2 = max(qhi2, slot_f[s, S_HI + 2])
                            intensity = qi + slot_f[s, S_I]
                            nlo0 = min(gq[S_NLO, m], slot_f[s, S_NLO])
                            nlo1 = min(gq[S_NLO + 1, m], slot_f[s, S_NLO + 1])
                            nlo2 = min(gq[S_NLO + 2, m], slot_f[s, S_NLO + 2])
                            nhi0 = max(gq[S_NHI, m], slot_f[s, S_NHI])
                            nhi1 = max(gq[S_NHI + 1, m], slot_f[s, S_NHI + 1])
                            nhi2 = max(gq[S_NHI + 2, m], slot_f[s, S_NHI + 2])
                            ax, ay, az, cos_half = cone_from_box(nlo0, nlo1, nlo2, nhi0, nhi1, nhi2)
                            d = metric_eval(metric_id, intensity, lo0, lo1, lo2, hi0, hi1, hi2, cos_half, has_cone, c)
                        if d < best_d or (d == best_d and b < best):
                            best = b
                            best_d = d
                    gb[m] = best
                    gd[m] = best_d
                thr = 0.0
                for m in range(g):
                    thr = max(thr, gd[m])
            if up == 0:
                break
            sib = up + 1 if up & 1 else up - 1
            up = (up - 1) >> 1
            if node_cnt[sib] > 0:
                stack_node[0] = sib
                stack_lb[0] = -1.0
                sp = 1
        for m in range(g):
            out_best[todo[g0 + m]] = gb[m]
            out_best_d[todo[g0 + m]] = gd[m]
        g0 = g1


@njit(cache=True)
def kd_group_by_leaf(kd, todo, n_todo, tmp):
    """Reorder ``todo[:n_todo]`` by kd leaf (stable counting sort), so that a round's searches form
    groups (:func:`kd_search_range`); tmp : (>= n_todo,) int64 scratch."""
    slot_of = kd[2]
    slot_leaf = kd[3]
    first_leaf = kd[8][I_FIRST_LEAF]
    count = np.zeros(kd[7].shape[0], np.int64)
    for i in range(n_todo):
        count[slot_leaf[slot_of[todo[i]]] - first_leaf + 1] += 1
    for j in range(1, count.shape[0]):
        count[j] += count[j - 1]
    for i in range(n_todo):
        a = todo[i]
        j = slot_leaf[slot_of[a]] - first_leaf
        tmp[count[j]] = a
        count[j] += 1
    for i in range(n_todo):
        todo[i] = tmp[i]


@njit(cache=True, nogil=True)
def kd_search_range(kd, todo, n_todo, best, best_d, metric_id, has_cone, use_cone, c, chunk, tasks):
    """best[a], best_d[a] = findBestMatch(a) for the clusters of ``todo[:n_todo]``: one thread's share
    of a round, chunks of ``chunk`` entries of todo taken from the counter ``tasks`` (int64 (1,), zero
    at the start; lightcuts.parallel.next_task) until none is left.

    A group is a run of ``todo`` in one kd leaf (at most a leaf size long), searched together
    (:func:`kd_search_groups`) by the thread whose chunk holds its start; order ``todo`` with
    :func:`kd_group_by_leaf` first. Groups depend on ``todo`` only, not on the chunks, and each
    search writes its own entries, so the result does not depend on how a round is split among
    threads. Chunks rather than one range per thread: the two cores are shared with other work and
    often run at different speeds, and a thread that finishes first takes the next chunk instead of
    waiting at the end of the round.
    """
    kdt = kd_scratch(kd)
    cap = kd[8][I_LEAFSIZE]
    gq = np.empty((SLOT_WIDTH, cap))
    gb = np.empty(cap, np.int64)
    gd = np.empty(cap)
    mb = np.empty(cap)
    lt = np.empty((S_I + 1, cap))
    while True:
        t = next_task(tasks)
        s = t * chunk
        if s >= n_todo:
            return
        kd_search_groups(kdt, todo, n_todo, s, min(n_todo, s + chunk), best, best_d, metric_id, has_cone, use_cone,
                         c, gq, gb, gd, mb, lt)


@njit(cache=True, nogil=True)
def _merge_rows(kd, left, right, first, n_pairs, new0, pair_sub, s, e, top):
    """:func:`kd_merge`'s slot work for the pairs ``left[first + p], right[first + p] -> new0 + p`` with
    ``s <= pair_sub[p] < e``, in order, and the active counts on the path from each emptied slot's
    leaf up to node ``top`` (0: the root; a first node of a level: to that level). One call for a
    whole batch: a call taking the kd tuple costs a reference-count update per array, atomic
    operations that the two threads of a batch would contend for."""
    slot_f, slot_id, slot_of, slot_leaf, node_s, node_n, node_cnt, leaf_start, info = kd[:9]
    for p in range(n_pairs):
        if not s <= pair_sub[p] < e:
            continue
        a = left[first + p]
        b = right[first + p]
        new_id = new0 + p
        sa = slot_of[a]
        sb = slot_of[b]
        da = 0.0
        db = 0.0
        for t in range(3):
            ca = 0.5 * (slot_f[sa, S_LO + t] + slot_f[sa, S_HI + t])
            cb = 0.5 * (slot_f[sb, S_LO + t] + slot_f[sb, S_HI + t])
            cc = 0.5 * (min(slot_f[sa, S_LO + t], slot_f[sb, S_LO + t])
                        + max(slot_f[sa, S_HI + t], slot_f[sb, S_HI + t]))
            da += (ca - cc) ** 2
            db += (cb - cc) ** 2
        keep, drop = (sa, sb) if da <= db else (sb, sa)
        for t in range(3):
            slot_f[keep, S_LO + t] = min(slot_f[sa, S_LO + t], slot_f[sb, S_LO + t])
            slot_f[keep, S_HI + t] = max(slot_f[sa, S_HI + t], slot_f[sb, S_HI + t])
            slot_f[keep, S_NLO + t] = min(slot_f[sa, S_NLO + t], slot_f[sb, S_NLO + t])
            slot_f[keep, S_NHI + t] = max(slot_f[sa, S_NHI + t], slot_f[sb, S_NHI + t])
        slot_f[keep, S_I] = slot_f[sa, S_I] + slot_f[sb, S_I]
        slot_id[keep] = new_id
        slot_of[a] = -1
        slot_of[b] = -1
        slot_of[new_id] = keep
        # Keep the leaf's active slots in front: its last active row fills the emptied slot, so a
        # search scans active slots only.
        leaf = slot_leaf[drop]
        last = leaf_start[leaf - info[I_FIRST_LEAF]] + node_cnt[leaf] - 1
        if last != drop:
            for t in range(SLOT_DATA):
                slot_f[drop, t] = slot_f[last, t]
            slot_id[drop] = slot_id[last]
            slot_of[slot_id[drop]] = drop
        slot_id[last] = -1
        k = leaf
        while k >= top:
            node_cnt[k] -= 1
            if k == 0:
                break
            k = (k - 1) >> 1


@njit(cache=True)
def kd_merge(kd, work, a, b, new_id, rebuild):
    """Replace active clusters a and b by their union ``new_id`` (see the module docstring).

    rebuild : rebuild the tree here when the active clusters have halved since the last build
    (False: the caller does, see :func:`kd_wants_rebuild`).
    """
    # The batch kernel with one pair (the same specialisation: int32 arrays).
    _merge_rows(kd, np.full(1, a, np.int32), np.full(1, b, np.int32), 0, 1, new_id, np.zeros(1, np.int32), 0, 1, 0)
    kd[8][I_ACTIVE] -= 1
    if rebuild and kd_wants_rebuild(kd):
        kd_build(kd, work)


# Merges of a batch whose two clusters lie in one subtree below the top levels touch only that
# subtree's slots and nodes, and the batch's new ids are distinct: such merges of different
# subtrees run in parallel (kd_merge_batch).
_BATCH_TOP = (1 << _TOP_LEVELS) - 1
KD_SUBTREES = 1 << _TOP_LEVELS


@njit(cache=True)
def kd_subtree_starts(kd):
    """(KD_SUBTREES,) int64: the first slot of each subtree below the top levels (a subtree's leaves,
    hence its slots, are contiguous), or all -1 if the tree has no level below them. The subtree of
    active cluster a is then the number of t >= 1 with ``slot_of[a] >= starts[t]`` (-1 without
    levels): the caller counts it inline, since a call taking the kd tuple costs a reference-count
    update per array (24 atomic operations), several times the count itself."""
    starts = np.full(KD_SUBTREES, -1, np.int64)
    first_leaf = kd[8][I_FIRST_LEAF]
    if first_leaf >= _BATCH_TOP:
        step = (first_leaf + 1) // KD_SUBTREES
        for t in range(KD_SUBTREES):
            starts[t] = kd[7][t * step]
    return starts


def kd_subtree(kd, a) -> int:
    """The subtree (0 .. KD_SUBTREES - 1) below the top levels that holds active cluster a, or -1 if
    the tree has no level below them: from Python (kernels count it inline, see
    :func:`kd_subtree_starts`)."""
    starts = kd_subtree_starts(kd)
    return -1 if starts[0] < 0 else int(np.count_nonzero(kd[2][a] >= starts[1:]))


@njit(cache=True, nogil=True)
def kd_merge_batch(kd, left, right, new0, n_pairs, pair_sub, s, e):
    """Merges ``left[new0 + p], right[new0 + p] -> new0 + p`` of the batch's pairs p with
    ``pair_sub[p]`` in [s, e) (their subtree, :func:`kd_subtree`), in batch order; the counts of the
    top levels and ``info`` wait for :func:`kd_merge_batch_finish`."""
    _merge_rows(kd, left, right, new0, n_pairs, new0, pair_sub, s, e, _BATCH_TOP)


@njit(cache=True)
def kd_merge_batch_finish(kd, left, right, new0, n_pairs, pair_sub):
    """After :func:`kd_merge_batch` over every subtree: the batch's other merges (pair_sub -1), in
    order, then the counts of the top levels and ``info``."""
    node_cnt = kd[6]
    top = _BATCH_TOP if kd[8][I_FIRST_LEAF] >= _BATCH_TOP else 0
    _merge_rows(kd, left, right, new0, n_pairs, new0, pair_sub, -1, 0, top)
    if top > 0:
        for k in range(top - 1, -1, -1):
            node_cnt[k] = node_cnt[2 * k + 1] + node_cnt[2 * k + 2]
    kd[8][I_ACTIVE] -= n_pairs


@njit(cache=True)
def kd_wants_rebuild(kd):
    """Whether the active clusters have halved since the last (re)build."""
    info = kd[8]
    return 2 * info[I_ACTIVE] <= info[I_BUILT] and info[I_ACTIVE] > 1


@njit(cache=True, nogil=True)
def kd_scratch(kd):
    """The tree ``kd`` with its own traversal stack and leaf buffer, for a search on another thread."""
    return (kd[0], kd[1], kd[2], kd[3], kd[4], kd[5], kd[6], kd[7], kd[8], np.empty(kd[9].shape[0], np.int64),
            np.empty(kd[10].shape[0]), np.empty(kd[11].shape[0]))


@njit(cache=True)
def _best_matches_after(position, normal, luminance, merges, metric_id, has_cone, use_cone, c, leafsize, grouped):
    n = position.shape[0]
    kd, work = kd_new(position, normal, luminance, np.arange(position.shape[0]), leafsize)
    kd_build(kd, work)
    for m in range(merges.shape[0]):
        kd_merge(kd, work, merges[m, 0], merges[m, 1], n + m, True)
    active = np.flatnonzero(kd[2] >= 0)
    best = np.empty(active.shape[0], np.int64)
    best_d = np.empty(active.shape[0])
    if grouped:
        todo = active.copy()
        kd_group_by_leaf(kd, todo, todo.shape[0], np.empty(todo.shape[0], np.int64))
        by_id = np.full(2 * n - 1, -1, np.int32)
        by_id_d = np.empty(2 * n - 1)
        kd_search_range(kd, todo, todo.shape[0], by_id, by_id_d, metric_id, has_cone, use_cone, c, 64,
                        np.zeros(1, np.int64))
        for i in range(active.shape[0]):
            best[i] = by_id[active[i]]
            best_d[i] = by_id_d[active[i]]
        return active, best, best_d
    for i in range(active.shape[0]):
        best[i], best_d[i] = kd_best_match(kd, active[i], metric_id, has_cone, use_cone, c)
    return active, best, best_d


def best_matches_after_merges(position, normal, luminance, has_cone: bool, metric, c: float,
                              merges=None, leafsize: int = LEAF_SIZE, grouped: bool = False):
    """findBestMatch through the kd-tree for every active cluster after a sequence of merges.

    A diagnostic of the search (the tests compare it with a brute-force scan).
    position, normal : (N, 3) float64; luminance : (N,) float64
    has_cone : True for oriented lights; metric : a built-in Metric; c : cone-term scale
    merges : (M, 2) int cluster ids merged in order; merge m creates cluster N + m
    leafsize : clusters per kd leaf
    grouped : search the clusters of each leaf together (:func:`kd_search_range`), as the
        locally-ordered builder does, instead of one by one (:func:`kd_best_match`)
    Returns ``(active, best, d)``: (K,) int64 active cluster ids, their best matches and the metric values.
    """
    position = np.ascontiguousarray(position, np.float64)
    merges = np.zeros((0, 2), np.int64) if merges is None else np.ascontiguousarray(merges, np.int64)
    return _best_matches_after(position, np.ascontiguousarray(normal, np.float64),
                               np.ascontiguousarray(luminance, np.float64), merges, int(metric.id), bool(has_cone),
                               bool(has_cone and metric.uses_cone), float(c), int(leafsize), bool(grouped))
