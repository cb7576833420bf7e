"""Property tests of the lightcut error bounds (lightcuts.integrators.bounds) against exact shading.

For random receivers, materials and clusters of lights of all three types, the bound I_C M_ub G_ub
must be >= the contribution M G I of every light the box (and cone) holds, channel by channel; the
cone bound >= the true cosine; and the clamped bound >= the clamped contribution.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.integrators.bounds import (BOUND_SLACK, DIRECTIONAL, OMNI, ORIENTED, box_distance2, cluster_error_bound,
                                     cone_cos_bound, geometric_bound, material_bound, max_cos_in_box)
from lightcuts.integrators.bounds import receiver_frames
from lightcuts.integrators.cut import _light_mg, node_bound
from lightcuts.integrators.forest import (LF_INDIRECT, LF_NRM, LF_POS, LF_TYPE, NB_I, NB_REP, NF_I, NK_LEFT, NK_REP,
                                     NK_RIGHT, REP_BITS, build_forest, pack_nodes)
from lightcuts.integrators.shading import facing_normal, reflect, unshadowed_contribution
from lightcuts.trees.build import build_tree

SETTINGS = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])

coord = st.floats(-5.0, 5.0, allow_nan=False, allow_infinity=False)
seeds = st.integers(0, 2**32 - 1)


def normalized(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def unit(rng, n=None):
    """A random unit vector (3,), or n of them (n, 3)."""
    return normalized(rng.normal(size=(3,) if n is None else (n, 3)))


def random_receiver(rng):
    """Point x, unit normal N facing wo, wo, R = reflect(wo, N)."""
    x = rng.uniform(-4, 4, 3)
    wo = unit(rng)
    n = np.array(facing_normal(*unit(rng), *wo))
    r = np.array(reflect(*wo, *n))
    return x, n, r


def random_material(rng):
    albedo = rng.uniform(0, 1, 3) * (rng.random() < 0.9)
    glossy = rng.random() < 0.6
    specular = rng.uniform(0, 1, 3) if glossy else np.zeros(3)
    exponent = float(rng.choice([0.0, 1.0, 5.0, 20.0, 80.0, 200.0, rng.uniform(0, 200)])) if glossy else 0.0
    return albedo, specular, exponent


def cone_around(rng, axis, cos_half, n):
    """n unit normals in the cone (axis, cos_half): uniform over the cap, about a third on its edge."""
    t1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(axis, t1)
    cos_t = np.where(rng.random(n) < 0.3, cos_half, rng.uniform(cos_half, 1.0, n))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t ** 2))
    phi = rng.uniform(0, 2 * np.pi, n)
    v = cos_t[:, None] * axis + sin_t[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_cluster(rng, light_type, x):
    """A box, a cone, and lights inside both (corners of the box included)."""
    n = int(rng.integers(1, 12))
    if light_type == DIRECTIONAL:
        centre = unit(rng)
        spread = rng.uniform(0, 1.5)
        dirs = normalized(centre + spread * rng.normal(size=(n, 3)))
        lo, hi = dirs.min(axis=0), dirs.max(axis=0)
        return lo, hi, np.zeros(3), -1.0, dirs, np.zeros((n, 3))
    centre = rng.uniform(-4, 4, 3)
    if rng.random() < 0.2:  # a box near the receiver: small distances stress the 1/d^2 bound
        centre = x + unit(rng) * rng.uniform(0.05, 1.0)
    half = rng.uniform(0, 1.5, 3) * (rng.random(3) < 0.9)
    lo, hi = centre - half, centre + half
    pos = rng.uniform(lo, hi, (n, 3))
    corners = np.array([[(lo, hi)[(k >> d) & 1][d] for d in range(3)] for k in range(8)])
    pos = np.concatenate([pos, corners[rng.integers(0, 8, 3)]])
    if light_type == OMNI:
        return lo, hi, np.zeros(3), -1.0, pos, np.zeros_like(pos)
    if rng.random() < 0.15:
        return lo, hi, np.zeros(3), -1.0, pos, unit(rng, len(pos))  # full sphere
    axis = unit(rng)
    cos_half = float(rng.choice([1.0, rng.uniform(0.5, 1.0), rng.uniform(-1.0, 1.0)]))
    return lo, hi, axis, cos_half, pos, cone_around(rng, axis, cos_half, len(pos))


def check_cluster(seed, light_type, clamp_d2):
    rng = np.random.default_rng(seed)
    x, n, r = random_receiver(rng)
    albedo, specular, exponent = random_material(rng)
    lo, hi, axis, cos_half, pos, nrm = random_cluster(rng, light_type, x)
    intensity = rng.uniform(0, 10, (len(pos), 3))
    total = intensity.sum(axis=0)
    bound = np.array(cluster_error_bound(*x, *n, *r, *albedo, *specular, exponent, light_type, *lo, *hi, *axis,
                                         cos_half, *total, clamp_d2))
    for j in range(len(pos)):
        c = np.array(unshadowed_contribution(light_type, *pos[j], *nrm[j], *total, *x, *n, *r, *albedo, *specular,
                                             exponent, clamp_d2))
        assert np.all(c <= bound), (j, c, bound)


@SETTINGS
@given(seeds)
def test_bound_holds_for_omni_clusters(seed):
    check_cluster(seed, OMNI, 0.0)


@SETTINGS
@given(seeds)
def test_bound_holds_for_oriented_clusters(seed):
    check_cluster(seed, ORIENTED, 0.0)


@SETTINGS
@given(seeds)
def test_bound_holds_for_directional_clusters(seed):
    check_cluster(seed, DIRECTIONAL, 0.0)


@SETTINGS
@given(seeds, st.sampled_from([OMNI, ORIENTED]), st.floats(1e-4, 4.0))
def test_clamped_bound_holds_for_clamped_contributions(seed, light_type, min_distance):
    check_cluster(seed, light_type, min_distance ** 2)


@SETTINGS
@given(seeds, st.sampled_from([OMNI, ORIENTED, DIRECTIONAL]), st.sampled_from([0.0, 0.01, 1.0]))
def test_fused_bound_is_the_product_of_its_terms(seed, light_type, clamp_d2):
    """cluster_error_bound evaluates I * M_ub * G_ub as ratios with one division: the same value as
    the product of material_bound and geometric_bound, up to rounding."""
    rng = np.random.default_rng(seed)
    x, n, r = random_receiver(rng)
    albedo, specular, exponent = random_material(rng)
    lo, hi, axis, cos_half, _, _ = random_cluster(rng, light_type, x)
    i = rng.uniform(0, 10, 3)
    fused = np.array(cluster_error_bound(*x, *n, *r, *albedo, *specular, exponent, light_type, *lo, *hi, *axis,
                                         cos_half, *i, clamp_d2))
    m = np.array(material_bound(*x, *n, *r, *albedo, *specular, exponent, *lo, *hi, light_type == DIRECTIONAL))
    g = geometric_bound(*x, light_type, *lo, *hi, *axis, cos_half, clamp_d2)
    with np.errstate(invalid="ignore"):
        product = np.where((i * m > 0) & (g > 0), i * m * g * BOUND_SLACK, 0.0)
    np.testing.assert_allclose(fused, product, rtol=1e-12, atol=0)


@SETTINGS
@given(seeds)
def test_bound_is_tight_for_a_single_light(seed):
    """A box around one light (lo == hi) bounds that light with no slack beyond rounding."""
    rng = np.random.default_rng(seed)
    x, n, r = random_receiver(rng)
    albedo, specular, exponent = random_material(rng)
    y = x + unit(rng) * rng.uniform(0.5, 3.0)
    nl = unit(rng)
    i = rng.uniform(0.1, 10, 3)
    c = np.array(unshadowed_contribution(ORIENTED, *y, *nl, *i, *x, *n, *r, *albedo, *specular, exponent, 0.0))
    b = np.array(cluster_error_bound(*x, *n, *r, *albedo, *specular, exponent, ORIENTED, *y, *y, *nl, 1.0, *i, 0.0))
    np.testing.assert_allclose(b, c, rtol=1e-6, atol=1e-12)


@SETTINGS
@given(seeds)
def test_cone_bound_holds_for_every_direction_from_the_box(seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-4, 4, 3)
    lo, hi, axis, cos_half, pos, nrm = random_cluster(rng, ORIENTED, x)
    b = cone_cos_bound(*x, *lo, *hi, *axis, cos_half)
    for y, nl in zip(pos, nrm):
        v = x - y
        d = np.linalg.norm(v)
        if d > 0:
            assert max(0.0, nl @ v / d) <= b * (1 + 1e-12), (b, nl @ v / d)


@SETTINGS
@given(seeds)
def test_max_cos_in_box_bounds_every_vector_and_is_exact_for_a_point(seed):
    rng = np.random.default_rng(seed)
    z = unit(rng)
    lo = rng.uniform(-3, 3, 3)
    hi = lo + rng.uniform(0, 2, 3) * (rng.random(3) < 0.8)
    b = max_cos_in_box(*z, *lo, *hi)
    assert -1.0 <= b <= 1.0
    for v in np.concatenate([rng.uniform(lo, hi, (50, 3)), [lo, hi]]):
        if np.linalg.norm(v) > 0:
            assert z @ v / np.linalg.norm(v) <= b + 1e-12
    p = lo
    assert math.isclose(max_cos_in_box(*z, *p, *p), z @ p / np.linalg.norm(p), abs_tol=1e-12)


def bound(x, n, albedo, specular, exponent, light_type, lo, hi, intensity, axis=(0.0, 0.0, 0.0), cone_cos=-1.0):
    return cluster_error_bound(*x, *n, *n, *albedo, *specular, exponent, light_type, *lo, *hi, *axis, cone_cos,
                               *intensity, 0.0)


def test_receiver_inside_a_box_gives_an_infinite_bound():
    lo, hi = np.array([-1.0, -1, -1]), np.array([1.0, 1, 1])
    x, n = np.zeros(3), np.array([0.0, 0, 1])
    b = bound(x, n, np.ones(3), np.zeros(3), 0.0, OMNI, lo, hi, np.ones(3))
    assert all(math.isinf(v) for v in b)
    assert box_distance2(*x, *lo, *hi) == 0.0
    assert box_distance2(3.0, 0.0, -2.0, *lo, *hi) == 5.0
    # A black channel (no intensity) stays 0, not NaN.
    b = bound(x, n, np.ones(3), np.zeros(3), 0.0, OMNI, lo, hi, np.array([1.0, 0.0, 1.0]))
    assert b[1] == 0.0 and math.isinf(b[0])


def test_cluster_behind_the_surface_has_zero_bound():
    x, n = np.zeros(3), np.array([0.0, 0, 1])
    b = bound(x, n, np.ones(3), np.ones(3), 10.0, OMNI, np.array([-1.0, -1, -3]), np.array([1.0, 1, -0.5]),
              np.ones(3))
    assert b == (0.0, 0.0, 0.0)
    # Directional: every direction of the box points below the horizon.
    b = bound(x, n, np.ones(3), np.zeros(3), 0.0, DIRECTIONAL, np.array([0.0, 0, -1]), np.array([0.5, 0.5, -0.7]),
              np.ones(3))
    assert b == (0.0, 0.0, 0.0)


def test_oriented_lights_facing_away_have_zero_bound():
    """A cone of normals pointing away from the receiver (more than 90 degrees from x - y) gives 0."""
    x = np.zeros(3)
    lo, hi = np.array([-1.0, -1, 2]), np.array([1.0, 1, 3])  # above x
    axis = np.array([0.0, 0, 1])                                # lights face up, away from x
    assert cone_cos_bound(*x, *lo, *hi, *axis, math.cos(math.radians(20))) == 0.0
    assert cone_cos_bound(*x, *lo, *hi, *-axis, math.cos(math.radians(20))) == 1.0
    assert cone_cos_bound(*x, *lo, *hi, *axis, -1.0) == 1.0


# The kernel's own path: node records packed to float32 (boxes rounded outwards, cones widened), the
# bound read from them by lightcuts.integrators.cut.node_bound, against every light below each node.

@njit(cache=True)
def _packed_bounds(node_b, node_bi, x, n, r, rd, rs, exponent, clamp_d2, out):
    fr = receiver_frames(n[0], n[1], n[2], r[0], r[1], r[2])
    for k in range(node_b.shape[0]):
        out[k] = node_bound(k, node_b, node_bi, x[0], x[1], x[2], n[0], n[1], n[2], r[0], r[1], r[2], fr,
                            rd[0], rd[1], rd[2], rs[0], rs[1], rs[2], exponent, clamp_d2)


@njit(cache=True)
def _contributions(light_f, light_i, x, n, r, rd, rs, exponent, clamp_d2, out):
    """M G I per RGB channel of every light (V = 1), as the cut computes it for a representative."""
    for j in range(light_f.shape[0]):
        c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
        res = _light_mg(np.int64(light_f[j, LF_TYPE]), light_f[j, LF_POS], light_f[j, LF_POS + 1],
                        light_f[j, LF_POS + 2], light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2],
                        c2, x[0], x[1], x[2], n[0], n[1], n[2], r[0], r[1], r[2], rd[0], rd[1], rd[2],
                        rs[0], rs[1], rs[2], exponent, 0.0)
        lit = res[4]
        out[j, 0] = res[0] * light_i[j, 0] if lit else 0.0
        out[j, 1] = res[1] * light_i[j, 1] if lit else 0.0
        out[j, 2] = res[2] * light_i[j, 2] if lit else 0.0


def _random_light_sets(rng):
    """Clustered lights of every type, a third of them in pairs at one point with one normal. Those
    pairs become clusters whose bound equals their contribution up to BOUND_SLACK, so that a record
    rounded inwards (a float32 box rounded to nearest) fails the test."""
    centres = rng.uniform(-3, 3, (6, 3))
    pos = centres[rng.integers(0, 6, 300)] + rng.normal(scale=0.05, size=(300, 3)) * rng.uniform(0, 1, (300, 1))
    facing = unit(rng, 6)
    nrm = normalized(facing[rng.integers(0, 6, 300)] + rng.normal(scale=0.1, size=(300, 3)))
    inten = rng.uniform(0, 1, (300, 3)) * rng.uniform(0.01, 10, (300, 1))
    dirs = normalized(unit(rng)[None, :] + rng.normal(scale=0.2, size=(40, 3)))
    pos[1:100:3], nrm[1:100:3] = pos[0:99:3], nrm[0:99:3]
    pos[101:300:3], nrm[101:300:3] = pos[100:299:3], nrm[100:299:3]
    dirs[1:40:3] = dirs[0:39:3]
    return {
        "omni": LightSet(pos[:100], np.zeros((100, 3)), inten[:100], "omni", rng.random(100) < 0.5),
        "oriented": LightSet(pos[100:], nrm[100:], inten[100:], "oriented", rng.random(200) < 0.5),
        "directional": LightSet(dirs, np.zeros((40, 3)), inten[:40], "directional"),
    }


@pytest.mark.parametrize("builder", ["agglomerative", "divisive-6d"])
def test_packed_node_records_bound_every_light_below_them(builder):
    rng = np.random.default_rng(5)
    for trial in range(4):
        sets = _random_light_sets(rng)
        trees = {k: build_tree(v, builder, seed=trial) for k, v in sets.items()}
        forest = build_forest(sets, trees)
        k_nodes = len(forest.node_k)
        left, right, rep = forest.node_k[:, NK_LEFT], forest.node_k[:, NK_RIGHT], forest.node_k[:, NK_REP]
        bounds, contrib = np.empty(k_nodes), np.empty((len(forest.light_f), 3))
        inner = left >= 0
        # A record holds the summed intensity rounded to the nearest float32 (estimate and bound
        # alike; lightcuts.integrators.forest.pack_nodes): the lights' sum is scaled by the same rounding.
        rounding = np.divide(forest.node_b[:, NB_I:NB_I + 3], forest.node_f[:, NF_I:NF_I + 3],
                             out=np.ones((k_nodes, 3)), where=forest.node_f[:, NF_I:NF_I + 3] > 0)
        checked = 0
        for _ in range(40):
            x, n, r = random_receiver(rng)
            if rng.random() < 0.3:   # among the lights, where boxes are near and cones matter most
                x = sets["oriented"].position[rng.integers(200)] + rng.normal(scale=0.1, size=3)
            rd, rs, exponent = random_material(rng)
            clamp_d2 = float(rng.choice([0.0, 0.01, 0.3]))
            _packed_bounds(forest.node_b, forest.node_bi, x, n, r, rd, rs, exponent, clamp_d2, bounds)
            _contributions(forest.light_f, forest.light_i, x, n, r, rd, rs, exponent, clamp_d2, contrib)
            # Sums of the lights below each node: children come after their parent (level order).
            total = np.where(inner[:, None], 0.0, contrib[rep])
            for k in np.flatnonzero(inner)[::-1]:
                total[k] = total[left[k]] + total[right[k]]
            total = (total * rounding) @ LUMINANCE
            bad = inner & (bounds < total * (1.0 - 1e-12))
            assert not bad.any(), (trial, np.flatnonzero(bad)[:5], bounds[bad][:5], total[bad][:5])
            checked += int((inner & (total > 0)).sum())
        assert checked > 1000


def test_node_records_refuse_representatives_beyond_their_bits():
    # A record packs the representative's light id below REP_BITS and the flags above it: an id that
    # does not fit must be refused, not silently mixed into the flags.
    node_f = np.zeros((1, 16))
    for rep, ok in ((2 ** REP_BITS - 1, True), (2 ** REP_BITS, False)):
        node_k = np.array([[-1, -1, rep, 1]], np.int64)
        if ok:
            node_b, node_bi = pack_nodes(node_f, node_k)
            assert node_bi[0, NB_REP] & (2 ** REP_BITS - 1) == rep and node_bi[0, NB_REP] >> REP_BITS == 1
        else:
            with pytest.raises(LightcutsError, match="2\\^28 lights"):
                pack_nodes(node_f, node_k)
