"""findBestMatch through the kd-tree: one cluster (``kd_search.kd_best_match``) and the clusters of a kd
leaf together (``kd_group_search.kd_search_range``), against a brute-force scan of every pair.

Properties:
- each search returns exactly the minimum of d(A u B) over the other active clusters, as the engine's
  pair cost computes it, and a cluster that attains it; with one active cluster, (-1, inf);
- ties go as the code defines them: A's own kd leaf is scanned whole first and a tie goes to the
  smaller id, so no tied cluster in A's leaf has a smaller id than the one returned;
- this holds for random boxes and points, duplicates and grids (ties everywhere), every metric with
  and without cones, any leaf size, after clusters were merged away (with kd rebuilds), for a round's
  arbitrary subset of clusters, however the round is cut into chunks;
- grouping by leaf is a stable sort of the round by kd leaf;
- the per-axis extent bounds of both searches are lower bounds: one query's for every cluster the
  node's bounds allow, the group's for every member's.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_group_search import _group_extent, kd_group_by_leaf, kd_search_range
from lightcuts.cluster.kd_merge import kd_merge
from lightcuts.cluster.kd_search import _union_extent, kd_best_match

from cluster_oracles import C, METRIC_CASES, Clusters, active, random_items, uses_cone


def check_searches(kd, cl, metric_id, has_cone, rng, chunk):
    """Every active cluster's kd_best_match, and a random subset's grouped search, against brute force."""
    ids = active(kd)
    assert list(ids) == sorted(cl.alive)
    use_cone = uses_cone(metric_id, has_cone)
    d = cl.costs(ids, metric_id, has_cone)
    where = {int(c): i for i, c in enumerate(ids)}
    leaf = {int(c): int(kd.slot_leaf[kd.slot_of[c]]) for c in ids}

    def check(a, b, value):
        if len(ids) == 1:
            assert (b, value) == (-1, np.inf)
            return
        i = where[a]
        assert value == d[i].min(), (a, b, value, d[i].min())
        assert b != a and b in where and d[i, where[b]] == value, (a, b)
        tied_in_leaf = [c for c in ids if c != a and leaf[c] == leaf[a] and d[i, where[c]] == value]
        assert all(b <= c for c in tied_in_leaf), (a, b, tied_in_leaf)

    for a in ids:
        check(int(a), *kd_best_match(kd, a, metric_id, has_cone, use_cone, C))
    # A round: a random subset of the clusters, grouped by leaf, then searched in chunks.
    todo = rng.permutation(ids)[:rng.integers(1, len(ids) + 1)]
    grouped = todo.copy()
    kd_group_by_leaf(kd, grouped, len(grouped), np.empty(len(grouped), np.int64))
    assert list(grouped) == sorted(todo, key=lambda c: leaf[c])
    best = np.full(2 * cl.n - 1, -7, np.int32)
    best_d = np.full(2 * cl.n - 1, -7.0)
    kd_search_range(kd, grouped, len(grouped), best, best_d, metric_id, has_cone, use_cone, C, chunk,
                    np.zeros(1, np.int64))
    for a in ids:
        if a in todo:
            check(int(a), int(best[a]), best_d[a])
        else:
            assert best[a] == -7 and best_d[a] == -7.0, "a cluster outside the round was written"


def searched_tree(n, seed, kind, spread, leafsize, frac, metric_id, has_cone, chunk):
    rng = np.random.default_rng(seed)
    lo, hi, normal, intensity = random_items(n, rng, kind, spread)
    order = rng.permutation(n)
    cl = Clusters(lo, hi, normal, intensity, order)
    kd, work = kd_new(lo, hi, normal, intensity, order, leafsize)
    kd_build(kd, work)
    check_searches(kd, cl, metric_id, has_cone, rng, chunk)
    # Random merges (not the builders' choices: any pair), rebuilding when half are gone.
    for _ in range(int(frac * (n - 1))):
        a, b = cl.random_pair(rng)
        kd_merge(kd, work, a, b, cl.merge(a, b), True)
    check_searches(kd, cl, metric_id, has_cone, rng, chunk)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(1, 48), seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["random", "duplicates", "grid"]),
       spread=st.sampled_from([0.0, 0.05]), leafsize=st.sampled_from([1, 2, 5, 32]), frac=st.floats(0, 1),
       case=st.sampled_from(METRIC_CASES), chunk=st.sampled_from([1, 3, 512]))
def test_searches_equal_the_brute_force_minimum(n, seed, kind, spread, leafsize, frac, case, chunk):
    searched_tree(n, seed, kind, spread, leafsize, frac, *case, chunk)


@pytest.mark.parametrize("metric_id,has_cone", METRIC_CASES)
def test_searches_in_a_deeper_tree(metric_id, has_cone):
    # 300 clusters in leaves of 4: seven levels, searches that climb far from their leaf.
    searched_tree(300, 7 + metric_id, "random", 0.02, 4, 0.6, metric_id, has_cone, 16)


intervals = st.tuples(st.floats(-10, 10), st.floats(0, 5)).map(lambda t: (t[0], t[0] + t[1]))


@settings(max_examples=100, deadline=None)
@given(members=st.lists(intervals, min_size=1, max_size=5), node=st.lists(intervals, min_size=1, max_size=5))
def test_extent_bounds_are_lower_bounds(members, node):
    # One axis: a node's clusters' boxes give hmin, lmax, emin; the union of a query (or every member
    # of a group) with any of them is at least as wide as the bound.
    hmin = min(h for _, h in node)
    lmax = max(lo for lo, _ in node)
    emin = min(h - lo for lo, h in node)
    g_emin = min(h - lo for lo, h in members)
    g_hmin = min(h for _, h in members)
    g_lmax = max(lo for lo, _ in members)
    group = _group_extent(g_emin, g_hmin, g_lmax, hmin, lmax, emin)
    for qlo, qhi in members:
        own = _union_extent(qlo, qhi, hmin, lmax, emin)
        assert group <= own
        for lo, hi in node:
            assert own <= max(qhi, hi) - min(qlo, lo)
