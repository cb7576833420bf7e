"""Building the kd-tree (``lightcuts/cluster/kd_build.py``).

Properties, on random boxes, points, duplicates and grids, and on clusters made of them:
- every cluster is in exactly one leaf, in its leaf's first slots, with its own bounds;
- the tree is balanced at the median: a node's left child holds half its clusters (rounded down),
  every centre on the left is <= the split <= every centre on the right, the split axis is the
  longest side of the node's cell, and no leaf holds more than the leaf size, at the least depth;
- every node's bounds are those of its clusters, rounded outwards to float32;
- the bound the search prunes with is a lower bound of d(A u B) for every query A and every B under
  the node, for every metric, with and without cones (the property that makes the search exact).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_tree import I_BUILT, I_FIRST_LEAF, N_AXIS, N_SPLIT, S_HI, S_LO

from cluster_helpers import kd_node_bound
from cluster_oracles import (C, METRIC_CASES, Clusters, active, check_node_bounds, check_storage, leaves,
                             node_clusters, random_items, uses_cone)


def build(n, seed, kind="random", spread=0.05, leafsize=4):
    rng = np.random.default_rng(seed)
    lo, hi, normal, intensity = random_items(n, rng, kind, spread)
    order = rng.permutation(n)
    kd, work = kd_new(lo, hi, normal, intensity, order, leafsize)
    kd_build(kd, work)
    return kd, work, Clusters(lo, hi, normal, intensity, order)


def check_shape(kd, leafsize):
    """Median splits along the longest side of each cell, leaves of at most ``leafsize``, least depth."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    n = int(kd.info[I_BUILT])
    for *_, cnt in leaves(kd):
        assert cnt <= leafsize
    # The least depth: one level fewer would leave a leaf with more than leafsize clusters.
    if first_leaf > 0:
        assert -(-n // ((first_leaf + 1) // 2)) > leafsize
    ids = active(kd)
    centre = {}
    for c in ids:
        s = kd.slot_of[c]
        centre[c] = 0.5 * (kd.slot_f[s, S_LO:S_LO + 3] + kd.slot_f[s, S_HI:S_HI + 3])
    pts = np.array([centre[c] for c in ids])
    cells = {0: (pts.min(0), pts.max(0))}
    for k in range(first_leaf):
        clo, chi = cells[k]
        axis = int(kd.node_s[k, N_AXIS])
        assert axis == int(np.argmax(chi - clo)), k
        left = np.array([centre[c][axis] for c in node_clusters(kd, 2 * k + 1)])
        right = np.array([centre[c][axis] for c in node_clusters(kd, 2 * k + 2)])
        assert len(left) == (len(left) + len(right)) // 2, k
        # The split is the median centre, the smallest on the right (an empty node: its cell's lower end).
        split = right.min() if len(right) else clo[axis]
        assert len(left) == 0 or left.max() <= split, k
        assert kd.node_s[k, N_SPLIT] == np.float32(split), k
        lhi, rlo = chi.copy(), clo.copy()
        lhi[axis] = rlo[axis] = split
        cells[2 * k + 1] = (clo, lhi)
        cells[2 * k + 2] = (rlo, chi)


FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FAST
@given(n=st.integers(1, 80), seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["random", "duplicates", "grid"]),
       spread=st.sampled_from([0.0, 0.05]), leafsize=st.sampled_from([1, 2, 3, 8, 32]))
def test_build_storage_shape_and_bounds(n, seed, kind, spread, leafsize):
    kd, _, cl = build(n, seed, kind, spread, leafsize)
    check_storage(kd, cl)
    check_shape(kd, leafsize)
    check_node_bounds(kd, cl, exact=True)
    # A build over clusters (boxes of normals, not single normals): half the items merged at random.
    rng = np.random.default_rng(seed)
    for _ in range(n // 2):
        cl.merge(*cl.random_pair(rng))
    ids = cl.alive
    clusters = Clusters(cl.lo[ids], cl.hi[ids], cl.nlo[ids], cl.inten[ids], normal_hi=cl.nhi[ids])
    kd, _ = clusters.fresh_kd(np.arange(len(ids)), leafsize)
    check_storage(kd, clusters)
    check_shape(kd, leafsize)
    check_node_bounds(kd, clusters, exact=True)


@pytest.mark.parametrize("metric_id,has_cone", METRIC_CASES)
def test_the_pruning_bound_is_below_every_cluster_under_the_node(metric_id, has_cone):
    kd, work, cl = build(90, metric_id + 10 * has_cone, spread=0.1, leafsize=3)
    ids = active(kd)
    d = cl.costs(ids, metric_id, has_cone)
    where = {c: i for i, c in enumerate(ids)}
    positive = checked = 0
    for k in range(2 * int(kd.info[I_FIRST_LEAF]) + 1):
        under = [where[c] for c in node_clusters(kd, k)]
        for i, a in enumerate(ids):
            others = [j for j in under if j != i]
            if not others:
                continue
            lb = kd_node_bound(kd, a, k, metric_id, has_cone, uses_cone(metric_id, has_cone), C)
            assert lb <= d[i, others].min(), (k, a, lb, d[i, others].min())
            checked += 1
            positive += lb > 0
    # Not a vacuous bound: it prunes (is positive) for most pairs of a query and a node.
    assert positive > checked // 2
