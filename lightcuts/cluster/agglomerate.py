r"""The clustering engine: fast agglomerative clustering (Walter, Bala, Kulkarni, Pingali, "Fast
Agglomerative Clustering for Rendering", IEEE Symposium on Interactive Ray Tracing 2008), one
implementation of the locally-ordered algorithm (Fig. 4) and of the heap-based one (Fig. 3) for every
hierarchy the project builds: light trees (``lightcuts.trees.agglomerative``, items = lights, their
boxes points) and BVHs (``lightcuts.accel.bvh.bvh_agglomerative``, items = triangles, their boxes).

The dissimilarity is pluggable: a built-in id of :mod:`lightcuts.cluster.dissimilarity` (the light
metrics, the surface area of the union box), with its lower bound over a kd node
(:mod:`lightcuts.cluster.kd_search`). Both merge, bottom-up, pairs of clusters that are each other's
best match under d(A u B), finding best matches with the kd-tree of :mod:`lightcuts.cluster.kd_tree`.
With a non-decreasing dissimilarity (the paper's eq. 1, e.g. the surface area) both build the greedy
tree (Fig. 2) up to ties; with box-of-normals cones the light metrics are not monotone, and the tree
may differ from the greedy one in a few clusters (docs/math.md, "Non-decreasing metrics").

:func:`agglomerate` -- locally-ordered clustering (Fig. 4: merge A and B as soon as each is the
other's best match), run in rounds so that its searches can share the cores::

    search best(A) for every cluster
    while more than one cluster:
        for each pair A, B = best(A) with d(A u B) <= d(B u best(B)):   # the tie rule of section 3.2
            merge(A, B)
        search best(X) for each new cluster X, and each X whose best match was merged

Why these rounds build Fig. 4's tree: docs/math.md, "Rounds of mutual best matches". A
round's searches only read the kd-tree and each writes its own cluster's answer, so they run on the
numba threads, the clusters of one kd leaf together
(:func:`~lightcuts.cluster.kd_group_search.kd_search_range`); the pairs are chosen on one thread in
a fixed order, which numbers the nodes; the kd-tree merges them, those within one subtree below its top
levels on the threads (:func:`~lightcuts.cluster.kd_merge.kd_merge_batch`). The tree does not depend
on the thread count. Each cluster keeps a list of the clusters whose best match it is, so a merge
finds whom to search again without a scan.

``agglomerate(..., heap=True)`` -- the heap-based version (Fig. 3), on one thread as in the paper:
every cluster's best match in a binary min-heap keyed on (d, cluster id); pop the smallest; skip it
if its cluster was merged away; search again and push it if its partner was; merge otherwise and
push the new cluster's best match.

Both kernels run on the items sorted along a Morton curve of their box centres
(:func:`~lightcuts.cluster.morton.morton_order`), so that clusters near each other in space have
nearby ids and the per-cluster arrays stay in cache; the leaves are relabelled to item ids at the
end. Only the ids among tied clusters depend on that order. No call inside a per-cluster or
per-pair loop takes the KdTree: each would cost an atomic reference-count update per array
(docs/performance.md, "Reference counting").

Node ids of the returned topology: leaves 0..N-1 are items 0..N-1, merge m makes node N + m, the
root is 2N - 2.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.kd_build import kd_build, kd_build_threaded, kd_new
from lightcuts.cluster.kd_group_search import kd_group_by_leaf, kd_search_range
from lightcuts.cluster.kd_merge import (kd_merge, kd_merge_batch, kd_merge_batch_finish, kd_subtree_starts,
                                        kd_wants_rebuild)
from lightcuts.cluster.kd_search import kd_best_match
from lightcuts.cluster.kd_tree import KD_SUBTREES, LEAF_SIZE
from lightcuts.cluster.morton import morton_order
from lightcuts.errors import LightcutsError
from lightcuts.parallel import on_counter, on_threads


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
def _leaves_to_items(left, right, order):
    """Relabel leaf children (cluster i < N) as item ``order[i]``."""
    n = order.shape[0]
    for m in range(n, left.shape[0]):
        if left[m] < n:
            left[m] = order[left[m]]
        if right[m] < n:
            right[m] = order[right[m]]


@njit(cache=True)
def _leaf_ids(n):
    """(2N-1,) int32 item per node: leaves 0..N-1 are clusters 0..N-1, -1 elsewhere (relabelled later)."""
    light = np.full(2 * n - 1, -1, np.int32)
    # A loop, not a slice assignment: numba's slice-shape error path costs seconds of compilation.
    for i in range(n):
        light[i] = i
    return light


# Entries of the locally-ordered builder's counters array.
C_NEXT, C_SEARCHES, C_ROUNDS = 0, 1, 2


def _rounds_start(lo, hi, normal, intensity, order, leafsize):
    """The locally-ordered builder's state, its kd-tree not built yet (the caller builds it, on the
    threads, and fills ``todo``). Plain Python around :func:`~lightcuts.cluster.kd_build.kd_new`, so
    that kd_new is compiled once (docs/performance.md, "chunks, cold compilation").

    Returns ``(kd, work, todo, todo_next, best, best_d, head, nxt, left, right, pair_sub, counters)``:
    todo, todo_next : (N,) int64 clusters to search this round, and the next round's; best, best_d :
        (2N-1,) int32 each cluster's last best match (-1: none yet, -2: to search again, -3: the
        cluster is gone) and its float64 d; head, nxt : (2N-1,) int32 per cluster, the singly
        linked list of the clusters whose best match it is (-1 ends it); left, right : (2N-1,)
        int32 children; pair_sub : (N,) int32 a round's pairs' kd subtrees; counters : see ``C_*``.
    """
    n = lo.shape[0]
    k = 2 * n - 1
    kd, work = kd_new(lo, hi, normal, intensity, order, leafsize)
    todo = np.empty(n, np.int64)
    counters = np.zeros(3, np.int64)
    counters[C_NEXT] = n
    return (kd, work, todo, np.empty(n, np.int64), np.full(k, -1, np.int32), np.full(k, np.inf),
            np.full(k, -1, np.int32), np.full(k, -1, np.int32), np.full(k, -1, np.int32), np.full(k, -1, np.int32),
            np.empty(n, np.int32), counters)


@njit(cache=True, nogil=True)
def _pair_round(kd, todo, n_todo, todo_next, best, best_d, head, nxt, left, right, pair_sub, counters):
    """After the searches of ``todo[:n_todo]``: choose every pair the tie rule allows, numbered
    ``left[m], right[m] -> m`` from ``counters[C_NEXT]`` on, each with its kd subtree in
    ``pair_sub`` (the kd-tree merges them next, :func:`_merge_pairs`); returns the next round's
    count (its clusters written to ``todo``).

    A checked on B = best(A) merges when d(A u B) <= B's own best d. Only pairs with a cluster
    searched this round are checked: A searched, or B searched and A in B's list. Any other pair was
    checked with the same values when the later of its two was searched. A merge marks its two
    clusters gone (best -3) and queues the new cluster, and every cluster whose best match was one
    of the two (read off their lists).
    """
    k = left.shape[0]
    new = counters[C_NEXT]
    n_pairs = 0
    slot_of = kd.slot_of
    starts = kd_subtree_starts(kd)
    counters[C_SEARCHES] += n_todo
    counters[C_ROUNDS] += 1
    for i in range(n_todo):
        a = todo[i]
        b = best[a]
        if b >= 0:
            nxt[a] = head[b]
            head[b] = a
    count = 0
    for i in range(n_todo):
        searched = todo[i]
        # The searched cluster's own pair first, then the pairs of the clusters listing it. A gone,
        # queued or unsearched cluster has best < 0 (lists keep gone clusters: skipped here).
        a = searched
        z = np.int64(head[searched])
        while True:
            b = np.int64(best[a])
            if b >= 0 and best[b] >= 0 and best_d[a] <= best_d[b]:
                left[new] = a
                right[new] = b
                # The kd subtree of each (kd_subtree_starts), -1 if they differ or there are none.
                sa = np.int64(slot_of[a])
                sb = np.int64(slot_of[b])
                ja = 0
                jb = 0
                for t in range(1, KD_SUBTREES):
                    ja += sa >= starts[t]
                    jb += sb >= starts[t]
                pair_sub[n_pairs] = ja if ja == jb and starts[0] >= 0 else -1
                n_pairs += 1
                best[a] = -3
                best[b] = -3
                todo_next[count] = new
                count += 1
                new += 1
                for gone in (a, b):
                    y = np.int64(head[gone])
                    while y >= 0:
                        if best[y] == gone:
                            todo_next[count] = y
                            count += 1
                            best[y] = -2
                        y = np.int64(nxt[y])
                if new == k or best[searched] == -3:
                    break
            if z < 0:
                break
            a = z
            z = np.int64(nxt[z])
        if new == k:
            break
    for i in range(count):
        todo[i] = todo_next[i]
    counters[C_NEXT] = new
    return count


def _merge_pairs(kd, left, right, new0, n_pairs, pair_sub, parallel_min):
    """The kd-tree merges of a round's pairs (:func:`_pair_round`): those within one subtree below
    the kd-tree's top levels on the threads, a subtree per task, then the rest in order. The slots
    do not depend on the thread count."""
    if n_pairs >= parallel_min:
        on_threads(kd_merge_batch, KD_SUBTREES, 0, kd, left, right, new0, n_pairs, pair_sub)
    else:
        kd_merge_batch(kd, left, right, new0, n_pairs, pair_sub, 0, KD_SUBTREES)
    kd_merge_batch_finish(kd, left, right, new0, n_pairs, pair_sub)


def _locally_ordered(lo, hi, normal, intensity, order, metric_id, has_cone, use_cone, c, leafsize,
                     parallel_min, what):
    """Fig. 4 in rounds: ``(left, right, item, counters)``, leaves as cluster ids (Morton order);
    ``what`` : (subject, advice) of the error if a round merges nothing.

    Rounds of at least ``parallel_min`` searches split them over the numba threads. Each round is
    two kernel calls from here: a kernel running all rounds would compile the search a second time.
    """
    n = lo.shape[0]
    item = _leaf_ids(n)
    if n == 1:
        return np.full(1, -1, np.int32), np.full(1, -1, np.int32), item, np.zeros(3, np.int64)
    kd, work, todo, todo_next, best, best_d, head, nxt, left, right, pair_sub, counters = _rounds_start(
        lo, hi, normal, intensity, order, leafsize)
    kd_build_threaded(kd, work)
    # The first round searches the clusters in slot (kd-leaf) order, for locality.
    todo[:] = kd.slot_id
    n_todo = n
    while counters[C_NEXT] < left.shape[0]:
        on_counter(kd_search_range, n_todo, parallel_min, kd, todo, n_todo, best, best_d, metric_id, has_cone,
                   use_cone, c, SEARCH_CHUNK)
        new0 = int(counters[C_NEXT])
        n_todo = _pair_round(kd, todo, n_todo, todo_next, best, best_d, head, nxt, left, right, pair_sub, counters)
        if int(counters[C_NEXT]) == new0:
            raise LightcutsError(f"{what[0]}: a round merged no pair (a cost is infinite or NaN); {what[1]}")
        _merge_pairs(kd, left, right, new0, int(counters[C_NEXT]) - new0, pair_sub, parallel_min)
        # Between rounds, so that the rebuild runs on the threads too.
        if kd_wants_rebuild(kd):
            kd_build_threaded(kd, work)
        kd_group_by_leaf(kd, todo, n_todo, todo_next)
    return left, right, item, counters


@njit(cache=True, nogil=True)
def _agglomerate_heap(lo, hi, normal, intensity, order, metric_id, has_cone, use_cone, c, leafsize):
    """Fig. 3: ``(left, right, item, stats)``, leaves as cluster ids (Morton order); ``stats`` =
    [kd-tree searches, stale heap entries skipped]. Stops early, with ``left[2N-2] = -1``, if a
    search finds no partner (an infinite or NaN cost), which would otherwise repeat forever."""
    n = lo.shape[0]
    k = 2 * n - 1
    left = np.full(k, -1, np.int32)
    right = np.full(k, -1, np.int32)
    item = _leaf_ids(n)
    stats = np.zeros(2, np.int64)
    if n == 1:
        return left, right, item, stats
    kd, work = kd_new(lo, hi, normal, intensity, order, leafsize)
    kd_build(kd, work)
    slot_of = kd.slot_of
    new = np.int64(n)
    # Live entries never exceed the active clusters: each pop pushes at most one entry.
    hd = np.empty(n)
    ha = np.empty(n, np.int64)
    hb = np.empty(n, np.int64)
    size = np.int64(0)
    # In slot order (kd-leaf order) for memory locality; the tree does not change in this loop, so
    # the order does not change the result.
    slot_id = kd.slot_id
    for s in range(n):
        i = np.int64(slot_id[s])
        b, d = kd_best_match(kd, i, metric_id, has_cone, use_cone, c)
        size = _heap_push(hd, ha, hb, size, d, i, b)
    stats[0] += n
    while new < k:
        size, d, a, b = _heap_pop(hd, ha, hb, size)
        if slot_of[a] < 0:
            stats[1] += 1
            continue
        if b < 0:
            break
        if slot_of[b] < 0:
            b, d = kd_best_match(kd, a, metric_id, has_cone, use_cone, c)
            stats[0] += 1
            size = _heap_push(hd, ha, hb, size, d, a, b)
            continue
        left[new] = a
        right[new] = b
        kd_merge(kd, work, a, b, new, True)
        if new < k - 1:
            b, d = kd_best_match(kd, new, metric_id, has_cone, use_cone, c)
            stats[0] += 1
            size = _heap_push(hd, ha, hb, size, d, new, b)
        new += 1
    return left, right, item, stats


# Clusters of a round's todo list a search thread takes at a time from a shared counter
# (kd_search_range), so that a thread on a slower core does not hold up the round.
SEARCH_CHUNK = 512
# Rounds with fewer searches than this run on one thread (a round's thread start-up costs about as
# much as a few dozen searches; the last rounds are small and many).
PARALLEL_MIN = 2048


def agglomerate(lo, hi, normal, intensity, metric_id: int, has_cone: bool, use_cone: bool, c: float,
                heap: bool = False, leafsize: int = LEAF_SIZE, parallel_min: int = PARALLEL_MIN, order=None,
                what: tuple[str, str] = ("agglomerative clustering", "check the inputs' magnitudes")):
    """Agglomerative clustering of N items: ``(left, right, item, root, stats)``.

    lo, hi : (N, 3) float64 C-contiguous, each item's box (a light: its position twice);
    normal : (N, 3) float64 each item's unit normal (zeros without a cone); intensity : (N,) float64
    metric_id : a built-in dissimilarity (:mod:`lightcuts.cluster.dissimilarity`); has_cone : items
        have normals and a cone term; use_cone : compute the union's cone; c : cone-term scale
    heap : Fig. 3 on one thread, else Fig. 4 in rounds; leafsize : clusters per kd leaf (>= 1);
        parallel_min : the smallest round searched on several threads (the tree depends on neither,
        except among ties for the leaf size)
    order : (N,) int64 the items' cluster order, default :func:`morton_order` of the box centres
    what : (subject, advice) of the one-line error when a cost is infinite or NaN
    Returns int32 (2N-1,) ``left, right`` (-1 at leaves) and ``item`` (the item at a leaf, -1
    elsewhere; leaf i is item i), ``root = 2N - 2``, and ``stats``: ``searches`` (kd-tree
    findBestMatch searches) and ``rounds`` (locally ordered) or ``stale`` (heap: entries skipped
    because their cluster was gone).
    """
    if int(leafsize) < 1:
        raise ValueError(f"leafsize must be >= 1, got {leafsize}")
    n = len(lo)
    if order is None:
        order = morton_order(0.5 * (lo + hi))
    args = (lo, hi, normal, intensity, order, int(metric_id), bool(has_cone), bool(use_cone), float(c), int(leafsize))
    if heap:
        left, right, item, st = _agglomerate_heap(*args)
        if n > 1 and left[-1] < 0:
            raise LightcutsError(f"{what[0]}: a cluster found no partner (a cost is infinite or NaN); {what[1]}")
        stats = {"searches": int(st[0]), "stale": int(st[1])}
    else:
        left, right, item, st = _locally_ordered(*args, int(parallel_min), what)
        stats = {"searches": int(st[C_SEARCHES]), "rounds": int(st[C_ROUNDS])}
    _leaves_to_items(left, right, order)
    return left, right, item, 2 * n - 2, stats
