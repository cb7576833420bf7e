"""The ``saoh`` builder: its splits against a brute-force evaluation of the heuristic, validity on
degenerate input, determinism across thread counts."""

from __future__ import annotations

import numpy as np
import pytest

from lightcuts.limits import MAX_COORD, MAX_INTENSITY
from lightcuts.lights import LightSet
from lightcuts.trees import build_tree, get_builder, validate_tree
from lightcuts.trees import saoh as saoh_module
from lightcuts.cluster.cones import cones_from_boxes
from lightcuts.trees.saoh import BUCKETS, m_omega, split_costs

from conftest import random_lights, unit

LIGHT_TYPES = ("omni", "oriented", "directional")


# ------------------------------------------------------------------ brute force, written from the paper

def _m_omega(cos_o, theta_e=np.pi / 2):
    """M_Omega (Conty Estevez and Kulla 2018) in its general form."""
    theta_o = np.arccos(np.clip(cos_o, -1.0, 1.0))
    theta_w = min(theta_o + theta_e, np.pi)
    s = np.sin(theta_o)
    return (2 * np.pi * (1 - np.cos(theta_o))
            + np.pi / 2 * (2 * theta_w * s - np.cos(theta_o - 2 * theta_w) - 2 * theta_o * s + np.cos(theta_o)))


def _side_cost(pos, nrm, lum, oriented):
    d = pos.max(axis=0) - pos.min(axis=0)
    area = 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
    m = _m_omega(cones_from_boxes(nrm.min(axis=0), nrm.max(axis=0))[1][0]) if oriented else 4 * np.pi
    return lum.sum() * m * area


def _brute(pos, nrm, lum, light_type):
    """(3, BUCKETS - 1) costs (inf where not a split) and the left-side masks of the valid ones."""
    oriented = light_type == "oriented"
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    ext = hi - lo
    costs = np.full((3, BUCKETS - 1), np.inf)
    masks = {}
    for a in range(3):
        if ext[a] <= 0:
            continue
        bucket = np.minimum((BUCKETS * ((pos[:, a] - lo[a]) / ext[a])).astype(int), BUCKETS - 1)
        for i in range(BUCKETS - 1):
            left = bucket <= i
            if left.all() or not left.any():
                continue
            costs[a, i] = ext.max() / ext[a] * (_side_cost(pos[left], nrm[left], lum[left], oriented)
                                                + _side_cost(pos[~left], nrm[~left], lum[~left], oriented))
            masks[a, i] = left
    return costs, masks


def _members(tree, node):
    out, stack = [], [node]
    while stack:
        k = stack.pop()
        if tree.left[k] < 0:
            out.append(int(tree.light[k]))
        else:
            stack += [int(tree.left[k]), int(tree.right[k])]
    return np.array(sorted(out))


def _slab(light_type):
    """64 lights in a slab 2 x 1 x 0.1 with a gap at y = 0.5; oriented ones face +z below the gap
    and -z above it."""
    rng = np.random.default_rng(0)
    pos = rng.random((64, 3)) * [2.0, 0.4, 0.1]
    up = np.arange(64) % 2 == 1
    pos[up, 1] += 0.6
    nrm = np.zeros((64, 3))
    nrm[:, 2] = np.where(up, -1.0, 1.0)
    if light_type != "oriented":
        nrm[:, 2] = 0.0
    return LightSet(pos, nrm, np.ones((64, 3)), light_type), up


# ------------------------------------------------------------------------------------------ tests

def test_m_omega_reduced_form_is_the_general_formula():
    for c in np.linspace(-1.0, 1.0, 41):
        assert m_omega(c) == pytest.approx(_m_omega(c), rel=1e-13, abs=1e-13)
    assert m_omega(1.0) == pytest.approx(np.pi) and m_omega(-1.0) == pytest.approx(4 * np.pi)


def test_two_groups_are_split_apart():
    rng = np.random.default_rng(1)
    pos = np.concatenate([rng.random((20, 3)), rng.random((30, 3)) + [10.0, 0.0, 0.0]])
    lights = LightSet(pos, unit(rng.normal(size=(50, 3))), rng.random((50, 3)), "oriented")
    tree = build_tree(lights, builder="saoh")
    parts = {tuple(_members(tree, tree.left[0])), tuple(_members(tree, tree.right[0]))}
    assert parts == {tuple(range(20)), tuple(range(20, 50))}


@pytest.mark.parametrize("light_type", ["oriented", "omni"])
def test_orientation_decides_the_root_split(light_type):
    """Omni lights: the long axis x wins. Oriented lights: the cut through the gap in y, which
    separates the two facings (each side's cone a single normal, M_Omega = pi instead of 4 pi)."""
    lights, up = _slab(light_type)
    costs, masks = _brute(lights.position, lights.normal, lights.luminance, light_type)
    kernel = split_costs(lights.position, lights.normal, lights.luminance, light_type)
    finite = np.isfinite(costs)
    np.testing.assert_array_equal(np.isfinite(kernel), finite)
    np.testing.assert_allclose(kernel[finite], costs[finite], rtol=1e-12)
    axis, bound = np.unravel_index(np.argmin(costs), costs.shape)
    assert np.argmin(kernel) == np.argmin(costs)
    tree = build_tree(lights, builder="saoh")
    left = _members(tree, tree.left[0])
    np.testing.assert_array_equal(left, np.flatnonzero(masks[axis, bound]))
    if light_type == "oriented":
        assert axis == 1
        np.testing.assert_array_equal(left, np.flatnonzero(~up))
    else:
        assert axis == 0


@pytest.mark.parametrize("light_type", LIGHT_TYPES)
def test_every_split_is_the_least_cost_candidate(light_type):
    """At every node the left child is the left side of a candidate of least brute-force cost."""
    lights = random_lights(60, light_type, seed=5)
    tree = build_tree(lights, builder="saoh")
    validate_tree(tree, lights)
    for node in np.flatnonzero(tree.left >= 0):
        idx = _members(tree, node)
        costs, masks = _brute(lights.position[idx], lights.normal[idx], lights.luminance[idx], light_type)
        left = set(_members(tree, tree.left[node]))
        best = costs.min()
        assert np.isfinite(best)
        chosen = [costs[k] for k, m in masks.items() if set(idx[m]) == left]
        assert chosen and min(chosen) <= best * (1 + 1e-12), (node, chosen, best)


@pytest.mark.parametrize("light_type", LIGHT_TYPES)
@pytest.mark.parametrize("duplicates", [False, True])
def test_valid_tree(light_type, duplicates):
    lights = random_lights(300, light_type, seed=2, duplicates=duplicates)
    validate_tree(build_tree(lights, builder="saoh", seed=1), lights)


def test_all_lights_at_one_point_split_evenly_by_index():
    n = 37
    lights = LightSet(np.tile([0.3, -2.0, 5.0], (n, 1)), np.tile([0.0, 1.0, 0.0], (n, 1)), np.ones((n, 3)), "oriented")
    assert not np.isfinite(split_costs(lights.position, lights.normal, lights.luminance, "oriented")).any()
    tree = build_tree(lights, builder="saoh")
    validate_tree(tree, lights)
    np.testing.assert_array_equal(_members(tree, tree.left[0]), np.arange(n // 2))
    depth = np.zeros(tree.n_nodes, int)
    for k in range(tree.n_nodes):  # depth-first ids: parents before children
        if tree.left[k] >= 0:
            depth[[tree.left[k], tree.right[k]]] = depth[k] + 1
    assert depth.max() == int(np.ceil(np.log2(n)))


def _degenerate(case):
    rng = np.random.default_rng(3)
    n = 200
    pos = rng.random((n, 3))
    nrm = unit(rng.normal(size=(n, 3)))
    inten = rng.random((n, 3))
    if case == "coplanar":
        pos[:, 2] = 0.25
    elif case == "collinear":
        pos[:, 1:] = 0.5
    elif case == "two-points":
        pos = np.where(rng.random((n, 1)) < 0.5, 0.0, 1.0) * np.ones((1, 3))
    elif case == "black":
        inten[:] = 0.0
    elif case == "extreme":
        pos = rng.choice([-MAX_COORD, MAX_COORD, 0.0], size=(n, 3))
        pos[:5, 0] = 5e-324  # a subnormal step next to the largest coordinates
        inten = np.full((n, 3), MAX_INTENSITY)
    return LightSet(pos, nrm, inten, "oriented")


@pytest.mark.parametrize("case", ["coplanar", "collinear", "two-points", "black", "extreme"])
def test_degenerate_input_terminates_with_a_valid_tree(case):
    lights = _degenerate(case)
    tree = build_tree(lights, builder="saoh")
    validate_tree(tree, lights)
    if case == "coplanar":  # a flat box still has area: the heuristic still chooses
        costs = _brute(lights.position, lights.normal, lights.luminance, "oriented")[0]
        kernel = split_costs(lights.position, lights.normal, lights.luminance, "oriented")
        assert np.argmin(kernel) == np.argmin(costs) and np.min(costs) > 0


def test_same_tree_for_any_thread_count(thread_counts):
    lights = random_lights(30000, "oriented", seed=9)
    assert len(lights) >= saoh_module._PARALLEL_MIN
    counts, num_threads = thread_counts
    trees = []
    for threads in counts:
        with num_threads(threads):
            trees.append(build_tree(lights, builder="saoh", seed=4))
    one, two = trees
    for key in ("left", "right", "light", "bbox_min", "bbox_max", "cone_axis", "cone_cos", "intensity", "rep"):
        assert getattr(one, key).tobytes() == getattr(two, key).tobytes(), key


def test_builder_does_not_modify_its_inputs():
    lights = random_lights(100, "oriented", seed=6)
    pos, nrm, lum = lights.position.copy(), lights.normal.copy(), lights.luminance.copy()
    get_builder("saoh")(pos, nrm, lum, "oriented", None, None, 0)
    np.testing.assert_array_equal(pos, lights.position)
    np.testing.assert_array_equal(nrm, lights.normal)
    np.testing.assert_array_equal(lum, lights.luminance)
