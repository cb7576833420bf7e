r"""The greedy agglomerative clustering (Walter et al. 2008, Fig. 2): the oracle of the fast loops.

At every step, merge the pair of active clusters whose union has the smallest cost; ties are
broken by the smaller cluster id, then the larger one, i.e. the pair with the smallest key

    (d(A u B), min(id_A, id_B), max(id_A, id_B)).

Cluster ids: item i is cluster i; the cluster made by the m-th merge (m = 0, 1, ...) is N + m, so
the root is 2N - 2. Each cluster caches its best partner (smallest key among the other active
clusters); after a merge, only clusters whose partner disappeared are searched again, and every
other cluster compares its cached partner with the new cluster. That is exactly the global minimum
at every step (O(N^2) time for typical inputs, O(N^3) at worst). For N up to a few thousand.

A cluster's union with another is described as the cost sees it: the union of the item boxes, the
cone of the union of the normal boxes (Walter 2008, section 5), the sum of the intensities. One
implementation for every hierarchy: the ``greedy`` light-tree builder (:mod:`lightcuts.trees.greedy`,
any metric) and the BVH reference (:func:`lightcuts.accel.bvh.bvh_agglomerative.bvh_greedy_reference`,
the surface area).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

from lightcuts.cluster.bounds import box_union, row3, set_row3, union_cone


@njit
def _union_cost(cost, has_cone, c, lum, lo, hi, nlo, nhi, a, b):
    """Metric of the union of clusters a and b."""
    ulo, uhi = box_union(row3(lo, a, 0), row3(hi, a, 0), row3(lo, b, 0), row3(hi, b, 0))
    cone_cos = -1.0
    if has_cone:
        cone_cos = union_cone(row3(nlo, a, 0), row3(nhi, a, 0), row3(nlo, b, 0), row3(nhi, b, 0))[3]
    return cost(lum[a] + lum[b], ulo[0], ulo[1], ulo[2], uhi[0], uhi[1], uhi[2], cone_cos, has_cone, c)


@njit
def _less(d1, a1, b1, d2, a2, b2):
    """Key order (d, smaller id, larger id); a <= b in both pairs."""
    if d1 != d2:
        return d1 < d2
    if a1 != a2:
        return a1 < a2
    return b1 < b2


@njit
def _find_best(cost, has_cone, c, lum, lo, hi, nlo, nhi, active, count, a, best, best_d):
    """Search all active clusters for a's partner; store it in best[a], best_d[a]."""
    bj = -1
    bd = np.inf
    for t in range(count):
        j = active[t]
        if j == a:
            continue
        d = _union_cost(cost, has_cone, c, lum, lo, hi, nlo, nhi, a, j)
        if bj < 0 or _less(d, min(a, j), max(a, j), bd, min(a, bj), max(a, bj)):
            bj = j
            bd = d
    best[a] = bj
    best_d[a] = bd


# The metric is a first-class function argument of this fixed type, so one compiled (and cached)
# kernel serves every metric, built-in or user; a plain dispatcher argument would compile (uncached)
# per metric.
_COST = types.FunctionType(types.float64(*([types.float64] * 8), types.boolean, types.float64))
_I32 = types.int32[::1]


_SIGNATURE = types.Tuple((_I32, _I32, _I32))(_COST, types.boolean, types.float64, types.float64[:, ::1],
                                           types.float64[:, ::1], types.float64[:, ::1], types.float64[::1])
_kernel = None


def _greedy_kernel():
    """The compiled kernel, made on first use: the explicit signature (one specialisation for every
    metric, passed as a first-class function) would otherwise compile, or load from the cache, when
    the module is imported, and every run imports the built-in builders."""
    global _kernel
    if _kernel is None:
        _kernel = njit(_SIGNATURE, cache=True, nogil=True)(_greedy)
    return _kernel


def _greedy(cost, has_cone, c, box_lo, box_hi, normal, intensity):
    """Greedy clustering with cost(intensity, lo0..hi2, cone_cos, has_cone, c) of items with boxes
    ``box_lo``, ``box_hi`` (N, 3), normals (N, 3) and intensities (N,).

    Returns (left, right, item) as (2N-1,) int32 arrays; the root is 2N - 2.
    """
    n = box_lo.shape[0]
    k = 2 * n - 1
    left = np.full(k, -1, np.int32)
    right = np.full(k, -1, np.int32)
    light = np.full(k, -1, np.int32)
    lo = np.empty((k, 3))
    hi = np.empty((k, 3))
    nlo = np.empty((k, 3))
    nhi = np.empty((k, 3))
    lum = np.empty(k)
    for i in range(n):
        light[i] = i
        lo[i] = box_lo[i]
        hi[i] = box_hi[i]
        nlo[i] = normal[i]
        nhi[i] = normal[i]
        lum[i] = intensity[i]
    # Active cluster ids, unordered (removal swaps with the last); best partner per cluster id.
    active = np.arange(n)
    count = n
    best = np.full(k, -1, np.int64)
    best_d = np.full(k, np.inf)
    if n > 1:
        for i in range(n):
            _find_best(cost, has_cone, c, lum, lo, hi, nlo, nhi, active, count, i, best, best_d)
    for new in range(n, k):
        # The globally smallest key is the smallest cached one.
        a = -1
        for t in range(count):
            i = active[t]
            j = best[i]
            if a < 0 or _less(best_d[i], min(i, j), max(i, j), best_d[a], min(a, best[a]), max(a, best[a])):
                a = i
        b = best[a]
        left[new] = min(a, b)
        right[new] = max(a, b)
        ulo, uhi = box_union(row3(lo, a, 0), row3(hi, a, 0), row3(lo, b, 0), row3(hi, b, 0))
        set_row3(lo, new, 0, ulo)
        set_row3(hi, new, 0, uhi)
        ulo, uhi = box_union(row3(nlo, a, 0), row3(nhi, a, 0), row3(nlo, b, 0), row3(nhi, b, 0))
        set_row3(nlo, new, 0, ulo)
        set_row3(nhi, new, 0, uhi)
        lum[new] = lum[a] + lum[b]
        t = 0
        while t < count:
            if active[t] == a or active[t] == b:
                count -= 1
                active[t] = active[count]
            else:
                t += 1
        active[count] = new
        count += 1
        if count == 1:
            break
        _find_best(cost, has_cone, c, lum, lo, hi, nlo, nhi, active, count, new, best, best_d)
        for t in range(count - 1):
            i = active[t]
            if best[i] == a or best[i] == b:
                _find_best(cost, has_cone, c, lum, lo, hi, nlo, nhi, active, count, i, best, best_d)
            else:
                d = _union_cost(cost, has_cone, c, lum, lo, hi, nlo, nhi, i, new)
                j = best[i]
                # new > every other id, so (i, new) orders as (min = i, max = new).
                if _less(d, i, new, best_d[i], min(i, j), max(i, j)):
                    best[i] = new
                    best_d[i] = d
    return left, right, light


def greedy_cluster(cost, has_cone: bool, c: float, lo, hi, normal, intensity):
    """Greedy clustering of N items (see the module docstring): ``(left, right, item)``, (2N-1,) int32.

    cost : njit function ``cost(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)``, e.g.
        a dissimilarity of :mod:`lightcuts.cluster.dissimilarity`; has_cone : the items have
        normals and the cost a cone term (else cone_cos = -1); c : cone-term scale
    lo, hi : (N, 3) each item's box (a light: its position twice); normal : (N, 3) unit normals
        (zeros without a cone); intensity : (N,) scalar intensities
    Leaves 0..N-1 are items 0..N-1 (``item``: the item at a leaf, -1 elsewhere), the root is 2N - 2.
    """
    return _greedy_kernel()(cost, bool(has_cone), float(c), np.ascontiguousarray(lo, np.float64),
                            np.ascontiguousarray(hi, np.float64), np.ascontiguousarray(normal, np.float64),
                            np.ascontiguousarray(intensity, np.float64))
