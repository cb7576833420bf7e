r"""findBestMatch of one cluster through the kd-tree (:mod:`lightcuts.cluster.kd_tree`): branch and bound.

A search for cluster A visits A's own leaf first (its neighbours give a tight best d at once), then,
climbing to the root, each sibling subtree on the way, top-down with the child on A's side of the
split first. A node is opened only if its lower bound of d(A u B) over the clusters B under it is
below the best d so far: per axis the union's extent is bounded from the node's ``hmin``, ``lmax``,
``emin``, the intensity from ``imin``, and the cone from the same bound on the boxes of normals
(docs/math.md, "The kd-tree's lower bound"). A leaf is scanned in two passes: the metric
without its cone term for every slot (no branches, so the loads of all rows overlap), then the
full metric only for the slots the first pass does not prune.

Bounds may be loose, never too tight, including their rounding: a search returns exactly the
minimum of the metric as computed, among equal values the smallest cluster id it meets
(``tests/trees/test_agglomerative.py`` checks it against a brute-force scan). The heap builder
searches one cluster at a time with :func:`kd_best_match`; the rounds of the locally-ordered builder
search the clusters of one kd leaf together (:mod:`lightcuts.cluster.kd_group_search`), with the
bound and pair helpers of this module.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import box_union, row3, union_cone
from lightcuts.cluster.dissimilarity import metric_eval
from lightcuts.cluster.kd_tree import (I_FIRST_LEAF, N_AXIS, N_EMIN, N_HMIN, N_IMIN, N_LMAX, N_SPLIT, NE_MIN, NH_MIN,
                                       NL_MAX, S_HI, S_I, S_LO, S_NHI, S_NLO, KdTree)

# Added to the cone-cosine bound: exceeds cone_from_box's rounding except for boxes whose centre is
# within ~1e-7 of the origin, whose cones are near the full sphere anyway.
_COS_SLACK = 1e-9


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


@njit(cache=True, inline="always")
def _node_bound(node_s, node_n, k, qlo, qhi, qnlo, qnhi, qi, metric_id, has_cone, use_cone, c, best_d):
    """Lower bound of d(A u B) over the clusters B under kd node k, for the query A (box corners qlo,
    qhi, normal-box corners qnlo, qnhi as 3-tuples, intensity qi): the dissimilarity of the box whose
    extents are :func:`_union_extent` per axis, at the node's smallest intensity, and, with the cone
    (``use_cone``) and only if that does not reach ``best_d`` already, the widest cone allowed by the
    same bound on the boxes of normals. For the surface area this is at least the bound of Walter et
    al. 2008, section 4 (docs/math.md, "The kd-tree's lower bound")."""
    u0 = _union_extent(qlo[0], qhi[0], node_s[k, N_HMIN], node_s[k, N_LMAX], node_s[k, N_EMIN])
    u1 = _union_extent(qlo[1], qhi[1], node_s[k, N_HMIN + 1], node_s[k, N_LMAX + 1], node_s[k, N_EMIN + 1])
    u2 = _union_extent(qlo[2], qhi[2], node_s[k, N_HMIN + 2], node_s[k, N_LMAX + 2], node_s[k, N_EMIN + 2])
    intensity = qi + np.float64(node_s[k, N_IMIN])
    lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, 1.0, has_cone, c)
    if use_cone and lb < best_d:
        spread = max(
            _union_extent(qnlo[0], qnhi[0], node_n[k, NH_MIN], node_n[k, NL_MAX], node_n[k, NE_MIN]),
            _union_extent(qnlo[1], qnhi[1], node_n[k, NH_MIN + 1], node_n[k, NL_MAX + 1], node_n[k, NE_MIN + 1]),
            _union_extent(qnlo[2], qnhi[2], node_n[k, NH_MIN + 2], node_n[k, NL_MAX + 2], node_n[k, NE_MIN + 2]))
        lb = metric_eval(metric_id, intensity, 0.0, 0.0, 0.0, u0, u1, u2, _cone_cos_bound(spread), has_cone, c)
    return lb


@njit(cache=True, inline="always")
def _pair_box_d(metric_id, has_cone, c, qlo, qhi, qi, lo, hi, intensity):
    """d(A u B) without the cone term (a lower bound of it): A's box corners qlo, qhi (3-tuples) and
    intensity qi, B's lo, hi and intensity."""
    ulo, uhi = box_union(qlo, qhi, lo, hi)
    return metric_eval(metric_id, qi + intensity, ulo[0], ulo[1], ulo[2], uhi[0], uhi[1], uhi[2], 1.0, has_cone, c)


@njit(cache=True, inline="always")
def _pair_d(metric_id, has_cone, c, qlo, qhi, qnlo, qnhi, qi, lo, hi, nlo, nhi, intensity):
    """d(A u B) as the builders define it: the union box, the cone of the union's box of normals, the
    summed intensity; A's and B's box corners, normal-box corners (3-tuples) and intensities."""
    ulo, uhi = box_union(qlo, qhi, lo, hi)
    cos_half = union_cone(qnlo, qnhi, nlo, nhi)[3]
    return metric_eval(metric_id, qi + intensity, ulo[0], ulo[1], ulo[2], uhi[0], uhi[1], uhi[2], cos_half, has_cone,
                       c)


@njit(cache=True)
def kd_best_match(kd, a, metric_id, has_cone, use_cone, c):
    """findBestMatch(A): the active cluster B != A minimising d(A u B).

    kd : the KdTree (:func:`~lightcuts.cluster.kd_build.kd_new`); a : active cluster id;
        metric_id, has_cone : as for :func:`~lightcuts.cluster.dissimilarity.metric_eval`; use_cone :
        compute the union's cone (oriented lights and a metric with a cone term); c : cone-term scale.
    Returns ``(b, d)``; ``(-1, inf)`` if A is the only active cluster.

    d is the metric as the builders define it: union box, box-of-normals cone of the union, summed
    intensity. Among equal d the smallest id found wins; nodes whose bound equals the best d are
    pruned, so which of several tied clusters is returned depends on the tree.

    Reads the tree only, writing nothing but the traversal stack and leaf buffer in ``kd``, so
    searches on several threads need only their own copies of those three (:func:`kd_scratch`).
    The loop calls only scalar helpers or helpers inlined by numba: in numba an array passed to a
    called function costs two atomic reference-count updates per call.

    :func:`kd_search_groups` with a group of one finds the same, along the same traversal; this
    search stays beside it for the heap builder, which searches one cluster at a time, since a
    group's set-up (member rows, leaf columns, scratch) costs more than one search saves
    (docs/performance.md, "Grouped searches").
    """
    slot_f, slot_id, slot_of, slot_leaf = kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf
    node_s, node_n, node_cnt, leaf_start, info = kd.node_s, kd.node_n, kd.node_cnt, kd.leaf_start, kd.info
    stack_node, stack_lb, dbuf = kd.stack_node, kd.stack_lb, kd.dbuf
    first_leaf = info[I_FIRST_LEAF]
    sa = slot_of[a]
    qlo = row3(slot_f, sa, S_LO)
    qhi = row3(slot_f, sa, S_HI)
    qnlo = row3(slot_f, sa, S_NLO)
    qnhi = row3(slot_f, sa, S_NHI)
    qlo0, qlo1, qlo2 = qlo
    qhi0, qhi1, qhi2 = qhi
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
                lb = _node_bound(node_s, node_n, k, qlo, qhi, qnlo, qnhi, qi, metric_id, has_cone, use_cone, c,
                                 best_d)
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
            # Two passes over the leaf (see the module docstring).
            s0 = leaf_start[k - first_leaf]
            cnt = node_cnt[k]
            for i in range(cnt):
                s = s0 + i
                dbuf[i] = _pair_box_d(metric_id, has_cone, c, qlo, qhi, qi, row3(slot_f, s, S_LO),
                                      row3(slot_f, s, S_HI), slot_f[s, S_I])
            for i in range(cnt):
                d = dbuf[i]
                if d > best_d:
                    continue
                s = s0 + i
                b = slot_id[s]
                if b == a:
                    continue
                if use_cone:
                    d = _pair_d(metric_id, has_cone, c, qlo, qhi, qnlo, qnhi, qi, row3(slot_f, s, S_LO),
                                row3(slot_f, s, S_HI), row3(slot_f, s, S_NLO), row3(slot_f, s, S_NHI), slot_f[s, S_I])
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


@njit(cache=True, nogil=True)
def kd_scratch(kd):
    """The KdTree ``kd`` with its own traversal stack and leaf buffer, for a search on another thread."""
    return KdTree(kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf, kd.node_s, kd.node_n, kd.node_cnt, kd.leaf_start,
                  kd.info, np.empty(kd.stack_node.shape[0], np.int64), np.empty(kd.stack_lb.shape[0]),
                  np.empty(kd.dbuf.shape[0]))

