"""Light-tree importance sampling (lightcuts.integrators.importance, light_sampler): the walk's
probabilities, their recomputation for MIS, unbiasedness over every builder's tree, and the
triangle light set whose leaves are boxes."""

import numpy as np
import pytest

from lightcuts.errors import LightcutsError
from lightcuts.integrators.light_sampler import build_light_sampler
from lightcuts.lights.lightset import LightSet
from lightcuts.lights.triangles import triangle_lights
from lightcuts.scene.scene import Scene
from lightcuts.trees import build_tree

BUILDERS = ("agglomerative", "agglomerative-heap", "divisive-3d", "divisive-6d", "greedy", "saoh")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _lights(seed, n_oriented=300, n_omni=40, n_dir=20):
    rng = np.random.default_rng(seed)
    sets = {
        "oriented": LightSet(rng.uniform(-1, 1, (n_oriented, 3)), _unit(rng.normal(size=(n_oriented, 3))),
                             rng.uniform(0.0, 2.0, (n_oriented, 3)) * (rng.random((n_oriented, 1)) < 0.9),
                             "oriented"),
        "omni": LightSet(rng.uniform(-2, 2, (n_omni, 3)), np.zeros((n_omni, 3)), rng.uniform(0.1, 1, (n_omni, 3)),
                         "omni"),
        "directional": LightSet(_unit(rng.normal(size=(n_dir, 3))), np.zeros((n_dir, 3)),
                                rng.uniform(0.1, 1, (n_dir, 3)), "directional"),
    }
    return sets


def _contribution(sets, p, n):
    """(L,) luminance of every light's unshadowed contribution at p (normal n, two-sided), global order."""
    out = []
    for typ in ("omni", "oriented", "directional"):
        ls = sets[typ]
        lum = ls.luminance
        if typ == "directional":
            out.append(lum * np.abs(ls.position @ n))
            continue
        d = p - ls.position
        r2 = (d * d).sum(axis=1)
        w = d / np.sqrt(r2)[:, None]
        g = np.abs(w @ n) / r2
        if typ == "oriented":
            g = g * np.maximum(0.0, (ls.normal * w).sum(axis=1))
        out.append(lum * g)
    return np.concatenate(out)


def _sampler(sets, builder):
    return build_light_sampler(sets, {t: build_tree(ls, builder) for t, ls in sets.items()})


@pytest.mark.parametrize("builder", BUILDERS)
def test_every_contributing_light_has_a_positive_probability(builder):
    """Unbiasedness, exactly: importance 0 only where no light below can contribute, so every light
    that lights p is drawn with p > 0 (and the estimator's mean is the all-lights sum)."""
    sets = _lights(1)
    s = _sampler(sets, builder)
    rng = np.random.default_rng(2)
    for _ in range(40):
        p = rng.uniform(-2.5, 2.5, 3)
        n = _unit(rng.normal(size=3))
        f = _contribution(sets, p, n)
        pmf = s.pmf(p, n)
        assert np.all(pmf[f > 0] > 0), f"{np.count_nonzero(pmf[f > 0] == 0)} lights lighting p are never drawn"
        assert pmf.sum() <= 1.0 + 1e-12
        # the estimator's exact mean over the draws equals the sum over all lights
        drawn = pmf > 0
        assert np.isclose((pmf[drawn] * (f[drawn] / pmf[drawn])).sum(), f.sum(), rtol=1e-12)


@pytest.mark.parametrize("builder", BUILDERS)
def test_probabilities_sum_to_one_where_every_node_is_important(builder):
    """Omni lights seen from a point with no receiver factor: every node has importance > 0, so the
    walk never fails and the leaves' probabilities sum to 1."""
    rng = np.random.default_rng(3)
    sets = {"omni": LightSet(rng.uniform(-1, 1, (257, 3)), np.zeros((257, 3)), rng.uniform(0.1, 1, (257, 3)), "omni")}
    s = _sampler(sets, builder)
    for p in ([3.0, 0.0, 0.0], [0.1, 0.2, -0.3]):
        pmf = s.pmf(np.array(p), np.zeros(3))
        assert np.all(pmf > 0)
        assert pmf.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("builder", BUILDERS)
def test_drawn_probability_is_the_recomputed_product(builder):
    """The probability the walk reports equals light_pmf's product from the leaf up (MIS needs it),
    and the draws' frequencies follow it."""
    sets = _lights(4)
    s = _sampler(sets, builder)
    p, n = np.array([0.2, 1.6, -0.4]), _unit(np.array([0.1, -1.0, 0.2]))
    u = (np.arange(200_000) + 0.5) / 200_000
    lights, probs = s.draw(p, n, u)
    pmf = s.pmf(p, n)
    ok = lights >= 0
    np.testing.assert_allclose(probs[ok], pmf[lights[ok]], rtol=1e-12)
    freq = np.bincount(lights[ok], minlength=len(pmf)) / len(u)
    np.testing.assert_allclose(freq, pmf, atol=5e-4)
    assert (~ok).mean() == pytest.approx(1.0 - pmf.sum(), abs=5e-4)


@pytest.mark.parametrize("builder", BUILDERS)
def test_estimator_mean_within_three_standard_errors(builder):
    """f(light) / p(light) over independent draws averages to the all-lights sum."""
    sets = _lights(5)
    s = _sampler(sets, builder)
    rng = np.random.default_rng(6)
    for _ in range(3):
        p = rng.uniform(-1.5, 1.5, 3)
        n = _unit(rng.normal(size=3))
        f = _contribution(sets, p, n)
        lights, probs = s.draw(p, n, rng.random(20_000))
        est = np.where(lights >= 0, f[np.maximum(lights, 0)] / np.where(probs > 0, probs, 1.0), 0.0)
        se = est.std(ddof=1) / np.sqrt(len(est))
        assert abs(est.mean() - f.sum()) <= 3 * se + 1e-12 * f.sum()


def test_importance_prefers_near_and_facing_lights():
    """Two equal clusters, one near and facing p, one far or facing away: the near one is drawn far
    more often (the importance is not the power alone)."""
    pos = np.array([[0.0, 0.0, 1.0], [0.0, 0.1, 1.0], [0.0, 0.0, 50.0], [0.0, 0.1, 50.0]])
    nrm = np.tile([0.0, 0.0, -1.0], (4, 1))
    sets = {"oriented": LightSet(pos, nrm, np.ones((4, 3)), "oriented")}
    s = _sampler(sets, "greedy")
    pmf = s.pmf(np.zeros(3), np.array([0.0, 0.0, 1.0]))
    assert pmf[:2].sum() > 100 * pmf[2:].sum()
    facing_away = {"oriented": LightSet(pos, -nrm, np.ones((4, 3)), "oriented")}
    assert _sampler(facing_away, "greedy").pmf(np.zeros(3), np.array([0.0, 0.0, 1.0])).sum() == 0.0


def test_bytes_per_light():
    sets = _lights(7, 4000, 0, 0)
    s = _sampler({"oriented": sets["oriented"]}, "agglomerative")
    assert s.nbytes / 4000 <= 100


def _emitter_scene(seed):
    """Small emitting triangles scattered over a floor's ceiling, facing down, plus a floor."""
    rng = np.random.default_rng(seed)
    k = 200
    c = np.column_stack([rng.uniform(-5, 5, k), np.full(k, 3.0), rng.uniform(-5, 5, k)])
    a = c + [0.2, 0.0, 0.0]
    b = c + [0.0, 0.0, 0.2]
    tris = np.stack([c, a, b], axis=1)  # normal (a - c) x (b - c) = x cross z = -y: facing down
    floor = np.array([[[-6, 0, -6], [-6, 0, 6], [6, 0, 6]], [[-6, 0, -6], [6, 0, 6], [6, 0, -6]]], float)
    allt = np.concatenate([tris, floor])
    emission = np.zeros((len(allt), 3))
    emission[:k] = rng.uniform(0.5, 5.0, (k, 3))
    return Scene(allt.reshape(-1, 3), np.arange(3 * len(allt)).reshape(-1, 3), albedo=0.5, specular=0.0, exponent=0.0,
                 emission=emission)


def test_triangle_lights_carry_power_and_boxes():
    scene = _emitter_scene(8)
    t = triangle_lights(scene)
    assert len(t.lights) == 200 and np.all(scene.emission[t.tri].max(axis=1) > 0)
    np.testing.assert_allclose(np.pi * t.lights.intensity.sum(axis=0),
                               np.pi * (scene.emission[t.tri] * scene.face_areas[t.tri, None]).sum(axis=0))
    assert np.all(t.lights.normal[:, 1] < -0.99)
    corners = scene.triangles[t.tri]
    assert np.all(t.lo <= corners.min(axis=1)) and np.all(t.hi >= corners.max(axis=1))


@pytest.mark.parametrize("builder", ("agglomerative", "saoh"))
def test_refitted_boxes_hold_every_triangle_below(builder):
    """A node's box holds the whole triangle of every light below it (not just its centroid)."""
    scene = _emitter_scene(9)
    t = triangle_lights(scene)
    s = build_light_sampler({"oriented": t.lights}, {"oriented": build_tree(t.lights, builder)},
                            {"oriented": (t.lo, t.hi)})
    corners = scene.triangles[t.tri]
    for j in range(len(t.lights)):
        k = int(s.leaf[j])
        while k >= 0:
            assert np.all(s.rec[k, 0:3] <= corners[j].min(axis=0)) and np.all(s.rec[k, 3:6] >= corners[j].max(axis=0))
            k = int(s.parent[k])


def test_bad_inputs_are_one_line():
    sets = _lights(11, 20, 0, 0)
    tree = build_tree(sets["oriented"], "greedy")
    with pytest.raises(LightcutsError, match="no tree"):
        build_light_sampler({"oriented": sets["oriented"]}, {})
    with pytest.raises(LightcutsError, match="per-light boxes"):
        build_light_sampler({"oriented": sets["oriented"]}, {"oriented": tree},
                            {"oriented": (np.zeros((3, 3)), np.zeros((3, 3)))})
