"""The fast agglomerative builders and their kd-tree (Walter, Bala, Kulkarni, Pingali 2008).

Properties:
- the kd-tree keeps each leaf's active clusters in its first slots, its cluster data equal to the
  clusters' boxes, and its node bounds valid for every cluster under each node, through merges and
  rebuilds;
- findBestMatch through the kd-tree returns the minimum of the metric over the active clusters,
  as a brute-force scan computes it, for every metric and light type, before and after merges
  (with and without kd rebuilds), at any leaf size and far from the origin;
- with a non-decreasing metric, ``agglomerative``, ``agglomerative-heap`` and ``greedy`` build the
  same set of clusters, also when the locally-ordered rounds run on several threads;
- the locally-ordered builder gives the same tree on one thread as on two;
- the builders terminate with valid trees on inputs where every merge ties.
"""

from __future__ import annotations

import zlib

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.cones import cone_from_box
from lightcuts.cluster.kd_build import kd_build, kd_build_threaded, kd_new
from lightcuts.cluster.kd_merge import kd_merge, kd_merge_batch, kd_merge_batch_finish, kd_subtree, kd_wants_rebuild
from lightcuts.cluster.kd_tree import (I_ACTIVE, I_BUILT, I_FIRST_LEAF, KD_SUBTREES, N_AXIS, N_EMIN, N_HMIN,
                                       N_IMIN, N_LMAX, N_SPLIT, NE_MIN, NH_MIN, NL_MAX, S_HI, S_I, S_LO, S_NHI, S_NLO,
                                       SLOT_DATA, KdTree)
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LightSet
from lightcuts.parallel import on_threads
from lightcuts.trees.agglomerative import agglomerative, agglomerative_stats
from lightcuts.trees.build import build_tree
from lightcuts.trees.metrics import Metric, metric_eval
from lightcuts.trees.registry import get_metric
from lightcuts.trees.validate import validate_tree

from cluster_helpers import best_matches_after_merges

METRIC_NAMES = ("walter2008", "walter2005", "surface-area")
KD_FIELDS = ("slot_f", "slot_id", "slot_of", "slot_leaf", "node_s", "node_n", "node_cnt", "leaf_start", "info",
             "stack_node", "stack_lb", "dbuf")
LIGHT_TYPES = ("omni", "oriented", "directional")


def unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_arrays(n, light_type, rng, offset=0.0, scale=1.0, face_normals=False):
    """(position, normal, luminance) of n random lights with continuous values (no ties)."""
    if light_type == "directional":
        position = unit(rng.normal(size=(n, 3)))
    else:
        position = offset + scale * rng.random((n, 3))
    if light_type != "oriented":
        normal = np.zeros((n, 3))
    elif face_normals:
        # Normals of a few faces, slightly perturbed: cones from near-zero to wide, as in a room.
        faces = np.array([[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1.0]])
        normal = unit(faces[rng.integers(0, len(faces), n)] + 0.02 * rng.normal(size=(n, 3)))
    else:
        normal = unit(rng.normal(size=(n, 3)))
    return position, normal, 0.05 + rng.random(n)


def random_merges(n, count, rng):
    """(count, 2) merges of random active clusters; merge m creates cluster n + m."""
    active = list(range(n))
    out = []
    for m in range(count):
        i, j = sorted(rng.choice(len(active), 2, replace=False))
        out.append((active[i], active[j]))
        del active[j], active[i]
        active.append(n + m)
    return np.array(out, np.int64).reshape(-1, 2)


def clusters_after(position, normal, luminance, merges):
    """Each active cluster's box, normal box and intensity after ``merges`` (dicts by cluster id)."""
    n = len(position)
    lo = {i: position[i].copy() for i in range(n)}
    hi = {i: position[i].copy() for i in range(n)}
    nlo = {i: normal[i].copy() for i in range(n)}
    nhi = {i: normal[i].copy() for i in range(n)}
    inten = {i: float(luminance[i]) for i in range(n)}
    for m, (a, b) in enumerate(merges):
        k = n + m
        lo[k], hi[k] = np.minimum(lo[a], lo[b]), np.maximum(hi[a], hi[b])
        nlo[k], nhi[k] = np.minimum(nlo[a], nlo[b]), np.maximum(nhi[a], nhi[b])
        inten[k] = inten[a] + inten[b]
        for table in (lo, hi, nlo, nhi, inten):
            del table[a], table[b]
    return lo, hi, nlo, nhi, inten


def pair_metric(metric, has_cone, c, clusters, a, b):
    """d(A u B) computed from scratch, as the builders define it."""
    lo, hi, nlo, nhi, inten = clusters
    ulo, uhi = np.minimum(lo[a], lo[b]), np.maximum(hi[a], hi[b])
    cos_half = 1.0
    if has_cone and metric.uses_cone:
        cos_half = cone_from_box(*np.minimum(nlo[a], nlo[b]), *np.maximum(nhi[a], nhi[b]))[3]
    return metric_eval(metric.id, inten[a] + inten[b], *ulo, *uhi, cos_half, has_cone, c)


def brute_force(metric, has_cone, c, clusters):
    """{cluster: {other: d}} over all pairs of active clusters."""
    ids = sorted(clusters[4])
    return {a: {b: pair_metric(metric, has_cone, c, clusters, a, b) for b in ids if b != a} for a in ids}


def check_against_brute_force(position, normal, luminance, light_type, metric_name, c, merges, leafsize):
    metric = get_metric(metric_name)
    has_cone = light_type == "oriented"
    table = brute_force(metric, has_cone, c, clusters_after(position, normal, luminance, merges))
    # One search per cluster, and the clusters of a kd leaf searched together.
    for grouped in (False, True):
        active, best, d = best_matches_after_merges(position, normal, luminance, has_cone, metric, c, merges,
                                                    leafsize, grouped)
        assert sorted(table) == list(active)
        for a, b, value in zip(active, best, d):
            ref = min(table[a].values())
            assert value == ref, (grouped, a, b, value, ref)
            # The returned cluster is a minimiser: the same one unless several tie.
            assert table[a][b] == ref, (grouped, a, b)


# ------------------------------------------------------------------------------------ kd tree

def check_kd_tree(kd, clusters):
    """The kd-tree's storage and bounds against the active clusters (dicts of clusters_after)."""
    slot_f, slot_id, slot_of, slot_leaf = kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf
    node_s, node_n, node_cnt, leaf_start, info = kd.node_s, kd.node_n, kd.node_cnt, kd.leaf_start, kd.info
    lo, hi, nlo, nhi, inten = clusters
    first_leaf = int(info[I_FIRST_LEAF])
    seen = []
    # The arrays keep the size of the first build; a rebuild over fewer clusters uses a prefix.
    for j in range(first_leaf + 1):
        leaf = first_leaf + j
        s0, s1, cnt = int(leaf_start[j]), int(leaf_start[j + 1]), int(node_cnt[leaf])
        # Active clusters first, then empty slots: a search scans exactly the first cnt slots.
        assert (slot_id[s0:s0 + cnt] >= 0).all() and (slot_id[s0 + cnt:s1] == -1).all(), leaf
        for s in range(s0, s0 + cnt):
            c = int(slot_id[s])
            seen.append(c)
            assert slot_of[c] == s and slot_leaf[s] == leaf
            np.testing.assert_array_equal(slot_f[s, S_LO:S_LO + 3], lo[c])
            np.testing.assert_array_equal(slot_f[s, S_HI:S_HI + 3], hi[c])
            np.testing.assert_array_equal(slot_f[s, S_NLO:S_NLO + 3], nlo[c])
            np.testing.assert_array_equal(slot_f[s, S_NHI:S_NHI + 3], nhi[c])
            assert slot_f[s, S_I] == inten[c]
            # Every node on the path bounds the cluster (float32 values widen exactly to float64).
            k = leaf
            while True:
                row = node_s[k, :N_SPLIT].astype(np.float64)
                nrow = node_n[k].astype(np.float64)
                assert (hi[c] >= row[N_HMIN:N_HMIN + 3]).all() and (lo[c] <= row[N_LMAX:N_LMAX + 3]).all()
                assert (hi[c] - lo[c] >= row[N_EMIN:N_EMIN + 3]).all() and inten[c] >= row[N_IMIN]
                assert (nhi[c] >= nrow[NH_MIN:NH_MIN + 3]).all() and (nlo[c] <= nrow[NL_MAX:NL_MAX + 3]).all()
                assert (nhi[c] - nlo[c] >= nrow[NE_MIN:NE_MIN + 3]).all()
                if k == 0:
                    break
                k = (k - 1) // 2
    assert sorted(seen) == sorted(inten) and int(info[I_ACTIVE]) == len(seen)
    for k in range(first_leaf):
        assert node_cnt[k] == node_cnt[2 * k + 1] + node_cnt[2 * k + 2]


def test_kd_tree_storage_and_bounds_through_merges_and_rebuilds():
    rng = np.random.default_rng(11)
    n = 300
    position, normal, luminance = random_arrays(n, "oriented", rng, face_normals=True)
    merges = random_merges(n, n - 2, rng)
    order = rng.permutation(n)
    kd, work = kd_new(position, position, normal, luminance, order, 4)
    kd_build(kd, work)
    # Cluster i < n is light order[i].
    lights = position[order], normal[order], luminance[order]
    check_kd_tree(kd, clusters_after(*lights, merges[:0]))
    for m, (a, b) in enumerate(merges):
        kd_merge(kd, work, a, b, n + m, True)
        if m % 37 == 0 or m >= n - 5:
            check_kd_tree(kd, clusters_after(*lights, merges[:m + 1]))


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_kd_merge_batches_on_threads():
    # A round's merges: pairs within one subtree below the top levels on the threads, the others
    # after them. The storage and every count must hold after each batch, and come out as when the
    # subtrees are done in turn.
    rng = np.random.default_rng(13)
    n = 3000
    position, normal, luminance = random_arrays(n, "oriented", rng, face_normals=True)
    order = rng.permutation(n)
    lights = position[order], normal[order], luminance[order]
    left = np.full(2 * n - 1, -1, np.int32)
    right = np.full(2 * n - 1, -1, np.int32)
    trees = [kd_new(lights[0], *lights, np.arange(n), 8) for _ in range(2)]
    for kd, work in trees:
        kd_build(kd, work)
    merges = []
    kinds = set()
    while len(merges) < n - 10:
        kd = trees[0][0]
        active = np.flatnonzero(kd.slot_of >= 0)
        # Neighbours in slot order (mostly one subtree), and a few random pairs (mostly not).
        active = active[np.argsort(kd.slot_of[active])]
        near = active[:len(active) // 2 // 2 * 2].reshape(-1, 2)
        far = rng.permutation(active[len(near) * 2:])
        far = far[:min(len(far) // 2, 20) * 2].reshape(-1, 2)
        pairs = np.concatenate([near, far])
        new0 = n + len(merges)
        left[new0:new0 + len(pairs)], right[new0:new0 + len(pairs)] = pairs[:, 0], pairs[:, 1]
        sub = np.array([kd_subtree(kd, a) if kd_subtree(kd, a) == kd_subtree(kd, b) else -1 for a, b in pairs],
                       np.int32)
        kinds |= {bool(s >= 0) for s in sub}
        on_threads(kd_merge_batch, KD_SUBTREES, 0, trees[0][0], left, right, new0, len(pairs), sub)
        kd_merge_batch(trees[1][0], left, right, new0, len(pairs), sub, 0, KD_SUBTREES)
        for kd, work in trees:
            kd_merge_batch_finish(kd, left, right, new0, len(pairs), sub)
        merges += [tuple(p) for p in pairs]
        check_kd_tree(trees[0][0], clusters_after(*lights, merges))
        # Merges write slots and counts only (not the node bounds).
        for name in ("slot_id", "slot_of", "slot_leaf", "node_cnt", "leaf_start", "info"):
            np.testing.assert_array_equal(getattr(trees[0][0], name), getattr(trees[1][0], name), err_msg=name)
        np.testing.assert_array_equal(trees[0][0].slot_f[:, :SLOT_DATA], trees[1][0].slot_f[:, :SLOT_DATA])
        for kd, work in trees:
            if kd_wants_rebuild(kd):
                kd_build(kd, work)
    assert kinds == {True, False}


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_kd_rebuild_on_threads_is_the_serial_rebuild():
    # The (re)build's subtrees go to threads from the locally-ordered builder, in turn from kd_merge:
    # every array of the tree must come out the same.
    rng = np.random.default_rng(12)
    n = 3000
    position, normal, luminance = random_arrays(n, "oriented", rng, face_normals=True)
    merges = random_merges(n, 2500, rng)
    order = rng.permutation(n)
    trees = []
    for threaded in (False, True):
        kd, work = kd_new(position, position, normal, luminance, order, 8)
        if threaded:
            kd_build_threaded(kd, work, parallel_min=0)
        else:
            kd_build(kd, work)
        internal = int(kd.info[I_FIRST_LEAF])
        for m, (a, b) in enumerate(merges):
            kd_merge(kd, work, a, b, n + m, not threaded)
            if threaded and kd_wants_rebuild(kd):
                kd_build_threaded(kd, work, parallel_min=0)
        assert kd.info[I_BUILT] < n  # rebuilt since the first build
        trees.append(kd)
    # Every written value: not the traversal scratch, the padding columns of the rows, nor the split
    # columns of nodes that were never internal.
    assert KdTree._fields == KD_FIELDS
    for name in KD_FIELDS:
        serial, threaded = (getattr(kd, name) for kd in trees)
        if name == "slot_f":
            serial, threaded = serial[:, :SLOT_DATA], threaded[:, :SLOT_DATA]
        elif name == "node_s":
            np.testing.assert_array_equal(serial[:internal, N_SPLIT:N_AXIS + 1],
                                          threaded[:internal, N_SPLIT:N_AXIS + 1])
            serial, threaded = serial[:, :N_SPLIT], threaded[:, :N_SPLIT]
        if name not in ("stack_node", "stack_lb", "dbuf"):
            np.testing.assert_array_equal(serial, threaded, err_msg=name)
    check_kd_tree(trees[1], clusters_after(position[order], normal[order], luminance[order], merges))


# ------------------------------------------------------------------------------------ kd search

@pytest.mark.parametrize("light_type", LIGHT_TYPES)
@pytest.mark.parametrize("metric_name", METRIC_NAMES)
def test_kd_search_matches_brute_force(light_type, metric_name):
    rng = np.random.default_rng(zlib.crc32(f"{light_type} {metric_name}".encode()))
    for n, n_merges, leafsize in [(2, 0, 8), (9, 0, 2), (60, 0, 4), (60, 20, 4), (60, 45, 3), (61, 59, 8),
                                  (80, 41, 2)]:
        position, normal, luminance = random_arrays(n, light_type, rng, face_normals=n % 2 == 0)
        merges = random_merges(n, n_merges, rng)
        # c of the order of the scene: the cone term weighs as much as distance.
        check_against_brute_force(position, normal, luminance, light_type, metric_name, 0.3, merges, leafsize)


@pytest.mark.parametrize("metric_name", METRIC_NAMES)
def test_kd_search_far_from_the_origin(metric_name):
    # Large coordinates and a small spread: the bounds' rounding allowance must keep them valid.
    rng = np.random.default_rng(3)
    for offset, scale in [(1e6, 1e-3), (-3e4, 1.0), (0.0, 1e-9)]:
        position, normal, luminance = random_arrays(50, "oriented", rng, offset, scale, face_normals=True)
        merges = random_merges(50, 30, rng)
        check_against_brute_force(position, normal, luminance, "oriented", metric_name, 0.3 * scale, merges, 4)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(2, 30), seed=st.integers(0, 2**31), grid=st.booleans(), frac=st.floats(0, 1),
       metric_name=st.sampled_from(METRIC_NAMES))
def test_kd_search_on_grids_and_duplicates(n, seed, grid, frac, metric_name):
    # Positions, normals and intensities on coarse grids: duplicates and ties everywhere.
    rng = np.random.default_rng(seed)
    position, normal, luminance = random_arrays(n, "oriented", rng, face_normals=True)
    if grid:
        position = np.round(position * 2) / 2
        luminance = np.round(luminance * 2) / 2
        normal = unit(np.round(normal))
    merges = random_merges(n, int(frac * (n - 2)), rng)
    check_against_brute_force(position, normal, luminance, "oriented", metric_name, 0.5, merges, 2)


# --------------------------------------------------------------------------- builders agree

def build_clusters(position, normal, luminance, light_type, builder, metric_name, seed=0):
    intensity = np.repeat(luminance[:, None], 3, axis=1)
    lights = LightSet(position, normal, intensity, light_type)
    c = 0.3 if get_metric(metric_name).uses_cone else None  # surface-area reads no c
    tree = build_tree(lights, builder=builder, metric=metric_name, c=c, seed=seed)
    validate_tree(tree, lights)
    return set(tree.clusters())


def rounds_on_threads(position, normal, luminance, light_type, metric_name, threads):
    """``agglomerative`` with every round (not only those of 2048 searches) split over ``threads``."""
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        return agglomerative_stats(position, normal, luminance, light_type, get_metric(metric_name), 0.3, 0,
                                   parallel_min=2)
    finally:
        numba.set_num_threads(before)


def clusters_of(left, right, n):
    """Every node's cluster as a frozenset of light ids (left/right over 2n-1 nodes, children first)."""
    members = [frozenset([i]) for i in range(n)] + [None] * (n - 1)
    for node in range(n, 2 * n - 1):
        members[node] = members[left[node]] | members[right[node]]
    return set(members)


@pytest.mark.parametrize("light_type,metric_name", [("omni", "walter2008"), ("omni", "walter2005"),
                                                    ("directional", "walter2008"), ("oriented", "surface-area"),
                                                    ("omni", "surface-area")])
def test_builders_agree_with_greedy_for_monotone_metrics(light_type, metric_name):
    rng = np.random.default_rng(zlib.crc32(f"{light_type} {metric_name}".encode()))
    for n in (2, 3, 17, 120, 300):
        position, normal, luminance = random_arrays(n, light_type, rng)
        greedy = build_clusters(position, normal, luminance, light_type, "greedy", metric_name)
        for builder in ("agglomerative", "agglomerative-heap"):
            got = build_clusters(position, normal, luminance, light_type, builder, metric_name)
            assert got == greedy, (builder, n, len(got ^ greedy))
        # Rounds searched on two threads merge the same pairs.
        left, right, *_ = rounds_on_threads(position, normal, luminance, light_type, metric_name, 2)
        assert clusters_of(left, right, n) == greedy, n


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
@pytest.mark.parametrize("light_type,metric_name", [("oriented", "walter2008"), ("omni", "walter2005"),
                                                    ("directional", "surface-area")])
def test_rounds_do_not_depend_on_the_thread_count(light_type, metric_name):
    # The searches of a round run on several threads; the merges after them on one, in a fixed
    # order: node numbering included, the tree is the same. Non-monotone cones included.
    rng = np.random.default_rng(11)
    position, normal, luminance = random_arrays(3000, light_type, rng, face_normals=True)
    one = rounds_on_threads(position, normal, luminance, light_type, metric_name, 1)
    two = rounds_on_threads(position, normal, luminance, light_type, metric_name, 2)
    for a, b in zip(one[:3], two[:3]):
        np.testing.assert_array_equal(a, b)
    assert one[4] == two[4] and one[4]["rounds"] > 5


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 60), seed=st.integers(0, 2**31))
def test_builders_agree_with_greedy_property(n, seed):
    rng = np.random.default_rng(seed)
    position, normal, luminance = random_arrays(n, "omni", rng)
    greedy = build_clusters(position, normal, luminance, "omni", "greedy", "walter2008")
    assert build_clusters(position, normal, luminance, "omni", "agglomerative", "walter2008", seed) == greedy
    assert build_clusters(position, normal, luminance, "omni", "agglomerative-heap", "walter2008") == greedy


def test_oriented_cones_builders_valid_and_deterministic():
    # The default metric with box cones is not monotone: no agreement is promised, but both
    # builders return valid trees, the same ones every time.
    rng = np.random.default_rng(5)
    position, normal, luminance = random_arrays(400, "oriented", rng, face_normals=True)
    for builder in ("agglomerative", "agglomerative-heap"):
        first = build_clusters(position, normal, luminance, "oriented", builder, "walter2008")
        assert build_clusters(position, normal, luminance, "oriented", builder, "walter2008") == first


# ------------------------------------------------------------------------------- termination

@pytest.mark.parametrize("builder", ["agglomerative", "agglomerative-heap"])
@pytest.mark.parametrize("case", ["one_point", "zero_intensity", "lattice", "two_points"])
def test_termination_when_every_merge_ties(builder, case):
    n = 3000
    rng = np.random.default_rng(0)
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    intensity = np.ones((n, 3))
    if case == "one_point":
        position = np.tile([0.3, -2.0, 7.0], (n, 1))
    elif case == "zero_intensity":
        # Every pair has d = 0 under the walter metrics.
        position = rng.random((n, 3))
        intensity = np.zeros((n, 3))
    elif case == "lattice":
        g = np.arange(15.0)
        position = np.stack(np.meshgrid(g, g, g[:14], indexing="ij"), -1).reshape(-1, 3)[:n]
    else:
        position = np.where(rng.random((n, 1)) < 0.5, [[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]])
    lights = LightSet(position, normal, intensity, "oriented")
    tree = build_tree(lights, builder=builder)
    validate_tree(tree, lights)


def test_work_counters():
    rng = np.random.default_rng(2)
    position, normal, luminance = random_arrays(2000, "oriented", rng, face_normals=True)
    metric = get_metric("walter2008")
    *_, local = agglomerative_stats(position, normal, luminance, "oriented", metric, 0.3, 0)
    *_, heap = agglomerative_stats(position, normal, luminance, "oriented", metric, 0.3, 0, heap=True)
    # Every cluster but the root was searched at least once; every round merges at least once.
    assert local["searches"] >= 2 * 2000 - 2
    assert 1 <= local["rounds"] <= 2000 - 1
    assert heap["searches"] >= 2000 and heap["stale"] <= 2000


def test_user_metric_is_refused_with_a_clear_message():
    from numba import njit

    @njit
    def perimeter(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
        return (hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2)

    metric = Metric("perimeter", -1, False, "box perimeter", perimeter)
    p = np.random.default_rng(0).random((5, 3))
    with pytest.raises(LightcutsError, match="greedy"):
        agglomerative(p, np.zeros((5, 3)), np.ones(5), "omni", metric, 1.0, 0)
