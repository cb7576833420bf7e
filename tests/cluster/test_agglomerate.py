"""The clustering loops (``lightcuts/cluster/agglomerate.py``): locally ordered (Fig. 4, in rounds) and
heap-based (Fig. 3), against the greedy oracle (Fig. 2, ``lightcuts/cluster/greedy.py``).

Properties, on random inputs without ties:
- every result is a binary tree over the N items: N - 1 merges, each node made from two earlier
  ones, every node but the root in exactly one parent, every item in exactly one leaf;
- with a non-decreasing dissimilarity (eq. 1: the surface area, the light metrics without a cone)
  the locally-ordered loop builds the greedy tree's clusters, and the heap loop the greedy tree
  node for node (it merges in the greedy order), at any kd leaf size, with rounds on the threads;
- neither the kd-tree's leaf size, the items' order nor the threads change the clusters, also with
  cones (where eq. 1 fails and the loops may differ from greedy);
- an infinite or NaN cost ends either loop with one LightcutsError naming the subject, not a hang.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster import dissimilarity
from lightcuts.cluster.agglomerate import agglomerate
from lightcuts.cluster.greedy import greedy_cluster
from lightcuts.errors import LightcutsError

from cluster_oracles import C, SURFACE_AREA, WALTER2005, WALTER2008, random_items

COST = {WALTER2008: dissimilarity.walter2008, WALTER2005: dissimilarity.walter2005,
        SURFACE_AREA: dissimilarity.surface_area}
#: (metric id, box half-size): non-decreasing dissimilarities without a cone, on boxes and points.
MONOTONE = [(SURFACE_AREA, 0.05), (WALTER2008, 0.0), (WALTER2005, 0.05)]


def items(n, seed, spread, oriented=False):
    lo, hi, normal, intensity = random_items(n, np.random.default_rng(seed), "random", spread)
    return lo, hi, normal if oriented else np.zeros_like(normal), intensity


def members(left, right, n):
    """Each node's cluster as a frozenset of items (children before parents)."""
    out = [frozenset([i]) for i in range(n)] + [None] * (n - 1)
    for m in range(n, 2 * n - 1):
        out[m] = out[left[m]] | out[right[m]]
    return out


def check_tree(left, right, item, root, n):
    k = 2 * n - 1
    assert root == k - 1 and left.shape == right.shape == item.shape == (k,)
    assert (left[:n] == -1).all() and (right[:n] == -1).all()
    np.testing.assert_array_equal(item, np.r_[np.arange(n), np.full(n - 1, -1)])
    ids = np.arange(n, k)
    assert ((0 <= left[n:]) & (left[n:] < ids) & (0 <= right[n:]) & (right[n:] < ids)).all()
    np.testing.assert_array_equal(np.bincount(np.r_[left[n:], right[n:]], minlength=k), np.r_[np.ones(k - 1), 0])


def run(args, metric_id, has_cone, **kw):
    left, right, item, root, _ = agglomerate(*args, metric_id, has_cone, has_cone and metric_id != SURFACE_AREA, C,
                                             **kw)
    check_tree(left, right, item, root, len(args[0]))
    return left, right


@pytest.mark.parametrize("metric_id,spread", MONOTONE)
@pytest.mark.parametrize("n", [2, 3, 40, 300])
def test_the_fast_loops_build_the_greedy_tree(metric_id, spread, n):
    args = items(n, n + metric_id, spread)
    g_left, g_right, g_item = greedy_cluster(COST[metric_id], False, C, *args)
    check_tree(g_left, g_right, g_item, 2 * n - 2, n)
    greedy = members(g_left, g_right, n)
    for leafsize in (32, 2):
        # The heap merges in the greedy order: the same node ids.
        assert members(*run(args, metric_id, False, heap=True, leafsize=leafsize), n) == greedy
        for parallel_min in (2048, 2):  # rounds on one thread, on every thread
            got = members(*run(args, metric_id, False, leafsize=leafsize, parallel_min=parallel_min), n)
            assert set(got) == set(greedy), (leafsize, parallel_min)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(2, 60), seed=st.integers(0, 2**32 - 1), case=st.sampled_from(MONOTONE))
def test_the_fast_loops_build_the_greedy_tree_property(n, seed, case):
    metric_id, spread = case
    args = items(n, seed, spread)
    greedy = members(*greedy_cluster(COST[metric_id], False, C, *args)[:2], n)
    assert members(*run(args, metric_id, False, heap=True), n) == greedy
    assert set(members(*run(args, metric_id, False, leafsize=3), n)) == set(greedy)


@pytest.mark.parametrize("metric_id,has_cone", [(WALTER2008, True), (WALTER2005, True), (SURFACE_AREA, False)])
def test_the_clusters_do_not_depend_on_the_kd_tree_or_the_item_order(metric_id, has_cone):
    n = 250
    args = items(n, 5, 0.02, oriented=has_cone)
    perm = np.random.default_rng(1).permutation(n)
    for heap in (False, True):
        want = set(members(*run(args, metric_id, has_cone, heap=heap), n))
        assert set(members(*run(args, metric_id, has_cone, heap=heap, leafsize=1), n)) == want
        assert set(members(*run(args, metric_id, has_cone, heap=heap, order=perm), n)) == want
        if not heap:
            assert set(members(*run(args, metric_id, has_cone, parallel_min=2), n)) == want


@pytest.mark.parametrize("heap", [False, True])
@pytest.mark.parametrize("bad", [np.inf, np.nan])
def test_an_infinite_or_nan_cost_is_one_error(heap, bad):
    lo, hi, normal, intensity = items(30, 6, 0.0)
    intensity[7] = bad
    with pytest.raises(LightcutsError, match=r"^the subject: a (cluster|round) .*; the advice$"):
        agglomerate(lo, hi, normal, intensity, WALTER2008, False, False, C, heap=heap,
                    what=("the subject", "the advice"))


def test_one_item_and_a_bad_leaf_size():
    lo, hi, normal, intensity = items(1, 0, 0.0)
    for heap in (False, True):
        left, right, item, root, _ = agglomerate(lo, hi, normal, intensity, WALTER2008, False, False, C, heap=heap)
        assert root == 0 and list(left) == list(right) == [-1] and list(item) == [0]
    with pytest.raises(ValueError, match="leafsize"):
        agglomerate(lo, hi, normal, intensity, WALTER2008, False, False, C, leafsize=0)
