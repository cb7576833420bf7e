r"""findBestMatch of a round's clusters through the kd-tree, those of one kd leaf together.

The locally-ordered builder's rounds (:mod:`lightcuts.cluster.agglomerate`) order their clusters by
kd leaf (:func:`kd_group_by_leaf`) and search each run in one leaf, a group, in one traversal
(:func:`kd_search_groups`): a node is opened unless the kd-tree's bound, with A's box replaced by
the group's, prunes it for every member at once (docs/math.md, "Groups"). Each member finds what
:func:`~lightcuts.cluster.kd_search.kd_best_match` finds (the same minimum d), with the same bound
and pair helpers. :func:`kd_search_range` is one thread's share of a round.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import col3, row3
from lightcuts.cluster.dissimilarity import metric_eval
from lightcuts.cluster.kd_search import _cone_cos_bound, _pair_box_d, _pair_d, _union_extent, kd_scratch
from lightcuts.cluster.kd_tree import (I_FIRST_LEAF, I_LEAFSIZE, N_AXIS, N_EMIN, N_HMIN, N_IMIN, N_LMAX, N_SPLIT,
                                       NE_MIN, NH_MIN, NL_MAX, S_HI, S_I, S_LO, S_NHI, S_NLO, SLOT_DATA, SLOT_WIDTH)
from lightcuts.parallel import next_task

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

