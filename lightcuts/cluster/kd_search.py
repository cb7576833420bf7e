r"""findBestMatch through the kd-tree (:mod:`lightcuts.cluster.kd_tree`): branch and bound.

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
(``tests/test_agglomerative.py`` checks it against a brute-force scan). :func:`kd_best_match`
searches one cluster; :func:`kd_search_range` searches a round's clusters, those of one kd leaf
together in one traversal (:func:`kd_search_groups`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import box_union, col3, row3, union_cone
from lightcuts.cluster.dissimilarity import metric_eval
from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_merge import kd_merge
from lightcuts.cluster.kd_tree import (I_FIRST_LEAF, I_LEAFSIZE, LEAF_SIZE, N_AXIS, N_EMIN, N_HMIN, N_IMIN, N_LMAX,
                                       N_SPLIT, NE_MIN, NH_MIN, NL_MAX, S_HI, S_I, S_LO, S_NHI, S_NLO, SLOT_DATA,
                                       SLOT_WIDTH, KdTree)
from lightcuts.parallel import next_task

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


@njit(cache=True)
def kd_node_bound(kd, a, k, metric_id, has_cone, use_cone, c):
    """The lower bound :func:`kd_best_match` uses for active cluster a against kd node k (with its
    cone part), as a float64: a diagnostic for the tests' check that it never exceeds d(A u B)."""
    sa = kd.slot_of[a]
    return _node_bound(kd.node_s, kd.node_n, k, row3(kd.slot_f, sa, S_LO), row3(kd.slot_f, sa, S_HI),
                       row3(kd.slot_f, sa, S_NLO), row3(kd.slot_f, sa, S_NHI), kd.slot_f[sa, S_I], metric_id,
                       has_cone, use_cone, c, np.inf)


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
    One call for many groups: a call taking the KdTree costs a reference-count update per array,
    atomic operations that the threads of a round would contend for. Scratch, with ``kd`` a thread's own
    (:func:`kd_scratch`): gq (SLOT_WIDTH, >= g1 - g0) float64, the members' rows as columns; gb, gd,
    mb (>= g1 - g0,) int64, float64, float64; lt (S_I + 1, leaf size) float64, a leaf's boxes and
    intensities as columns.

    The members' searches share their node bounds: a node is opened unless it bounds d(A u B) from
    below for every member A at once, by the kd-tree's bound with A's box replaced by the group's
    ``hi >= min hi``, ``lo <= max lo``, ``extent >= min extent`` (and the same for the normal boxes;
    docs/math.md, "Groups"), against the largest best d of the group. A leaf it reaches costs
    each member whose own bound does not prune it one scan; the leaf's boxes are copied as columns
    once for those scans, so that their first pass reads consecutive values and vectorises.
    """
    slot_f, slot_id, slot_of, slot_leaf = kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf
    node_s, node_n, node_cnt, leaf_start, info = kd.node_s, kd.node_n, kd.node_cnt, kd.leaf_start, kd.info
    stack_node, stack_lb, dbuf = kd.stack_node, kd.stack_lb, kd.dbuf
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
                    qlo = col3(gq, S_LO, m)
                    qhi = col3(gq, S_HI, m)
                    qnlo = col3(gq, S_NLO, m)
                    qnhi = col3(gq, S_NHI, m)
                    qi = gq[S_I, m]
                    for i in range(cnt):
                        dbuf[i] = _pair_box_d(metric_id, has_cone, c, qlo, qhi, qi, col3(lt, S_LO, i),
                                              col3(lt, S_HI, i), lt[S_I, i])
                    # As in kd_best_match: the cone term for the survivors of the first pass.
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
                                        row3(slot_f, s, S_HI), row3(slot_f, s, S_NLO), row3(slot_f, s, S_NHI),
                                        slot_f[s, S_I])
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
    slot_of = kd.slot_of
    slot_leaf = kd.slot_leaf
    first_leaf = kd.info[I_FIRST_LEAF]
    count = np.zeros(kd.leaf_start.shape[0], np.int64)
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
    cap = kd.info[I_LEAFSIZE]
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
def kd_scratch(kd):
    """The KdTree ``kd`` with its own traversal stack and leaf buffer, for a search on another thread."""
    return KdTree(kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf, kd.node_s, kd.node_n, kd.node_cnt, kd.leaf_start,
                  kd.info, np.empty(kd.stack_node.shape[0], np.int64), np.empty(kd.stack_lb.shape[0]),
                  np.empty(kd.dbuf.shape[0]))


@njit(cache=True)
def _best_matches_after(position, normal, luminance, merges, metric_id, has_cone, use_cone, c, leafsize, grouped):
    n = position.shape[0]
    kd, work = kd_new(position, position, normal, luminance, np.arange(position.shape[0]), leafsize)
    kd_build(kd, work)
    for m in range(merges.shape[0]):
        kd_merge(kd, work, merges[m, 0], merges[m, 1], n + m, True)
    active = np.flatnonzero(kd.slot_of >= 0)
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
