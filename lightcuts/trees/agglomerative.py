r"""Fast agglomerative builders (Walter, Bala, Kulkarni, Pingali, "Fast Agglomerative Clustering for
Rendering", IEEE Symposium on Interactive Ray Tracing 2008): ``agglomerative`` and
``agglomerative-heap``.

Both merge, bottom-up, pairs of clusters that are each other's best match under a metric d(A u B)
(:mod:`lightcuts.trees.metrics`), finding best matches with the kd-tree of
:mod:`lightcuts.trees.kdtree`. With a non-decreasing metric (eq. 1 of the paper: d(A u B) <=
d(A u C u B); true for omni and directional lights and for the surface-area metric) both build the
greedy tree (Fig. 2), up to ties. With box-of-normals cones the metric is not monotone (see
:mod:`lightcuts.trees.cones`): the builders still terminate and return a valid tree, which may
differ from the greedy one in a few clusters (``benchmarks/bench_agglomerative.py`` measures how
many).

``agglomerative`` -- locally-ordered clustering (Fig. 4)::

    A = any cluster; B = best(A)
    while more than one cluster:
        C = best(B)
        if C == A or d(A u B) <= d(B u C):   # the tie rule of section 3.2
            A = merge(A, B); B = best(A)
        else:
            A, B = B, C

Each step that does not merge strictly lowers d (C is B's best match and d(B u C) < d(A u B)), so
there are no cycles, even with a non-monotone metric or ties. The search for best(B) starts from the
known candidate A at d(A u B). The first A is drawn from ``seed``.

best(B) is answered without a search when B's last search is provably still right: its partner is
still active, and no cluster merged since can beat it, which :func:`~lightcuts.trees.kdtree.
kd_best_match` certifies with a lower bound that grows under union (for monotone metrics always; for
box-of-normals cones when no other cluster came within the cone-term bound). The answer is the one
a fresh search would give, up to ties. On indirect VPLs about 5% of best(B) calls are answered so:
most cached partners have been merged away by the time B is asked again.

``agglomerative-heap`` -- the heap-based version (Fig. 3): every cluster's best match in a binary
min-heap keyed on (d, cluster id); pop the smallest; skip it if its cluster was merged away;
recompute and push it again if its partner was; merge otherwise and push the new cluster's best
match.

Locality: indirect VPLs arrive in path order, scattered in space, so per-cluster arrays indexed by
light id would be read at random. The kernel runs on the lights sorted along a Morton (Z-order)
curve of their positions (:func:`morton_order`), where nearby clusters have nearby ids (about 5%
faster at 200K Cornell VPLs, 12% at 800K); the kd-tree reads the lights through that permutation and
the kernel relabels the leaves to light ids at the end. Only the ids among tied clusters depend on
the order, as with any relabelling.

Work (200K Cornell VPLs, oriented, walter2008): about 3.3 kd-tree searches per merge (1 for each new
cluster, 1 per chain step, 1.44 chain steps per merge, minus the cached answers); the searches are
about 85% of the time, the kd-tree (re)builds about 10%, the Morton order about 1%.

Node ids of the returned topology: leaves 0..N-1 are lights 0..N-1, merge m makes node N + m, the
root is 2N - 2. Both run single-threaded (the merge loop is sequential; the paper's heap version
also starts from one best-match search per light, which we keep sequential so that the two
algorithms compare like for like).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.trees.kdtree import LEAF_SIZE, kd_best_match, kd_merge, kd_new
from lightcuts.trees.metrics import Metric
from lightcuts.trees.registry import BUILDERS


@njit(cache=True)
def _heap_push(hd, ha, hb, size, d, a, b):
    """Add (d, a, b) to the binary min-heap of ``size`` entries keyed on (d, a); returns the new size.

    Keys are unique: a cluster has at most one live entry. Sifts a hole up with scalar compares (an
    array passed to a helper per compare would cost numba reference-count updates each time).
    """
    i = size
    while i > 0:
        p = (i - 1) >> 1
        if hd[p] < d or (hd[p] == d and ha[p] < a):
            break
        hd[i] = hd[p]
        ha[i] = ha[p]
        hb[i] = hb[p]
        i = p
    hd[i] = d
    ha[i] = a
    hb[i] = b
    return size + 1


@njit(cache=True)
def _heap_pop(hd, ha, hb, size):
    """Remove the smallest entry; returns ``(new size, d, a, b)`` of that entry."""
    top_d = hd[0]
    top_a = ha[0]
    top_b = hb[0]
    size -= 1
    d = hd[size]
    a = ha[size]
    b = hb[size]
    i = 0
    while True:
        m = 2 * i + 1
        if m >= size:
            break
        if m + 1 < size and (hd[m + 1] < hd[m] or (hd[m + 1] == hd[m] and ha[m + 1] < ha[m])):
            m += 1
        if d < hd[m] or (d == hd[m] and a < ha[m]):
            break
        hd[i] = hd[m]
        ha[i] = ha[m]
        hb[i] = hb[m]
        i = m
    hd[i] = d
    ha[i] = a
    hb[i] = b
    return size, top_d, top_a, top_b


@njit(cache=True)
def _leaves_to_lights(left, right, order):
    """Relabel leaf children (cluster i < N) as light ``order[i]``."""
    n = order.shape[0]
    for m in range(n, left.shape[0]):
        if left[m] < n:
            left[m] = order[left[m]]
        if right[m] < n:
            right[m] = order[right[m]]


@njit(cache=True)
def _agglomerate(position, normal, luminance, order, metric_id, has_cone, use_cone, c, start, leafsize, heap):
    """Both builders in one kernel (one compilation): Fig. 4 (``heap`` False) or Fig. 3 (True).

    Cluster i < N is light ``order[i]`` (:func:`morton_order`); ``start`` is a cluster id. Returns
    ``(left, right, light, stats)`` with leaves as light ids, the root being node 2N-2; ``stats`` = [kd-tree
    searches, chain steps without a merge (locally ordered) or stale heap entries skipped (heap),
    best matches answered from the cache (locally ordered)].
    """
    n = position.shape[0]
    k = 2 * n - 1
    left = np.full(k, -1, np.int32)
    right = np.full(k, -1, np.int32)
    light = np.full(k, -1, np.int32)
    # A loop, not a slice assignment: numba's slice-shape error path costs seconds of compilation.
    for i in range(n):
        light[i] = i
    stats = np.zeros(3, np.int64)
    if n == 1:
        return left, right, light, stats
    kd, work = kd_new(position, normal, luminance, order, leafsize)
    slot_of = kd[2]
    # Typed ids: a literal -1 would make numba compile a second specialisation of kd_best_match.
    none = np.int64(-1)
    new = np.int64(n)
    if not heap:
        # Each cluster's last search: partner, d, and the lower bound that proves the partner is
        # still the best match while both are active (see kd_best_match); -1: never searched.
        cached = np.full(k, -1, np.int64)
        cached_d = np.empty(k)
        cached_lb = np.empty(k)
        a = np.int64(start)
        b, d_ab, lb = kd_best_match(kd, a, none, np.inf, metric_id, has_cone, use_cone, c)
        stats[0] += 1
        cached[a] = b
        cached_d[a] = d_ab
        cached_lb[a] = lb
        while new < k:
            cc = cached[b]
            if cc >= 0 and slot_of[cc] >= 0 and cached_lb[b] >= cached_d[b]:
                d_bc = cached_d[b]
                stats[2] += 1
            else:
                cc, d_bc, lb = kd_best_match(kd, b, a, d_ab, metric_id, has_cone, use_cone, c)
                stats[0] += 1
                cached[b] = cc
                cached_d[b] = d_bc
                cached_lb[b] = lb
            # C is B's best match, so d(B u C) <= d(A u B); equality is the tie rule: merge.
            if cc == a or d_ab <= d_bc:
                left[new] = a
                right[new] = b
                kd_merge(kd, work, a, b, new)
                a = new
                new += 1
                if new < k:
                    b, d_ab, lb = kd_best_match(kd, a, none, np.inf, metric_id, has_cone, use_cone, c)
                    stats[0] += 1
                    cached[a] = b
                    cached_d[a] = d_ab
                    cached_lb[a] = lb
            else:
                a = b
                b = cc
                d_ab = d_bc
                stats[1] += 1
        _leaves_to_lights(left, right, order)
        return left, right, light, stats
    # Live entries never exceed the active clusters: each pop pushes at most one entry.
    hd = np.empty(n)
    ha = np.empty(n, np.int64)
    hb = np.empty(n, np.int64)
    size = np.int64(0)
    # In slot order (kd-leaf order) for memory locality; the tree does not change in this loop, so
    # the order does not change the result.
    slot_id = kd[1]
    for s in range(n):
        i = np.int64(slot_id[s])
        b, d, lb = kd_best_match(kd, i, none, np.inf, metric_id, has_cone, use_cone, c)
        size = _heap_push(hd, ha, hb, size, d, i, b)
    stats[0] += n
    while new < k:
        size, d, a, b = _heap_pop(hd, ha, hb, size)
        if slot_of[a] < 0:
            stats[1] += 1
            continue
        if slot_of[b] < 0:
            b, d, lb = kd_best_match(kd, a, none, np.inf, metric_id, has_cone, use_cone, c)
            stats[0] += 1
            size = _heap_push(hd, ha, hb, size, d, a, b)
            continue
        left[new] = a
        right[new] = b
        kd_merge(kd, work, a, b, new)
        if new < k - 1:
            b, d, lb = kd_best_match(kd, new, none, np.inf, metric_id, has_cone, use_cone, c)
            stats[0] += 1
            size = _heap_push(hd, ha, hb, size, d, new, b)
        new += 1
    _leaves_to_lights(left, right, order)
    return left, right, light, stats


def _arguments(position, normal, luminance, light_type: str, metric: Metric, c: float, name: str):
    """The kernels' arguments, in the one dtype combination they are compiled for."""
    if not getattr(metric, "builtin", False):
        raise LightcutsError(f"builder {name!r}: metric {metric.name!r} is a user metric; the kd-tree search "
                             "needs a lower bound, available for the built-in metrics only "
                             "(walter2008, walter2005, surface-area); use builder 'greedy' instead")
    position = np.ascontiguousarray(position, np.float64)
    normal = np.ascontiguousarray(normal, np.float64)
    luminance = np.ascontiguousarray(luminance, np.float64)
    if len(position) == 0:
        raise LightcutsError(f"builder {name!r}: no lights")
    has_cone = light_type == "oriented"
    return position, normal, luminance, int(metric.id), has_cone, bool(has_cone and metric.uses_cone), float(c)


@njit(cache=True)
def _spread3(v):
    """Spread the low 21 bits of v (uint64) to every third bit (Morton code interleave)."""
    v &= np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    return (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)


@njit(cache=True)
def _morton_keys(position, bits, index_bits):
    """(N,) uint64 keys: the Morton code of each position quantised to ``bits`` bits per axis over the
    bounding box, shifted left by ``index_bits``, or-ed with the light's index (unique keys)."""
    n = position.shape[0]
    lo = np.empty(3)
    scale = np.empty(3)
    top = np.float64((1 << bits) - 1)
    for t in range(3):
        vmin = np.inf
        vmax = -np.inf
        for i in range(n):
            vmin = min(vmin, position[i, t])
            vmax = max(vmax, position[i, t])
        lo[t] = vmin
        scale[t] = top / (vmax - vmin) if vmax > vmin else 0.0
    keys = np.empty(n, np.uint64)
    for i in range(n):
        code = np.uint64(0)
        for t in range(3):
            x = (position[i, t] - lo[t]) * scale[t]
            # Non-finite coordinates (refused before any tree is built) must not make the cast undefined.
            if not x >= 0.0:
                x = 0.0
            code |= _spread3(np.uint64(min(x, top))) << np.uint64(2 - t)
        keys[i] = (code << np.uint64(index_bits)) | np.uint64(i)
    return keys


def morton_order(position: np.ndarray) -> np.ndarray:
    """(N,) int64 permutation sorting the lights along a Z-order (Morton) curve of their positions.

    position : (N, 3) float64, quantised over its bounding box to as many bits per axis (at most 21) as
    fit in 64-bit keys beside the light index, which breaks ties (the order of the sort is unique, so
    any sort algorithm gives it). Lights that arrive in path order are scattered in space; in this
    order, clusters near each other in space have nearby ids, so the per-cluster arrays the builders
    index stay in cache.
    """
    n = len(position)
    index_bits = max(1, (n - 1).bit_length())
    bits = min(21, (64 - index_bits) // 3)
    keys = _morton_keys(np.ascontiguousarray(position, np.float64), bits, index_bits)
    keys.sort()
    return (keys & np.uint64((1 << index_bits) - 1)).astype(np.int64)


def agglomerative_stats(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int,
                        heap: bool = False, leafsize: int = LEAF_SIZE):
    """Either builder with its work counters: ``(left, right, light, root, stats)``.

    stats : dict with ``searches`` (kd-tree findBestMatch searches) and, for the locally-ordered
    builder, ``steps`` (chain steps without a merge) and ``cached`` (best matches answered from the
    cache), for the heap builder ``stale`` (entries skipped because their cluster was gone).
    leafsize : clusters per kd leaf (a tuning knob; results do not depend on it except among ties)
    """
    if int(leafsize) < 1:
        raise ValueError(f"leafsize must be >= 1, got {leafsize}")
    args = _arguments(position, normal, luminance, light_type, metric, c, "agglomerative-heap" if heap else
                      "agglomerative")
    n = len(args[0])
    start = int(np.random.default_rng(seed).integers(n))
    # Build over the lights in Morton order (cluster i = light order[i]); leaves come back as lights.
    order = morton_order(args[0])
    left, right, light, st = _agglomerate(*args[:3], order, *args[3:], int(np.flatnonzero(order == start)[0]),
                                          int(leafsize), bool(heap))
    stats = {"searches": int(st[0]), ("stale" if heap else "steps"): int(st[1])}
    if not heap:
        stats["cached"] = int(st[2])
    return left, right, light, 2 * n - 2, stats


@BUILDERS.register("agglomerative")
def agglomerative(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int):
    """Locally-ordered agglomerative clustering (Walter et al. 2008, Fig. 4); see the module docstring.

    position, normal : (N, 3) float64; luminance : (N,) float64 scalar intensity
    light_type : "omni", "oriented" (the only type with a cone term) or "directional"
    metric : a built-in Metric; c : cone-term scale, world units; seed : picks the first cluster
    Returns ``(left, right, light, root)`` over 2N-1 nodes (leaves 0..N-1, root 2N-2).
    """
    return agglomerative_stats(position, normal, luminance, light_type, metric, c, seed)[:4]


@BUILDERS.register("agglomerative-heap")
def agglomerative_heap(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int):
    """Heap-based agglomerative clustering (Walter et al. 2008, Fig. 3); see the module docstring.

    Same arguments and result as :func:`agglomerative`; deterministic, ``seed`` is unused.
    """
    return agglomerative_stats(position, normal, luminance, light_type, metric, c, seed, heap=True)[:4]
