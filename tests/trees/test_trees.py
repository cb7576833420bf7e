"""Light trees: cones, metrics, the builder contract, build_tree, validate_tree, registries, files."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numba import njit

import lightcuts
from lightcuts.cli import main as cli_main
from lightcuts.cluster.cones import cone_contains, cone_from_box, cone_sine, cones_from_boxes
from lightcuts.errors import LightcutsError
from lightcuts.lights import LightSet
from lightcuts.trees import (BUILDERS, METRICS, LightTree, build_tree, default_c, get_builder, get_metric,
                             metric_eval, register_metric, validate_tree)
from lightcuts.trees.metric_type import metric_values

from conftest import random_lights, unit

ALL_BUILDERS = BUILDERS.names()
LIGHT_TYPES = ("omni", "oriented", "directional")
FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def normal_box_cone(normals):
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    lo, hi = normals.min(axis=0), normals.max(axis=0)
    ax, ay, az, cos_half = cone_from_box(*map(float, lo), *map(float, hi))
    return np.array([ax, ay, az]), cos_half


def assert_cone_holds(normals):
    axis, cos_half = normal_box_cone(normals)
    normals = np.asarray(normals).reshape(-1, 3)
    assert -1.0 <= cos_half <= 1.0
    if cos_half > -1.0:
        assert abs(np.linalg.norm(axis) - 1.0) < 1e-12
        # Exact containment up to the rounding of the dot product itself (the cone is padded).
        assert np.all(normals @ axis >= cos_half - 1e-14), (normals @ axis - cos_half).min()
    assert cone_contains(axis, cos_half, normals, tol=1e-12).all()
    return axis, cos_half


# ------------------------------------------------------------------------------------------ cones

unit_vectors = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(
    lambda v: 1e-3 < np.linalg.norm(v)).map(unit)


@FAST
@given(st.lists(unit_vectors, min_size=1, max_size=40))
def test_cone_contains_every_normal(normals):
    assert_cone_holds(normals)


@FAST
@given(unit_vectors, st.lists(st.tuples(*[st.floats(-1e-3, 1e-3)] * 3), min_size=1, max_size=10))
def test_cone_near_antipodal_sets(n, jitters):
    normals = [n] + [unit(-n + np.array(j)) for j in jitters]
    axis, cos_half = assert_cone_holds(normals)
    assert cos_half < 1e-3  # two (nearly) opposite directions need (about) a hemisphere


@FAST
@given(st.lists(unit_vectors, min_size=1, max_size=10))
def test_cone_spanning_more_than_a_hemisphere(normals):
    # Add -x, +x, +y and a vector below the xy-plane: the set spans more than a hemisphere.
    extra = unit([[-1, 0, 0], [1, 0, 0], [0, 1, 0], [0, -0.3, 0.95]])
    axis, cos_half = assert_cone_holds(np.concatenate([extra, np.reshape(normals, (-1, 3))]))
    assert cos_half < 0.0


def test_cone_wider_than_90_degrees_is_kept():
    normals = unit([[-1, 0, 0], [1, 0, 0], [0, 1, 0], [0, -0.3, 0.95]])
    axis, cos_half = assert_cone_holds(normals)
    assert -1.0 < cos_half < -0.2  # not clamped to 0, not the full sphere
    assert cone_sine(cos_half) == 1.0


def test_full_sphere():
    normals = np.concatenate([np.eye(3), -np.eye(3)])
    axis, cos_half = assert_cone_holds(normals)
    assert cos_half == -1.0 and np.all(axis == 0.0)
    # Antipodal pair: the box centre is the origin.
    assert normal_box_cone([[0, 0, 1], [0, 0, -1]])[1] == -1.0


@FAST
@given(unit_vectors)
def test_cone_of_a_single_normal_is_that_normal(n):
    axis, cos_half = normal_box_cone([n, n])
    assert cos_half == 1.0
    np.testing.assert_allclose(axis, n, atol=1e-15)


def test_cone_examples_and_vectorised_form():
    # +x and +y: box [0,1]x[0,1]x0, the exact 45-degree cone about (1,1,0)/sqrt2.
    axis, cos_half = normal_box_cone(np.eye(3)[:2])
    np.testing.assert_allclose(axis, unit([1, 1, 0]), atol=1e-15)
    assert abs(cos_half - np.sqrt(0.5)) < 1e-14
    rng = np.random.default_rng(3)
    lo = -rng.random((50, 3))
    hi = lo + rng.random((50, 3))
    axes, coss = cones_from_boxes(lo, hi)
    for k in range(50):
        assert np.array_equal(axes[k], cone_from_box(*lo[k], *hi[k])[:3]) and coss[k] == cone_from_box(*lo[k], *hi[k])[3]


@FAST
@given(st.floats(-1, 1))
def test_cone_sine(cos_half):
    s = cone_sine(cos_half)
    assert s == (1.0 if cos_half <= 0 else pytest.approx(np.sqrt(1 - cos_half ** 2), abs=1e-15))


# ---------------------------------------------------------------------------------------- metrics

def numpy_metric(name, intensity, lo, hi, cone_cos, has_cone, c):
    """The formulas of docs/math.md ("Clustering metrics"), written independently of lightcuts.trees.metrics."""
    ext = hi - lo
    l2 = (ext ** 2).sum(axis=1)
    if name == "surface-area":
        return 2 * (ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0])
    if name == "walter2008":
        s = np.where(cone_cos <= 0, 1.0, np.sqrt(np.clip(1 - cone_cos ** 2, 0, None)))
        return intensity * (l2 + (c ** 2 * s ** 2 if has_cone else 0.0)) ** 2
    assert name == "walter2005"
    return intensity * (l2 + (c ** 2 * (1 - cone_cos) ** 2 if has_cone else 0.0))


@pytest.mark.parametrize("name", ["walter2008", "walter2005", "surface-area"])
@pytest.mark.parametrize("has_cone", [True, False])
def test_metric_eval_matches_numpy(name, has_cone):
    rng = np.random.default_rng(7)
    k = 300
    intensity = rng.random(k) * 10
    lo = rng.normal(size=(k, 3))
    hi = lo + rng.random((k, 3)) * 3
    cone_cos = rng.uniform(-1, 1, k)
    cone_cos[:5] = [-1, 0, 1, 1e-9, -1e-9]
    c = 0.37
    metric = get_metric(name)
    expect = numpy_metric(name, intensity, lo, hi, cone_cos, has_cone, c)
    np.testing.assert_allclose(metric_values(metric, intensity, lo, hi, cone_cos, has_cone, c), expect, rtol=1e-13)
    got = [metric_eval(metric.id, intensity[i], *lo[i], *hi[i], cone_cos[i], has_cone, c) for i in range(k)]
    np.testing.assert_allclose(got, expect, rtol=1e-13)


def test_metric_registry():
    assert {"walter2008", "walter2005", "surface-area"} <= set(METRICS.names())
    assert get_metric("sah") is get_metric("surface-area")
    assert [get_metric(n).id for n in ("walter2008", "walter2005", "surface-area")] == [0, 1, 2]
    assert get_metric("walter2008").uses_cone and not get_metric("surface-area").uses_cone
    # The cone term grows as the cone widens (the S^2 reading of eq. 2), saturating at 90 degrees.
    d = [metric_eval(0, 1.0, 0., 0., 0., 0., 0., 0., cc, True, 1.0) for cc in (1.0, 0.9, 0.5, 0.0, -0.5)]
    assert d[0] == 0.0 and d[0] < d[1] < d[2] < d[3] == d[4] == 1.0


# ----------------------------------------------------------------------------------- the contract

@pytest.mark.parametrize("builder", ALL_BUILDERS)
@pytest.mark.parametrize("light_type", LIGHT_TYPES)
@pytest.mark.parametrize("n,duplicates", [(1, False), (2, False), (3, False), (2, True), (40, True), (150, False)])
def test_builder_contract(builder, light_type, n, duplicates):
    lights = random_lights(n, light_type, seed=n, duplicates=duplicates)
    tree = build_tree(lights, builder=builder, seed=5)
    validate_tree(tree, lights)
    assert tree.n_nodes == 2 * n - 1 and tree.n_lights == n
    assert tree.meta["builder"] == builder and tree.meta["type"] == light_type and tree.meta["n_lights"] == n
    np.testing.assert_allclose(tree.intensity[tree.root], lights.intensity.sum(axis=0), rtol=1e-12)
    # Deterministic: the same call builds the same tree.
    again = build_tree(lights, builder=builder, seed=5)
    for key in ("left", "right", "light", "rep", "cone_cos", "bbox_min"):
        assert np.array_equal(getattr(tree, key), getattr(again, key)), key


@pytest.mark.parametrize("builder", ALL_BUILDERS)
@pytest.mark.parametrize("metric", ["walter2005", "surface-area"])
def test_builder_contract_other_metrics(builder, metric):
    lights = random_lights(60, "oriented", seed=11)
    if "metric" not in BUILDERS.entry(builder).reads:
        with pytest.raises(LightcutsError, match=f"tree.metric: builder '{builder}' reads no metric"):
            build_tree(lights, builder=builder, metric=metric)
        return
    tree = build_tree(lights, builder=builder, metric=metric)
    validate_tree(tree, lights)
    assert tree.meta["metric"] == metric


@pytest.mark.parametrize("builder", ALL_BUILDERS)
def test_builder_contract_identical_lights(builder):
    # Every light at one point with one normal and intensity: every merge costs the same.
    n = 33
    lights = LightSet(np.tile([0.5, 0.2, 0.1], (n, 1)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones((n, 3)), "oriented")
    tree = build_tree(lights, builder=builder)
    validate_tree(tree, lights)
    assert np.all(tree.cone_cos == 1.0)


# ------------------------------------------------------------------------------------ build_tree

def test_single_light():
    lights = random_lights(1, "oriented")
    tree = build_tree(lights, builder="divisive-3d")
    assert tree.n_nodes == 1 and tree.root == 0 and tree.rep[0] == 0 and tree.cone_cos[0] == 1.0
    np.testing.assert_array_equal(tree.bbox_min[0], lights.position[0])
    np.testing.assert_allclose(tree.cone_axis[0], lights.normal[0], atol=1e-15)


def test_nodes_filled_bottom_up():
    lights = random_lights(200, "oriented", seed=2)
    tree = build_tree(lights, builder="divisive-6d")
    normal = lights.normal / np.linalg.norm(lights.normal, axis=1, keepdims=True)  # as build_tree does
    for node, members in zip(range(tree.n_nodes), _clusters_by_node(tree)):
        idx = sorted(members)
        np.testing.assert_array_equal(tree.bbox_min[node], lights.position[idx].min(axis=0))
        np.testing.assert_array_equal(tree.bbox_max[node], lights.position[idx].max(axis=0))
        axis, cos_half = normal_box_cone(normal[idx])
        assert cos_half == tree.cone_cos[node] and np.array_equal(axis, tree.cone_axis[node])
        np.testing.assert_allclose(tree.intensity[node], lights.intensity[idx].sum(axis=0), rtol=1e-12)


@pytest.mark.parametrize("builder", ["divisive-6d", "test-shuffled"])
def test_fill_on_threads_is_the_bottom_up_fill(builder, scratch_registries, thread_counts):
    """A tree large enough for the threaded fill: every node is its children's union, and the
    arrays are the same with one thread or two (a preorder builder, and one that is not)."""

    from lightcuts.trees import fill as fill_module

    lights = random_lights(25000, "oriented", seed=4)
    assert 2 * len(lights) - 1 >= fill_module._PARALLEL_MIN
    base = get_builder("divisive-6d")

    def shuffled(*args):
        left, right, light, root = base(*args)
        perm = np.random.default_rng(7).permutation(len(left))
        inv = np.argsort(perm)
        remap = lambda a: np.where(a >= 0, perm[np.maximum(a, 0)], -1)
        return remap(left)[inv], remap(right)[inv], light[inv], perm[root]

    BUILDERS.register("test-shuffled", shuffled)
    counts, num_threads = thread_counts
    trees = []
    for threads in counts:
        with num_threads(threads):
            trees.append(build_tree(lights, builder=builder, seed=5))
    one, two = trees
    for key in ("bbox_min", "bbox_max", "cone_axis", "cone_cos", "intensity", "rep"):
        np.testing.assert_array_equal(getattr(one, key), getattr(two, key), err_msg=key)
    inner = np.flatnonzero(two.left >= 0)
    a, b = two.left[inner], two.right[inner]
    np.testing.assert_array_equal(two.bbox_min[inner], np.minimum(two.bbox_min[a], two.bbox_min[b]))
    np.testing.assert_array_equal(two.bbox_max[inner], np.maximum(two.bbox_max[a], two.bbox_max[b]))
    np.testing.assert_array_equal(two.intensity[inner], two.intensity[a] + two.intensity[b])
    assert np.all((two.rep[inner] == two.rep[a]) | (two.rep[inner] == two.rep[b]))
    leaf = np.flatnonzero(two.left < 0)
    np.testing.assert_array_equal(two.bbox_min[leaf], lights.position[two.light[leaf]])
    np.testing.assert_array_equal(two.intensity[leaf], lights.intensity[two.light[leaf]])
    validate_tree(two, lights)


def _clusters_by_node(tree):
    out = [None] * tree.n_nodes
    stack = [(tree.root, False)]
    while stack:
        k, done = stack.pop()
        if tree.left[k] < 0:
            out[k] = {int(tree.light[k])}
        elif done:
            out[k] = out[tree.left[k]] | out[tree.right[k]]
        else:
            stack += [(k, True), (tree.left[k], False), (tree.right[k], False)]
    return out


def test_default_c():
    lights = random_lights(50, "oriented", seed=4)
    diag = np.linalg.norm(lights.position.max(axis=0) - lights.position.min(axis=0))
    assert default_c(lights) == pytest.approx(diag / 16)
    lights.meta["diagonal"] = 4.0  # as lights_from_config writes it
    assert default_c(lights) == 0.25
    lights.meta["scene_diagonal"] = 8.0
    assert default_c(lights) == 0.5
    assert build_tree(lights, builder="divisive-6d").meta["c"] == 0.5
    assert "c" not in build_tree(lights, builder="divisive-3d").meta  # reads no c
    assert build_tree(lights, builder="divisive-6d", c=2.0).meta["c"] == 2.0
    with pytest.raises(LightcutsError, match="tree.c: builder .divisive-3d. reads no c"):
        build_tree(lights, builder="divisive-3d", c=2.0)
    sun = random_lights(50, "directional", seed=4)
    sun.meta["scene_diagonal"] = 8.0  # directional lights live on the unit sphere: not used
    diag = np.linalg.norm(sun.position.max(axis=0) - sun.position.min(axis=0))
    assert default_c(sun) == pytest.approx(diag / 16)
    with pytest.raises(LightcutsError, match="tree.c"):
        build_tree(lights, builder="divisive-6d", c=-1.0)


def test_divisive_splits_at_the_middle_not_the_median():
    x = np.array([0.0, 0.1, 0.2, 0.3, 1.0])
    lights = LightSet(np.c_[x, np.zeros(5), np.zeros(5)], np.zeros((5, 3)), np.ones((5, 3)), "omni")
    tree = build_tree(lights, builder="divisive-3d")
    root_children = {frozenset(_clusters_by_node(tree)[c]) for c in (tree.left[tree.root], tree.right[tree.root])}
    assert root_children == {frozenset({0, 1, 2, 3}), frozenset({4})}


def test_divisive_6d_splits_by_normal():
    # Four lights at one point, two facing +z and two -z: 6D separates the normals first; 3D has no
    # spatial extent to split and falls back to an even split by index (which mixes them).
    normals = np.array([[0, 0, 1], [0, 0, -1], [0, 0, 1], [0, 0, -1]], float)
    lights = LightSet(np.zeros((4, 3)), normals, np.ones((4, 3)), "oriented")
    for builder, expect in (("divisive-6d", {frozenset({0, 2}), frozenset({1, 3})}),
                            ("divisive-3d", {frozenset({0, 1}), frozenset({2, 3})})):
        tree = build_tree(lights, builder=builder)
        validate_tree(tree, lights)
        assert {frozenset(_clusters_by_node(tree)[c]) for c in (tree.left[tree.root], tree.right[tree.root])} == expect


# ------------------------------------------------------------------------- greedy, the oracle

def brute_force_greedy(lights, cost):
    """Fig. 2 of the 2008 paper taken literally: O(N^3), every active pair at every step.

    cost(lum, lo, hi, cone_cos) of a union; ties by (cost, smaller id, larger id); merge m is
    cluster N + m. Returns the set of clusters (frozensets of light indices).
    """
    n = len(lights)
    oriented = lights.type == "oriented"
    clusters = {i: ([i], lights.position[i], lights.position[i], lights.normal[i], lights.normal[i],
                     lights.luminance[i]) for i in range(n)}
    out = {frozenset([i]) for i in range(n)}
    for new in range(n, 2 * n - 1):
        best = None
        for a, b in itertools.combinations(sorted(clusters), 2):
            ma, lo_a, hi_a, nlo_a, nhi_a, la = clusters[a]
            mb, lo_b, hi_b, nlo_b, nhi_b, lb = clusters[b]
            cone_cos = normal_box_cone([np.minimum(nlo_a, nlo_b), np.maximum(nhi_a, nhi_b)])[1] if oriented else -1.0
            key = (cost(la + lb, np.minimum(lo_a, lo_b), np.maximum(hi_a, hi_b), cone_cos), a, b)
            if best is None or key < best:
                best = key
        _, a, b = best
        ma, lo_a, hi_a, nlo_a, nhi_a, la = clusters.pop(a)
        mb, lo_b, hi_b, nlo_b, nhi_b, lb = clusters.pop(b)
        clusters[new] = (ma + mb, np.minimum(lo_a, lo_b), np.maximum(hi_a, hi_b), np.minimum(nlo_a, nlo_b),
                         np.maximum(nhi_a, nhi_b), la + lb)
        out.add(frozenset(ma + mb))
    return out


@pytest.mark.parametrize("metric", ["walter2008", "walter2005", "surface-area"])
@pytest.mark.parametrize("light_type", LIGHT_TYPES)
def test_greedy_matches_brute_force(metric, light_type):
    lights = random_lights(14, light_type, seed=21)
    m = get_metric(metric)
    has_cone = light_type == "oriented" and m.uses_cone
    c = default_c(lights)

    def cost(lum, lo, hi, cone_cos):
        return metric_eval(m.id, lum, *lo, *hi, cone_cos, has_cone, c)

    tree = build_tree(lights, builder="greedy", metric=metric)
    assert set(tree.clusters()) == brute_force_greedy(lights, cost)


def test_greedy_tie_rule():
    # Identical omni lights: every union costs 0, so the pair with the smallest ids merges first:
    # (0,1) -> 6, (2,3) -> 7, (4,5) -> 8, (6,7) -> 9, (8,9) -> 10.
    lights = LightSet(np.zeros((6, 3)), np.zeros((6, 3)), np.ones((6, 3)), "omni")
    tree = build_tree(lights, builder="greedy")
    assert tree.root == 10
    assert [(tree.left[k], tree.right[k]) for k in range(6, 11)] == [(0, 1), (2, 3), (4, 5), (6, 7), (8, 9)]
    assert set(tree.clusters()) == brute_force_greedy(lights, lambda lum, lo, hi, cc: 0.0)


@njit
def _perimeter_metric(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
    return intensity * ((hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2)) + (1.0 - cone_cos if has_cone else 0.0)




def test_user_metric_with_greedy(scratch_registries):
    metric = register_metric("test-perimeter", _perimeter_metric, description="I times half the box perimeter")
    assert get_metric("test-perimeter") is metric and not metric.builtin
    lights = random_lights(12, "oriented", seed=8)
    tree = build_tree(lights, builder="greedy", metric="test-perimeter", c=1.0)
    validate_tree(tree, lights)
    assert tree.meta["metric"] == "test-perimeter"

    def cost(lum, lo, hi, cone_cos):
        return _perimeter_metric(lum, *lo, *hi, cone_cos, True, 1.0)

    assert set(tree.clusters()) == brute_force_greedy(lights, cost)
    with pytest.raises(LightcutsError, match="njit"):
        register_metric("test-plain-python", lambda *a: 0.0)


# ------------------------------------------------------------------------------ representatives

def test_representative_of_two_lights_follows_intensity():
    # Luminances 1 and 3: the root takes light 0 with probability 1/4.
    lights = LightSet(np.array([[0, 0, 0], [1, 0, 0]], float), np.zeros((2, 3)), np.array([[1, 1, 1], [3, 3, 3]], float),
                      "omni")
    seeds = 2000
    hits = sum(build_tree(lights, builder="divisive-3d", seed=s).rep[0] == 0 for s in range(seeds))
    expect = seeds * 0.25
    assert abs(hits - expect) < 5 * np.sqrt(seeds * 0.25 * 0.75), hits


def test_root_representative_distribution_chi_square():
    # P(root representative = i) = I_i / sum I, whatever the tree: chi-square over many seeds.
    rng = np.random.default_rng(0)
    n = 8
    lum = np.array([1, 2, 3, 4, 0.5, 6, 7, 0.25])
    lights = LightSet(rng.random((n, 3)), np.zeros((n, 3)), np.outer(lum, [1, 1, 1]), "omni")
    seeds = 2000
    counts = np.bincount([build_tree(lights, builder="divisive-3d", seed=s).rep[0] for s in range(seeds)],
                         minlength=n)
    expect = seeds * lum / lum.sum()
    chi2 = ((counts - expect) ** 2 / expect).sum()
    assert chi2 < 30.0, (chi2, counts, expect)  # 7 degrees of freedom: P(chi2 > 30) ~ 1e-4


def test_representatives_do_not_depend_on_node_numbering(scratch_registries):
    lights = random_lights(300, "oriented", seed=12)
    base = get_builder("divisive-6d")

    def shuffled(position, normal, luminance, light_type, metric, c, seed):
        left, right, light, root = base(position, normal, luminance, light_type, metric, c, seed)
        perm = np.random.default_rng(99).permutation(len(left))  # new id of old node k: perm[k]
        inv = np.argsort(perm)
        remap = lambda a: np.where(a >= 0, perm[np.maximum(a, 0)], -1)
        return remap(left)[inv], remap(right)[inv], light[inv], perm[root]

    BUILDERS.register("test-shuffled", shuffled)
    a = build_tree(lights, builder="divisive-6d", seed=3)
    b = build_tree(lights, builder="test-shuffled", seed=3)
    validate_tree(b, lights)
    rep_a = {frozenset(c): r for c, r in zip(_clusters_by_node(a), a.rep)}
    rep_b = {frozenset(c): r for c, r in zip(_clusters_by_node(b), b.rep)}
    assert rep_a == rep_b


# ------------------------------------------------------------------------------ validate_tree

def test_validate_tree_catches_corruption():
    lights = random_lights(64, "oriented", seed=13)
    good = build_tree(lights, builder="divisive-6d")
    validate_tree(good, lights)
    internal = np.flatnonzero(good.left >= 0)
    k = int(internal[len(internal) // 2])

    def corrupted(**changes):
        arrays = {key: getattr(good, key).copy() for key in ("left", "right", "light", "bbox_min", "bbox_max",
                                                             "cone_axis", "cone_cos", "intensity", "rep")}
        for key, fn in changes.items():
            fn(arrays[key])
        return LightTree(**arrays, root=good.root)

    cases = {
        "box does not contain": dict(bbox_max=lambda a: a.__setitem__((good.root, 0), a[good.root, 0] - 1e-6)),
        "intensity": dict(intensity=lambda a: a.__setitem__((k, 1), a[k, 1] * 1.001)),
        "cone axis": dict(cone_cos=lambda a: a.__setitem__(k, 0.999999)),
        "representative": dict(rep=lambda a: a.__setitem__(good.left[good.root], a[good.right[good.root]])),
        "reached twice": dict(right=lambda a: a.__setitem__(k, good.left[k])),
        "every light": dict(light=lambda a: a.__setitem__(np.flatnonzero(good.left < 0)[:2], 0)),
    }
    for what, change in cases.items():
        with pytest.raises(AssertionError):
            validate_tree(corrupted(**change), lights)
    with pytest.raises(AssertionError, match="nodes for"):
        validate_tree(good, random_lights(10, "oriented"))


# ------------------------------------------------------------------------ registries and errors

def test_unknown_names_fail_with_the_valid_ones():
    lights = random_lights(5, "omni")
    with pytest.raises(LightcutsError, match=r"unknown builder 'nope'; valid: .*divisive-3d"):
        build_tree(lights, builder="nope")
    with pytest.raises(LightcutsError, match=r"unknown metric 'nope'; valid: .*walter2008"):
        build_tree(lights, builder="greedy", metric="nope")


def test_runtime_registered_builder_is_found(scratch_registries):
    def chain(position, normal, luminance, light_type, metric, c, seed):
        return _chain(len(position))

    BUILDERS.register("test-chain", chain)
    assert "test-chain" in BUILDERS.names()
    lights = random_lights(20, "omni")
    tree = build_tree(lights, builder="test-chain")
    validate_tree(tree, lights)
    assert tree.depth() == 20


def _chain(n):
    left, right, light = (np.full(2 * n - 1, -1) for _ in range(3))
    light[:n] = np.arange(n)
    prev = 0
    for m in range(n - 1):
        left[n + m], right[n + m], prev = prev, m + 1, n + m
    return left, right, light, prev


@pytest.mark.parametrize("mutation,message", [
    (lambda t: (t[0][:-1], t[1][:-1], t[2][:-1], t[3]), "shape"),
    (lambda t: (t[0], t[1], np.where(t[2] == 1, 0, t[2]), t[3]), "light 0 is in 2 leaves"),
    (lambda t: (t[0], t[1], t[2], 99), "root 99"),
    (lambda t: (t[0], np.where(t[1] == 3, 2, t[1]), t[2], t[3]), "child of"),
    (lambda t: t[:3], "tuple"),
])
def test_invalid_builder_output_names_the_builder(scratch_registries, mutation, message):
    BUILDERS.register("test-broken", lambda p, *rest: mutation(_chain(len(p))))
    with pytest.raises(LightcutsError, match=f"builder 'test-broken'.*{message}"):
        build_tree(random_lights(6, "omni"), builder="test-broken")


def test_bad_lights_fail_before_any_kernel():
    good = random_lights(4, "oriented")
    bad_pos = good.position.copy()
    bad_pos[2, 1] = np.nan
    with pytest.raises(LightcutsError, match="position has non-finite"):
        build_tree(LightSet(bad_pos, good.normal, good.intensity, "oriented"), builder="divisive-3d")
    with pytest.raises(LightcutsError, match="not unit length"):
        build_tree(LightSet(good.position, 2 * good.normal, good.intensity, "oriented"), builder="divisive-3d")
    with pytest.raises(LightcutsError, match="negative"):
        build_tree(LightSet(good.position, good.normal, -good.intensity, "oriented"), builder="divisive-3d")


@pytest.mark.parametrize("arrays,message", [
    (dict(position=np.zeros((3, 3)), intensity=np.ones((3, 3)), type=np.array("omni")), "missing key"),
    (dict(position=np.zeros((3, 2)), normal=np.zeros((3, 3)), intensity=np.ones((3, 3)), type=np.array("omni")),
     "shape"),
    (dict(position=np.full((3, 3), np.nan), normal=np.zeros((3, 3)), intensity=np.ones((3, 3)),
          type=np.array("omni")), "non-finite"),
])
def test_malformed_light_files_through_the_cli(tmp_path, capsys, arrays, message):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    assert cli_main(["tree", "--lights", str(path), "--builder", "divisive-3d", "--out", str(tmp_path / "t.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and str(path) in err and message in err and "\n" not in err
    assert not (tmp_path / "t.npz").exists()


def test_npz_round_trip(tmp_path):
    lights = random_lights(100, "oriented", seed=6)
    tree = build_tree(lights, builder="divisive-6d", seed=4)
    loaded = LightTree.load(tree.save(tmp_path / "tree.npz"))
    for key in ("left", "right", "light", "bbox_min", "bbox_max", "cone_axis", "cone_cos", "intensity", "rep"):
        a, b = getattr(tree, key), getattr(loaded, key)
        assert a.dtype == b.dtype and np.array_equal(a, b), key
    assert loaded.root == tree.root and loaded.meta == tree.meta
    validate_tree(loaded, lights)


def test_entry_point_plugins_are_found(tmp_path):
    """A builder and a metric from another package (a dist-info on sys.path), in a fresh process.

    A fresh process is how a plugin meets the registry in practice (installed before the run); it also
    keeps this test independent of the registries' entry-point cache in the test process.
    """
    (tmp_path / "tinyplugin.py").write_text(textwrap.dedent("""
        import numpy as np
        from numba import njit

        def chain(position, normal, luminance, light_type, metric, c, seed):
            n = len(position)
            left, right, light = (np.full(2 * n - 1, -1) for _ in range(3))
            light[:n] = np.arange(n)
            prev = 0
            for m in range(n - 1):
                left[n + m], right[n + m], prev = prev, m + 1, n + m
            return left, right, light, prev

        @njit
        def perimeter(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
            return intensity * ((hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2))
    """))
    info = tmp_path / "tinyplugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tinyplugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[lightcuts.builders]\ntiny-chain = tinyplugin:chain\n\n[lightcuts.metrics]\ntiny-perimeter = tinyplugin:perimeter\n")
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        import numpy as np
        from lightcuts.lights import LightSet
        from lightcuts.trees import BUILDERS, METRICS, build_tree, validate_tree
        assert "tiny-chain" in BUILDERS.names() and "tiny-perimeter" in METRICS.names()
        rng = np.random.default_rng(0)
        lights = LightSet(rng.random((9, 3)), np.zeros((9, 3)), rng.random((9, 3)), "omni")
        tree = build_tree(lights, builder="tiny-chain")
        validate_tree(tree, lights)
        assert tree.depth() == 9
        tree = build_tree(lights, builder="greedy", metric="tiny-perimeter")
        validate_tree(tree, lights)
        print("ok", tree.meta["metric"])
    """)
    env = dict(os.environ, PYTHONPATH=str(Path(lightcuts.__file__).parents[1]))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["ok", "tiny-perimeter"]


# ----------------------------------------------------------------------------- scaling report

def test_scaling_helpers():
    from lightcuts.commands.scaling import parse_sizes, resolve_specs
    from lightcuts.config.schema import config_from_dict
    from lightcuts.report.scaling import fitted_exponent

    cfg = config_from_dict({"scene": {"builtin": "cornell"}})

    def resolve_builders(text):
        return [s.name for s in resolve_specs(text, cfg)]

    assert parse_sizes("400, 100,400") == [100, 400]
    for bad in ("", "10,x", "0"):
        with pytest.raises(LightcutsError, match="--sizes"):
            parse_sizes(bad)
    n = np.array([1e3, 1e4, 1e5])
    assert fitted_exponent(n, 3e-6 * n ** 1.5) == pytest.approx(1.5)
    assert np.isnan(fitted_exponent(n[:1], n[:1]))
    assert "greedy" not in resolve_builders(None) and "divisive-3d" in resolve_builders(None)
    with pytest.raises(LightcutsError, match="unknown builder"):
        resolve_builders("divisive-3d,nope")


def test_scaling_command_end_to_end(tmp_path, capsys):
    import csv

    cfg = tmp_path / "box.yaml"
    cfg.write_text("name: box\nseed: 3\nscene: {builtin: cornell}\nlights: {indirect: {count: 10}}\n")
    out = tmp_path / "out"
    argv = ["scaling", str(cfg), "--sizes", "300,600", "--builders", "divisive-3d,divisive-6d", "--repeats", "2",
            "--out", str(out)]
    assert cli_main(argv) == 0
    rows = list(csv.DictReader((out / "scaling.csv").open()))
    assert [(r["n_requested"], r["builder"]) for r in rows] == [
        ("300", "divisive-3d"), ("300", "divisive-6d"), ("600", "divisive-3d"), ("600", "divisive-6d")]
    for r in rows:
        assert int(r["n_lights"]) > 0 and 0 < float(r["min_s"]) <= float(r["median_s"]) and int(r["depth"]) > 1
    assert (out / "scaling.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "fitted exponent divisive-3d" in capsys.readouterr().out
    assert cli_main(["scaling", str(cfg), "--sizes", "50000", "--builders", "greedy", "--out", str(out)]) == 2


def test_render_scaling_rows_equal_single_renders(tmp_path):
    import csv
    import json

    cfg = tmp_path / "box.yaml"
    cfg.write_text("name: box\nseed: 3\nscene: {builtin: cornell}\ncamera: {resolution: [24, 24]}\n"
                   "lights: {indirect: {count: 10}}\n")
    out = tmp_path / "out"
    assert cli_main(["scaling", str(cfg), "--render", "--sizes", "400,1200", "--builders", "divisive-6d",
                     "--repeats", "1", "--out", str(out), "--no-progress"]) == 0
    rows = list(csv.DictReader((out / "render_scaling.csv").open()))
    assert [r["n_requested"] for r in rows] == ["400", "1200"]
    assert (out / "render_scaling.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for r in rows:
        single = tmp_path / f"r{r['n_requested']}"
        assert cli_main(["render", str(cfg), "--out", str(single), "--no-progress", "--set", "tree.builder=divisive-6d",
                         "--set", f"lights.indirect.count={r['n_requested']}", "--set", "lights.direct.count=0"]) == 0
        report = json.loads((single / "report.json").read_text())
        assert float(r["cut_mean"]) == report["cut_size_mean"] and float(r["cut_max"]) == report["cut_size_max"]
        assert float(r["shadow_rays_per_pixel"]) == report["shadow_rays_per_pixel"]
        assert int(r["n_lights"]) == report["lights"]["oriented"] and float(r["render_s"]) > 0


def test_nearly_unit_normals_stay_inside_their_cones():
    # Normals read back from float32 are unit only to ~1e-7; the cones must still contain them.
    lights = random_lights(500, "oriented", seed=14)
    lights.normal = lights.normal.astype(np.float32).astype(np.float64) * (1 - 5e-7)
    for builder in ("divisive-6d", "greedy"):
        validate_tree(build_tree(lights, builder=builder), lights, angle_tol=1e-12)
