"""Agglomerative BVH topologies (Walter et al. 2008, section 4) on the shared clustering engine: the
locally-ordered and heap builders equal the naive greedy clustering on boxes without ties, the
kd-tree's node bound never exceeds the surface area of a union and is at least section 4's bound,
the topology is valid, and the result does not depend on the thread count."""

from __future__ import annotations

import numpy as np
import pytest

from lightcuts.accel.triangles import triangle_boxes
from lightcuts.accel.bvh.bvh_agglomerative import (bvh_agglomerative, bvh_agglomerative_heap, bvh_agglomerative_stats,
                                               bvh_greedy_reference)
from lightcuts.cluster.dissimilarity import SURFACE_AREA
from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_merge import kd_merge
from lightcuts.cluster.kd_tree import I_FIRST_LEAF, S_HI, S_LO
from lightcuts.cluster.morton import morton_order
from lightcuts.errors import LightcutsError

from cluster_helpers import kd_node_bound


def random_boxes(n, seed, spread=0.05):
    """n boxes: uniform centres in the unit cube, half-sizes up to ``spread`` (no ties, almost surely)."""
    rng = np.random.default_rng(seed)
    c = rng.random((n, 3))
    h = rng.random((n, 3)) * spread
    return c - h, c + h


def surface_area(lo, hi):
    e = hi - lo
    return 2.0 * (e[..., 0] * e[..., 1] + e[..., 1] * e[..., 2] + e[..., 2] * e[..., 0])


def clusters(left, right, n):
    """The internal clusters as a set of frozensets of leaves."""
    members = [frozenset([i]) for i in range(n)] + [None] * (n - 1)
    for m in range(n, 2 * n - 1):
        members[m] = members[left[m]] | members[right[m]]
    return set(members[n:])


def check_topology(left, right, prim, root, n):
    """2n-1 nodes; leaves 0..n-1 with left = right = -1 and prim = their id; every other node has two
    children made before it and prim -1; every node but the root has one parent; the root holds all."""
    k = 2 * n - 1
    assert root == k - 1
    for a in (left, right, prim):
        assert a.dtype == np.int32 and a.shape == (k,)
    assert (left[:n] == -1).all() and (right[:n] == -1).all()
    np.testing.assert_array_equal(prim[:n], np.arange(n))
    assert (prim[n:] == -1).all()
    ids = np.arange(n, k)
    assert ((left[n:] >= 0) & (left[n:] < ids) & (right[n:] >= 0) & (right[n:] < ids)).all()
    parents = np.bincount(np.concatenate([left[n:], right[n:]]), minlength=k)
    np.testing.assert_array_equal(parents, np.r_[np.ones(k - 1, np.int64), 0])


@pytest.mark.parametrize("n, seed", [(2, 0), (3, 1), (250, 2), (400, 3)])
def test_locally_ordered_heap_and_greedy_build_the_same_clusters(n, seed):
    lo, hi = random_boxes(n, seed)
    ref = bvh_greedy_reference(lo, hi)
    check_topology(*ref, n)
    want = clusters(ref[0], ref[1], n)
    for leafsize in (32, 4):
        for heap in (False, True):
            left, right, prim, root, _ = bvh_agglomerative_stats(lo, hi, heap=heap, leafsize=leafsize,
                                                                 parallel_min=64)
            check_topology(left, right, prim, root, n)
            assert clusters(left, right, n) == want, (heap, leafsize)


def test_the_greedy_reference_merges_the_least_surface_area_first():
    # Three boxes on a line: the two nearest merge first, whatever their ids.
    lo = np.array([[0.0, 0, 0], [5.0, 0, 0], [1.5, 0, 0]])
    left, right, _, _ = bvh_greedy_reference(lo, lo + 1.0)
    assert {int(left[3]), int(right[3])} == {0, 2}
    lo, hi = random_boxes(40, 9)
    left, right, _, _ = bvh_greedy_reference(lo, hi)
    # Non-decreasing merge costs (eq. 1 makes the greedy order monotone).
    blo, bhi = list(lo), list(hi)
    for m in range(40, 79):
        blo.append(np.minimum(blo[left[m]], blo[right[m]]))
        bhi.append(np.maximum(bhi[left[m]], bhi[right[m]]))
    costs = surface_area(np.array(blo[40:]), np.array(bhi[40:]))
    assert (np.diff(costs) >= 0).all()


def node_members(kd, k):
    """(lo, hi) of the active clusters under kd node k."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    depth_all = (first_leaf + 1).bit_length() - 1
    depth_k = (k + 1).bit_length() - 1
    span = depth_all - depth_k
    leaf0 = ((k + 1) << span) - 1
    rows = []
    for leaf in range(leaf0, leaf0 + (1 << span)):
        s0 = int(kd.leaf_start[leaf - first_leaf])
        rows.extend(range(s0, s0 + int(kd.node_cnt[leaf])))
    rows = np.array(rows, np.int64)
    return kd.slot_f[rows, S_LO:S_LO + 3], kd.slot_f[rows, S_HI:S_HI + 3]


def section4_bound(qlo, qhi, lo, hi):
    """Walter et al. 2008, section 4: per axis, the separation of A's centre from the box of the
    node's centres plus half of A's size plus half the smallest size; its surface area."""
    c = 0.5 * (lo + hi)
    qc = 0.5 * (qlo + qhi)
    sep = np.maximum(0.0, np.maximum(c.min(0) - qc, qc - c.max(0)))
    e = sep + 0.5 * ((qhi - qlo) + (hi - lo).min(0))
    return 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])


def check_node_bounds(kd, fresh):
    """For every active cluster A and every kd node with clusters: bound <= SA(A u B) for each B under
    it; right after a (re)build (``fresh``) also bound >= section 4's bound (up to float32 rounding)."""
    active = np.flatnonzero(kd.slot_of >= 0)
    checked = 0
    # A rebuild over fewer clusters uses a prefix of the node arrays.
    for k in range(2 * int(kd.info[I_FIRST_LEAF]) + 1):
        if kd.node_cnt[k] == 0:
            continue
        lo, hi = node_members(kd, k)
        for a in active:
            s = kd.slot_of[a]
            qlo, qhi = kd.slot_f[s, S_LO:S_LO + 3], kd.slot_f[s, S_HI:S_HI + 3]
            lb = kd_node_bound(kd, a, k, SURFACE_AREA, False, False, 0.0)
            true = surface_area(np.minimum(qlo, lo), np.maximum(qhi, hi))
            assert lb <= true.min(), (k, a, lb, true.min())
            if fresh:
                paper = section4_bound(qlo, qhi, lo, hi)
                assert lb >= paper - 1e-5 * (1.0 + paper), (k, a, lb, paper)
            checked += 1
    assert checked > 0


@pytest.mark.parametrize("seed, spread", [(0, 0.05), (1, 0.3), (2, 0.0)])
def test_kd_node_bound_is_below_the_true_surface_area(seed, spread):
    n = 120
    lo, hi = random_boxes(n, seed, spread)
    order = morton_order(0.5 * (lo + hi))
    kd, work = kd_new(lo, hi, np.zeros((n, 3)), np.zeros(n), order, 4)
    kd_build(kd, work)
    check_node_bounds(kd, fresh=True)
    # Merges leave the node bounds in place (loose, never too tight); rebuilds make them tight again.
    left, right, _, _ = bvh_greedy_reference(lo, hi)
    # Cluster ids of the kd-tree are positions in ``order``.
    where = np.empty(n, np.int64)
    where[order] = np.arange(n)
    ids = np.r_[where, np.arange(n, 2 * n - 1)]
    for m in range(n, n + 90):
        kd_merge(kd, work, ids[left[m]], ids[right[m]], m, True)
        if m % 15 == 0:
            check_node_bounds(kd, fresh=False)


def test_thread_count_does_not_change_the_bvh(thread_counts):
    counts, num_threads = thread_counts
    lo, hi = random_boxes(6000, 5)
    # A grid of equal boxes: many ties, which must still resolve the same way.
    g = np.stack(np.meshgrid(*[np.arange(12.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    out = {}
    for t in counts:
        with num_threads(t):
            out[t] = [bvh_agglomerative_stats(lo, hi, parallel_min=256)[:4],
                      bvh_agglomerative_stats(g, g + 0.5, parallel_min=256)[:4],
                      bvh_agglomerative_heap(g, g + 0.5)]
    for a, b in zip(out[counts[0]], out[counts[1]]):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)
    for res, n in zip(out[counts[0]], (6000, len(g), len(g))):
        check_topology(*res, n)


def test_public_functions_on_a_mesh_and_bad_input():
    # A small mesh: a fan of triangles; both builders, valid topologies.
    v = np.array([[np.cos(a), np.sin(a), 0.1 * a] for a in np.linspace(0, 6, 30)] + [[0.0, 0, 0]])
    f = np.array([[30, i, i + 1] for i in range(29)])
    lo, hi = triangle_boxes(v, f)
    assert lo.shape == (29, 3) and (lo <= hi).all()
    for build in (bvh_agglomerative, bvh_agglomerative_heap):
        check_topology(*build(lo, hi), 29)
        left, right, prim, root = build(lo[:1], hi[:1])
        assert root == 0 and left[0] == right[0] == -1 and prim[0] == 0
        left, right, prim, root = build(lo[:0], hi[:0])  # an empty scene
        assert root == -1 and len(left) == len(right) == len(prim) == 0
    nan_lo = np.where(np.arange(29)[:, None] == 3, np.nan, lo)
    for bad_lo, bad_hi in [(lo, hi[:-1]), (nan_lo, hi), (hi + 1, hi), (lo[:, :2], hi[:, :2])]:
        with pytest.raises(LightcutsError, match="bvh-agglomerative"):
            bvh_agglomerative(bad_lo, bad_hi)
