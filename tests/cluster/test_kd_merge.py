"""Merging clusters in the kd-tree (``lightcuts/cluster/kd_merge.py``).

Properties:
- a merge writes A u B (union boxes, summed intensity) into the slot of whichever of A, B has its
  centre nearer C's, removes A and B, and keeps every leaf dense and every count right;
- node bounds are left in place and stay valid (loose) for every cluster under each node;
- a tree after merges answers every search (one cluster or grouped) as a tree built afresh over its
  active clusters does;
- a rebuild happens exactly when the active clusters have halved, and gives the tree built afresh
  over the active clusters, array for array;
- a batch of merges (a round's: those within one subtree below the top levels, then the others)
  leaves every cluster in the same leaf, with the same counts, as the same merges one at a time;
  kd_subtree names the subtree below the top levels that holds a cluster.
"""

from __future__ import annotations

import numpy as np
import pytest

from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_group_search import kd_group_by_leaf, kd_search_range
from lightcuts.cluster.kd_merge import (kd_merge, kd_merge_batch, kd_merge_batch_finish, kd_subtree,
                                        kd_wants_rebuild)
from lightcuts.cluster.kd_search import kd_best_match
from lightcuts.cluster.kd_tree import (I_ACTIVE, I_BUILT, I_FIRST_LEAF, KD_SUBTREES, N_AXIS, N_SPLIT, S_HI, S_LO,
                                       SLOT_DATA, TOP_LEVELS)

from cluster_oracles import (C, METRIC_CASES, Clusters, active, check_node_bounds, check_storage, leaves,
                             random_items, uses_cone)


def start(n, seed, leafsize, kind="random"):
    rng = np.random.default_rng(seed)
    lo, hi, normal, intensity = random_items(n, rng, kind)
    order = rng.permutation(n)
    kd, work = kd_new(lo, hi, normal, intensity, order, leafsize)
    kd_build(kd, work)
    return rng, kd, work, Clusters(lo, hi, normal, intensity, order)


def centre(kd, s):
    return 0.5 * (kd.slot_f[s, S_LO:S_LO + 3] + kd.slot_f[s, S_HI:S_HI + 3])


@pytest.mark.parametrize("kind", ["random", "duplicates"])
def test_a_merge_takes_the_nearer_slot_and_keeps_the_tree_valid(kind):
    rng, kd, work, cl = start(70, 1, 3, kind)
    while len(cl.alive) > 1:
        a, b = cl.random_pair(rng)
        sa, sb = int(kd.slot_of[a]), int(kd.slot_of[b])
        ca, cb = centre(kd, sa), centre(kd, sb)
        new = cl.merge(a, b)
        cc = 0.5 * (cl.lo[new] + cl.hi[new])
        kd_merge(kd, work, a, b, new, False)
        assert kd.slot_of[a] == kd.slot_of[b] == -1
        assert kd.slot_of[new] == (sa if ((ca - cc) ** 2).sum() <= ((cb - cc) ** 2).sum() else sb)
        check_storage(kd, cl)
        if len(cl.alive) % 9 == 0:
            check_node_bounds(kd, cl, exact=False)
    check_node_bounds(kd, cl, exact=False)


@pytest.mark.parametrize("metric_id,has_cone", METRIC_CASES)
def test_after_merges_searches_answer_as_a_fresh_tree(metric_id, has_cone):
    rng, kd, work, cl = start(120, 2 + metric_id, 4)
    for _ in range(55):  # 65 left: no rebuild yet, every bound left loose by the merges
        a, b = cl.random_pair(rng)
        kd_merge(kd, work, a, b, cl.merge(a, b), True)
    assert kd.info[I_BUILT] == 120
    ids = active(kd)
    fresh, _ = cl.fresh_kd(ids, 4)
    use_cone = uses_cone(metric_id, has_cone)
    answers = []
    for tree, own in ((kd, ids), (fresh, np.arange(len(ids)))):
        best = np.full(2 * len(tree.slot_id), -1, np.int32)
        best_d = np.full(len(best), np.nan)
        todo = own.copy()
        kd_group_by_leaf(tree, todo, len(todo), np.empty(len(todo), np.int64))
        kd_search_range(tree, todo, len(todo), best, best_d, metric_id, has_cone, use_cone, C, 8,
                        np.zeros(1, np.int64))
        # Answers in the merged tree's ids (the fresh tree's cluster j is ids[j]).
        rename = (lambda b: b) if tree is kd else (lambda b: ids[b])
        one = [kd_best_match(tree, a, metric_id, has_cone, use_cone, C) for a in own]
        answers.append([(rename(b), d, rename(best[a]), best_d[a]) for a, (b, d) in zip(own, one)])
    # The same minimum; the same partner unless several tie (the surface area ignores intensity: a
    # cluster inside a large query's box ties with every other one inside it).
    d = cl.costs(ids, metric_id, has_cone)
    unique = (d == d.min(1, keepdims=True)).sum(1) == 1
    assert unique.mean() > 0.5
    for u, (b0, d0, g0, gd0), (b1, d1, g1, gd1) in zip(unique, *answers):
        assert d0 == d1 == gd0 == gd1
        assert not u or b0 == b1 == g0 == g1


def test_rebuild_when_halved_is_the_fresh_build():
    rng, kd, work, cl = start(150, 3, 4)
    rebuilt = 0
    while len(cl.alive) > 1:
        built = int(kd.info[I_BUILT])
        a, b = cl.random_pair(rng)
        kd_merge(kd, work, a, b, cl.merge(a, b), False)
        k = len(cl.alive)
        assert kd_wants_rebuild(kd) == (2 * k <= built and k > 1)
        if not kd_wants_rebuild(kd):
            continue
        # The rebuild compacts the active slots in slot order: the fresh tree gets them so.
        ids = kd.slot_id[:built][kd.slot_id[:built] >= 0].astype(np.int64)
        kd_build(kd, work)
        rebuilt += 1
        assert kd.info[I_BUILT] == kd.info[I_ACTIVE] == k
        fresh, _ = cl.fresh_kd(ids, 4)
        first_leaf = int(fresh.info[I_FIRST_LEAF])
        m = 2 * first_leaf + 1
        np.testing.assert_array_equal(kd.info, fresh.info)
        np.testing.assert_array_equal(kd.slot_id[:k], ids[fresh.slot_id[:k]])
        np.testing.assert_array_equal(kd.slot_f[:k, :SLOT_DATA], fresh.slot_f[:k, :SLOT_DATA])
        np.testing.assert_array_equal(kd.slot_leaf[:k], fresh.slot_leaf[:k])
        np.testing.assert_array_equal(kd.leaf_start[:first_leaf + 2], fresh.leaf_start[:first_leaf + 2])
        np.testing.assert_array_equal(kd.node_cnt[:m], fresh.node_cnt[:m])
        np.testing.assert_array_equal(kd.node_n[:m], fresh.node_n[:m])
        # Node rows: the bounds; splits and axes of the internal nodes (leaves never write theirs).
        np.testing.assert_array_equal(kd.node_s[:m, :N_SPLIT], fresh.node_s[:m, :N_SPLIT])
        np.testing.assert_array_equal(kd.node_s[:first_leaf, N_SPLIT:N_AXIS + 1],
                                      fresh.node_s[:first_leaf, N_SPLIT:N_AXIS + 1])
        check_storage(kd, cl)
        check_node_bounds(kd, cl, exact=True)
    assert rebuilt >= 5


def subtree_of(kd, c):
    """The subtree below the top TOP_LEVELS levels that holds cluster c: its leaf's ancestor at that
    depth, numbered from 0 (-1 if the tree has no deeper level)."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    if first_leaf < (1 << TOP_LEVELS) - 1:
        return -1
    k = int(kd.slot_leaf[kd.slot_of[c]])
    while k >= (1 << (TOP_LEVELS + 1)) - 1:
        k = (k - 1) // 2
    return k - ((1 << TOP_LEVELS) - 1)


@pytest.mark.parametrize("n,leafsize", [(400, 4), (60, 8), (20, 8)])
def test_a_batch_is_the_same_merges_one_at_a_time(n, leafsize):
    # (60, 8): exactly TOP_LEVELS levels, the subtrees are leaves; (20, 8): fewer levels, no subtree.
    rng, kd, work, cl = start(n, 4, leafsize)
    one, work1 = kd_new(cl.lo[:n], cl.hi[:n], cl.nlo[:n], cl.inten[:n], np.arange(n), leafsize)
    kd_build(one, work1)
    left = np.full(2 * n - 1, -1, np.int32)
    right = np.full(2 * n - 1, -1, np.int32)
    pair_sub = np.empty(n, np.int32)
    kinds = set()
    while True:
        # Rounds until half the clusters are left (then the builders rebuild).
        limit = len(cl.alive) - n // 2 - 1
        if limit <= 0:
            break
        ids = active(kd)
        for c in ids:
            assert kd_subtree(kd, c) == subtree_of(kd, c)
        # Neighbours in slot order (mostly within a subtree) and a few random pairs (mostly not).
        by_slot = ids[np.argsort(kd.slot_of[ids])]
        near = by_slot[:len(by_slot) // 4 * 2].reshape(-1, 2)
        rest = rng.permutation(by_slot[len(near) * 2:])
        pairs = np.concatenate([near, rest[:min(len(rest) // 2, 6) * 2].reshape(-1, 2)])
        pairs = pairs[:limit]
        new0 = cl.next
        for p, (a, b) in enumerate(pairs):
            left[new0 + p], right[new0 + p] = a, b
            sa, sb = kd_subtree(kd, a), kd_subtree(kd, b)
            pair_sub[p] = sa if sa == sb else -1
            kinds.add(bool(pair_sub[p] >= 0))
        kd_merge_batch(kd, left, right, new0, len(pairs), pair_sub, 0, KD_SUBTREES)
        kd_merge_batch_finish(kd, left, right, new0, len(pairs), pair_sub)
        for a, b in pairs:
            kd_merge(one, work1, a, b, cl.merge(a, b), False)
        check_storage(kd, cl)
        check_storage(one, cl)
        np.testing.assert_array_equal(kd.node_cnt, one.node_cnt)
        np.testing.assert_array_equal(kd.info, one.info)
        for (leaf, s0, cnt), (leaf1, s1, cnt1) in zip(leaves(kd), leaves(one)):
            assert sorted(kd.slot_id[s0:s0 + cnt]) == sorted(one.slot_id[s1:s1 + cnt1]), leaf
    assert kinds == ({False} if n == 20 else {True, False})
