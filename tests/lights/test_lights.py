"""Light generation: direct area-light samples, particle-traced VPLs, sun and environment lights, config glue.

Scenes are built here (a closed box with an emitter flush in its ceiling, a few loose triangles), so
the tests need no files. Properties are stated so that a wrong estimator fails them: exact power
bookkeeping where it is deterministic, expectations over seeds or many samples where it is not.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lightcuts.accel import RAY_CASTERS, make_caster
from lightcuts.config.schema import config_from_dict
from lightcuts.errors import LightcutsError
from lightcuts.lights import LightSet
from lightcuts.lights.direct import allocate_proportional, direct_lights, square_to_triangle
from lightcuts.lights.environment import (EnvironmentMap, environment_lights, procedural_sky, rotation_y,
                                          sun_light)
from lightcuts.lights.generate import lights_from_config, load_environment, sub_seed
from lightcuts.lights.indirect import indirect_lights
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.scene import Scene

CASTER = "embree" if "embree" in RAY_CASTERS else "embreex"
RHO = np.array([0.6, 0.5, 0.3])
LE = np.array([10.0, 8.0, 6.0])


# ---------------------------------------------------------------------------------------------
# Scenes


def _quad(p, a, b):
    p, a, b = (np.asarray(x, float) for x in (p, a, b))
    return np.array([p, p + a, p + a + b, p + b]), np.array([[0, 1, 2], [0, 2, 3]])


def _scene(quads, albedo, emission, name="test"):
    """quads: list of ((V, F), kind); kind 'e' = emitter (faces -y), 'in'/'out' = winding of the normal."""
    verts, faces, em = [], [], []
    base = 0
    for (v, f), kind in quads:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
        em += [kind == "e"] * len(f)
    s = Scene(np.concatenate(verts), np.concatenate(faces), albedo, 0.0, 0.0,
              np.where(np.array(em)[:, None], emission, 0.0), name=name)
    return s


def _orient(scene, want):
    """Flip faces so that face i's normal has a positive dot product with want[i] (0 rows: untouched)."""
    n = scene.face_normals
    flip = np.einsum("ij,ij->i", n, want) < 0
    faces = scene.faces.copy()
    faces[flip] = faces[flip][:, ::-1]
    return Scene(scene.vertices, faces, scene.albedo, scene.specular, scene.exponent, scene.emission,
                 name=scene.name)


def closed_box(rho=RHO, le=LE):
    """The unit cube, every face albedo ``rho`` (the emitter too), closed. The emitter is the square
    [0.4, 0.6]^2 of the ceiling (y = 1), flush with it and facing down, so no particle can reach its
    back. Walls are wound alternately inwards and outwards, so both branches of the VPL normal's
    turn towards the incoming side are exercised."""
    quads = [
        (_quad([0, 0, 0], [1, 0, 0], [0, 0, 1]), "in"),
        (_quad([0, 1, 0], [1, 0, 0], [0, 0, 0.4]), "out"),
        (_quad([0, 1, 0.6], [1, 0, 0], [0, 0, 0.4]), "in"),
        (_quad([0, 1, 0.4], [0.4, 0, 0], [0, 0, 0.2]), "out"),
        (_quad([0.6, 1, 0.4], [0.4, 0, 0], [0, 0, 0.2]), "in"),
        (_quad([0.4, 1, 0.4], [0.2, 0, 0], [0, 0, 0.2]), "e"),
        (_quad([0, 0, 0], [0, 1, 0], [0, 0, 1]), "out"),
        (_quad([1, 0, 0], [0, 1, 0], [0, 0, 1]), "in"),
        (_quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), "in"),
        (_quad([0, 0, 1], [1, 0, 0], [0, 1, 0]), "out"),
    ]
    s = _scene(quads, np.asarray(rho), np.asarray(le), "closed-box")
    centre = s.triangles.mean(axis=1)
    inward = np.array([0.5, 0.5, 0.5]) - centre
    kinds = np.repeat([k for _, k in quads], 2)
    want = np.where((kinds == "in")[:, None] | (kinds == "e")[:, None], inward, -inward)
    return _orient(s, want)


def coloured_emitters():
    """Three emitter triangles of different colours, sizes and orientations, and one dark triangle."""
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 0, 1],
                  [0, 1, 0], [0, 1, 3], [0.5, 2, 0],
                  [1, 1, 1], [1.2, 1.1, 1], [1, 1.3, 1.4],
                  [5, 5, 5], [6, 5, 5], [5, 6, 5]], float)
    f = np.arange(12).reshape(4, 3)
    em = np.array([[5.0, 0.0, 0.0], [0.0, 2.0, 0.5], [1.0, 1.0, 9.0], [0.0, 0.0, 0.0]])
    return Scene(v, f, 0.5, 0.0, 0.0, em, name="coloured")


def power_of_emitters(scene):
    return np.pi * (scene.emission * scene.face_areas[:, None]).sum(axis=0)


@pytest.fixture(scope="module")
def box():
    return closed_box()


@pytest.fixture(scope="module")
def box_caster(box):
    return make_caster(box, CASTER)


# ---------------------------------------------------------------------------------------------
# Direct lights


def _barycentric(p, tri):
    """(n, 3) barycentric coordinates of points p (n, 3) in triangles tri (n, 3, 3), and distance to the plane."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    area2 = np.einsum("ij,ij->i", n, n)
    w_a = np.einsum("ij,ij->i", np.cross(c - b, p - b), n) / area2
    w_b = np.einsum("ij,ij->i", np.cross(a - c, p - c), n) / area2
    dist = np.einsum("ij,ij->i", p - a, n) / np.sqrt(area2)
    return np.stack([w_a, w_b, 1 - w_a - w_b], axis=1), dist


def _owner(scene, lights):
    """Index of the emitter triangle each light lies on (the one whose plane and extent contain it)."""
    tri = scene.triangles[scene.emitters]
    owner = np.full(len(lights), -1)
    for k, t in enumerate(tri):
        bary, dist = _barycentric(lights.position, np.broadcast_to(t, (len(lights), 3, 3)))
        inside = (np.abs(dist) < 1e-12) & np.all(bary >= -1e-12, axis=1)
        owner[inside & (owner < 0)] = scene.emitters[k]
    return owner


@pytest.mark.parametrize("count", [3, 4, 17, 1000])
def test_direct_lights_preserve_power_per_channel_and_sit_on_their_emitters(count):
    scene = coloured_emitters()
    lights = direct_lights(scene, count, seed=7)
    assert len(lights) == count and lights.type == "oriented" and not lights.indirect.any()
    np.testing.assert_allclose(lights.power, power_of_emitters(scene), rtol=1e-9)
    owner = _owner(scene, lights)
    assert np.all(owner >= 0), "every light lies on an emitter triangle"
    np.testing.assert_allclose(lights.normal, scene.face_normals[owner], atol=1e-15)
    # a light's colour is its triangle's: intensity parallel to Le
    le = scene.emission[owner]
    np.testing.assert_allclose(np.cross(lights.intensity, le), 0.0, atol=1e-9 * np.abs(le).max())
    # per triangle, the power is that triangle's (exact, not only in total)
    for t in scene.emitters:
        np.testing.assert_allclose(np.pi * lights.intensity[owner == t].sum(axis=0),
                                   np.pi * scene.emission[t] * scene.face_areas[t], rtol=1e-9)


def test_direct_lights_are_unbiased_for_a_nonlinear_function_of_position():
    """E[sum_k I_k g(y_k)] = sum_t Le_t * integral_t g dA for g = x^2 (exact integral over a triangle);
    the classic sqrt map without stratification or a wrong barycentric map would still pass a
    power test but fail this one."""
    scene = coloured_emitters()
    tri = scene.triangles[scene.emitters]
    x = tri[:, :, 0]
    exact_int = scene.face_areas[scene.emitters] / 6 * (
        (x ** 2).sum(axis=1) + x[:, 0] * x[:, 1] + x[:, 0] * x[:, 2] + x[:, 1] * x[:, 2])
    exact = (scene.emission[scene.emitters] * exact_int[:, None]).sum(axis=0)
    sets = [direct_lights(scene, 50, seed) for seed in range(400)]
    est = np.mean([(ls.intensity * ls.position[:, :1] ** 2).sum(axis=0) for ls in sets], axis=0)
    # standard error measured at about 0.4%: 2% is a 5-sigma band
    np.testing.assert_allclose(est, exact, rtol=0.02)


def test_direct_lights_with_fewer_lights_than_emitters_are_unbiased_and_luminance_exact():
    scene = coloured_emitters()  # 3 emitters; rescaled to comparable power so the test's variance is small
    lum_power = scene.face_areas * (scene.emission @ LUMINANCE)
    scale = np.where(lum_power > 0, np.array([1.0, 1.5, 2.0, 0.0]) / np.maximum(lum_power, 1e-300), 0.0)
    scene = Scene(scene.vertices, scene.faces, 0.5, 0.0, 0.0, scene.emission * scale[:, None])
    seeds = range(10000)
    sets = [direct_lights(scene, 2, s) for s in seeds]
    total = power_of_emitters(scene)
    for ls in sets:  # every light carries the same luminance: total luminance power exact
        assert len(ls) == 2
        np.testing.assert_allclose(ls.power @ LUMINANCE, total @ LUMINANCE, rtol=1e-12)
    # standard error measured at about 0.9% (red), 0.5%, 0.3%: 4% is a 4-sigma band
    np.testing.assert_allclose(np.mean([ls.power for ls in sets], axis=0), total, rtol=0.04)


def test_direct_lights_are_reproducible_by_seed():
    scene = coloured_emitters()
    a, b, c = direct_lights(scene, 50, 1), direct_lights(scene, 50, 1), direct_lights(scene, 50, 2)
    assert np.array_equal(a.position, b.position) and np.array_equal(a.intensity, b.intensity)
    assert not np.array_equal(a.position, c.position)


def test_direct_lights_of_a_dark_scene_are_empty():
    scene = coloured_emitters()
    dark = Scene(scene.vertices, scene.faces, 0.5, 0.0, 0.0, 0.0)
    assert len(direct_lights(dark, 10, 0)) == 0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(1e-6, 1e3), min_size=1, max_size=30), st.integers(0, 200))
def test_proportional_allocation(weights, extra):
    w = np.array(weights)
    n = len(w) + extra
    counts = allocate_proportional(w, n)
    assert counts.sum() == n and counts.min() >= 1
    # monotone: a heavier stratum never gets fewer samples
    heavier = w[:, None] > w[None, :]
    assert np.all(counts[:, None] >= counts[None, :] - ~heavier * n)
    quota = n * w / w.sum()
    if quota.min() >= 1:  # the floor of one does not bind: plain largest remainders
        assert np.all(np.abs(counts - quota) < 1)


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 64))
def test_square_to_triangle_is_area_preserving(n):
    """A regular n x n grid of cell centres lands in the triangle with its density uniform: each of
    the triangle's four midpoint sub-triangles receives a quarter of the points, up to the cells the
    sub-triangle edges cut."""
    g = (np.arange(n) + 0.5) / n
    u, v = (a.ravel() for a in np.meshgrid(g, g))
    b0, b1 = square_to_triangle(u, v)
    assert np.all(b0 >= 0) and np.all(b1 >= 0) and np.all(b0 + b1 <= 1)
    b2 = 1 - b0 - b1
    corner = [np.count_nonzero(b > 0.5) for b in (b0, b1, b2)]
    for c in corner:
        assert abs(c - n * n / 4) <= 2 * n + 1


# ---------------------------------------------------------------------------------------------
# Indirect VPLs


def _expected_box_power(scene, rho, max_bounces):
    """Closed box, every surface albedo rho: each path hits a surface at every bounce (nothing
    escapes, the emitter's back is unreachable, its front reflects like the rest), so the power
    reaching the k-th hit is P rho^(k-1) and the VPLs of hit k carry P rho^k; in total
    P * sum_{k=1..K} rho^k, K = max_bounces. Russian roulette leaves the expectation unchanged."""
    return power_of_emitters(scene) * sum(np.asarray(rho) ** k for k in range(1, max_bounces + 1))


def test_vpl_power_in_a_closed_box_without_roulette_is_exact(box, box_caster):
    """With roulette off (rr_start past max_bounces) and one emitter colour, every path carries the
    same power, so the total is exact, not only in expectation."""
    lights = indirect_lights(box, box_caster, 3000, seed=3, max_bounces=3, rr_start=10)
    assert lights.meta["indirect_paths"] * 3 == len(lights)
    np.testing.assert_allclose(lights.power, _expected_box_power(box, RHO, 3), rtol=1e-9)


@pytest.mark.parametrize("rr_start,max_bounces", [(1, 16), (3, 8)])
def test_vpl_power_in_a_closed_box_matches_the_geometric_series(box, box_caster, rr_start, max_bounces):
    lights = indirect_lights(box, box_caster, 20000, seed=11, max_bounces=max_bounces, rr_start=rr_start)
    assert lights.indirect.all() and lights.type == "oriented"
    assert abs(len(lights) - 20000) < 0.1 * 20000
    # per-channel relative spread measured at about 1% for 20000 VPLs: 4% is a 4-sigma band
    np.testing.assert_allclose(lights.power, _expected_box_power(box, RHO, max_bounces), rtol=0.04)


def test_vpls_lie_on_the_box_and_face_its_inside(box, box_caster):
    lights = indirect_lights(box, box_caster, 5000, seed=5)
    p, n = lights.position, lights.normal
    assert np.all((p >= -1e-9) & (p <= 1 + 1e-9))
    on_face = np.min(np.minimum(np.abs(p), np.abs(1 - p)), axis=1)
    assert on_face.max() < 1e-9, "each VPL lies on a face plane"
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", n, 0.5 - p) > 0), "normals face the side the particle came from"
    # ... whichever way the faces are wound: the box has geometric normals pointing both ways
    facing_in = np.einsum("ij,ij->i", box.face_normals, 0.5 - box.triangles.mean(axis=1)) > 0
    assert facing_in.any() and not facing_in.all()
    assert np.all(lights.intensity >= 0) and np.all(lights.intensity.max(axis=1) > 0)


def test_vpls_are_deterministic_and_independent_of_thread_count(box, box_caster):
    a = indirect_lights(box, box_caster, 4000, seed=9)
    b = indirect_lights(box, box_caster, 4000, seed=9)
    for k in ("position", "normal", "intensity"):
        assert np.array_equal(getattr(a, k), getattr(b, k))
    c = indirect_lights(box, box_caster, 4000, seed=10)
    assert not np.array_equal(a.position[:100], c.position[:100])
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = indirect_lights(box, box_caster, 4000, seed=9)
    finally:
        numba.set_num_threads(threads)
    for k in ("position", "normal", "intensity"):
        assert np.array_equal(getattr(a, k), getattr(single, k))


@pytest.mark.skipif(not {"embree", "embreex"} <= set(RAY_CASTERS.names()), reason="needs both Embree casters")
def test_fused_and_wavefront_routes_give_the_same_vpls(box):
    """The embree caster (per-ray calls in one kernel) and embreex (batch wavefront) trace the same
    paths: Embree returns the same hits to both, so the VPLs agree bit for bit, order included."""
    fused = indirect_lights(box, make_caster(box, "embree"), 3000, seed=21, max_bounces=5)
    wave = indirect_lights(box, make_caster(box, "embreex"), 3000, seed=21, max_bounces=5)
    for k in ("position", "normal", "intensity"):
        assert np.array_equal(getattr(fused, k), getattr(wave, k))


def test_the_back_of_an_emitter_absorbs():
    """An emitter facing down between a floor and a ceiling (all albedo 1). Particles that go round it
    to the ceiling come back down onto its back and end there: no VPL is ever stored on the emitter
    with an upward normal, while its front (albedo 1) does collect VPLs."""
    quads = [(_quad([-5, 0, -5], [10, 0, 0], [0, 0, 10]), "in"),
             (_quad([-5, 2, -5], [10, 0, 0], [0, 0, 10]), "in"),
             (_quad([-0.5, 1, -0.5], [1, 0, 0], [0, 0, 1]), "e")]
    s = _scene(quads, 1.0, np.array([1.0, 1.0, 1.0]))
    s = _orient(s, np.array([[0, 1, 0]] * 2 + [[0, -1, 0]] * 2 + [[0, -1, 0]] * 2, float))
    lights = indirect_lights(s, make_caster(s, CASTER), 20000, seed=1, max_bounces=8)
    on_emitter = (np.abs(lights.position[:, 1] - 1) < 1e-9) & (np.abs(lights.position[:, 0]) <= 0.5) \
        & (np.abs(lights.position[:, 2]) <= 0.5)
    assert np.any(on_emitter & (lights.normal[:, 1] < 0)), "the front reflects"
    assert not np.any(on_emitter & (lights.normal[:, 1] > 0)), "the back absorbs"


def test_particles_that_escape_leave_no_vpls():
    quads = [(_quad([0, 0, 0], [1, 0, 0], [0, 0, 1]), "e"), (_quad([0, -1, 0], [1, 0, 0], [0, 0, 1]), "in")]
    s = _scene(quads, 0.8, np.array([1.0, 1.0, 1.0]))
    s = _orient(s, np.array([[0, 1, 0]] * 2 + [[0, 1, 0]] * 2, float))  # the emitter faces away from the floor
    assert len(indirect_lights(s, make_caster(s, CASTER), 500, seed=1)) == 0


# ---------------------------------------------------------------------------------------------
# Sun and environment


def test_sun_light():
    ls = sun_light([0, 2, 0], [3.0, 2.0, 1.0])
    assert ls.type == "directional" and len(ls) == 1
    np.testing.assert_array_equal(ls.position, [[0, 1, 0]])
    np.testing.assert_array_equal(ls.intensity, [[3, 2, 1]])
    with pytest.raises(LightcutsError, match="lights.sun.direction"):
        sun_light([0, 0, 0], [1, 1, 1])


def _irradiance(lights, normals):
    return np.maximum(0.0, normals @ lights.position.T) @ lights.intensity


@pytest.mark.parametrize("rotate", [0.0, 37.0])
def test_environment_lights_of_a_constant_map_give_pi_L_on_any_surface(rotate):
    L = np.array([0.5, 1.0, 2.0])
    env = EnvironmentMap(np.broadcast_to(L, (32, 64, 3)), rotate=rotate)
    lights = environment_lights(env, 4096, seed=3, scale=2.0)
    assert lights.type == "directional" and len(lights) == 4096
    np.testing.assert_allclose(np.linalg.norm(lights.position, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(lights.intensity.sum(axis=0), 4 * np.pi * 2 * L, rtol=1e-9)
    normals = np.random.default_rng(0).normal(size=(200, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(_irradiance(lights, normals), np.broadcast_to(np.pi * 2 * L, (200, 3)), rtol=0.02)


def _test_map(h=16, w=32):
    rng = np.random.default_rng(4)
    px = rng.random((h, w, 3)).astype(np.float32) ** 4
    px[3, 5] = [40.0, 30.0, 20.0]
    px[9, :] = 0.0  # a black row: never sampled
    return px


def test_environment_lights_agree_with_the_lookup_and_are_unbiased():
    env = EnvironmentMap(_test_map(), rotate=-75.0, scale=1.5)
    lights = environment_lights(env, 3000, seed=2)
    # each light's intensity is L(w) S / (count lum(L(w))) with L from the renderer's lookup: the
    # sampling and the lookup agree on which pixel a direction belongs to, rotation included
    seen = env.radiance(lights.position)
    solid = (2 * np.pi / 32) * (np.cos(np.pi * np.arange(16) / 16) - np.cos(np.pi * np.arange(1, 17) / 16))
    s_lum = ((env.pixels.astype(float) @ LUMINANCE) * solid[:, None]).sum() * env.scale
    np.testing.assert_allclose(lights.intensity, seen * (s_lum / (3000 * (seen @ LUMINANCE)))[:, None], rtol=1e-6)
    # sum of I estimates integral of L over the sphere (g = 1), unbiased: average over seeds
    exact = (env.pixels.astype(float) * solid[:, None, None]).sum(axis=(0, 1)) * env.scale
    mean = np.mean([environment_lights(env, 64, seed).intensity.sum(axis=0) for seed in range(300)], axis=0)
    np.testing.assert_allclose(mean, exact, rtol=0.02)


def test_environment_convention():
    """u = atan2(x, -z) / 2pi, v = acos(y) / pi; rotate turns the map about +y (right-handed)."""
    h, w = 8, 16
    px = np.zeros((h, w, 3), np.float32)
    px[h // 2, w // 4] = [1, 2, 3]  # u ~ 0.25-0.31, v ~ 0.5-0.62: just below the horizon, towards +x
    px[0, :] = [7, 7, 7]  # the zenith row
    d = np.array([[np.cos(0.1), -np.sin(0.1), 0.0]])
    d2 = d @ rotation_y(90).T
    e0 = EnvironmentMap(px)
    np.testing.assert_array_equal(e0.radiance(d), [[1, 2, 3]])
    np.testing.assert_array_equal(e0.radiance([[0, 1, 0]]), [[7, 7, 7]])
    e90 = EnvironmentMap(px, rotate=90.0, scale=2.0)
    np.testing.assert_allclose(rotation_y(90) @ [1, 0, 0], [0, 0, -1], atol=1e-15)  # +x turns to -z
    np.testing.assert_array_equal(e90.radiance(d2), [[2, 4, 6]])
    np.testing.assert_allclose(e0.directions([0.25], [0.5]), [[1, 0, 0]], atol=1e-15)
    np.testing.assert_allclose(e0.directions([0.5], [0.5]), [[0, 0, 1]], atol=1e-15)


def test_environment_exr_round_trip(tmp_path):
    px = _test_map(12, 24)
    path = EnvironmentMap(px).save(tmp_path / "env.exr")
    back = EnvironmentMap.load(path, rotate=10.0, scale=3.0)
    assert back.pixels.dtype == np.float32 and np.array_equal(back.pixels, px)
    assert back.rotate == 10.0 and back.scale == 3.0
    assert [p.name for p in tmp_path.iterdir()] == ["env.exr"], "no temporary file left behind"


def test_environment_load_errors(tmp_path):
    import OpenEXR

    with pytest.raises(LightcutsError, match="missing.exr"):
        EnvironmentMap.load(tmp_path / "missing.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an exr")
    with pytest.raises(LightcutsError, match="junk.exr"):
        EnvironmentMap.load(tmp_path / "junk.exr")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Y": np.ones((4, 8), np.float32)}) as f:
        f.write(str(tmp_path / "grey.exr"))
    with pytest.raises(LightcutsError, match="grey.exr.*not an RGB"):
        EnvironmentMap.load(tmp_path / "grey.exr")
    bad = np.ones((4, 8, 3), np.float32)
    bad[1, 1, 1] = np.nan
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": bad}) as f:
        f.write(str(tmp_path / "nan.exr"))
    with pytest.raises(LightcutsError, match="nan.exr.*non-finite"):
        EnvironmentMap.load(tmp_path / "nan.exr")


def test_procedural_sky():
    sun = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    env = procedural_sky(sun_direction=sun * 3, resolution=(128, 64), sun_irradiance=15.0,
                         sun_colour=(1.0, 1.0, 1.0))
    assert env.shape == (64, 128) and np.all(np.isfinite(env.pixels)) and env.pixels.min() >= 0
    dirs = np.random.default_rng(1).normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lum = env.radiance(dirs) @ LUMINANCE
    assert env.radiance(sun[None]) @ LUMINANCE > 100 * lum.max(), "the sun disc outshines the sky"
    up, down = dirs[:, 1] > 0.05, dirs[:, 1] < -0.05
    assert lum[up].min() > lum[down].max(), "the sky is brighter than the ground"
    zenith, horizon = env.radiance([[0, 1, 0], [-0.3, 0.01, -0.95]])
    assert zenith[2] / zenith[0] > horizon[2] / horizon[0], "bluer overhead"
    # the disc gives the asked irradiance: light it with the map's own directional lights
    lights = environment_lights(env, 8192, 0)
    towards_sun = np.einsum("ij,j->i", lights.position, sun) > np.cos(np.radians(3.0))
    np.testing.assert_allclose(lights.intensity[towards_sun].sum(axis=0), 15.0, rtol=0.05)
    with pytest.raises(LightcutsError, match="procedural.sun_direction"):
        procedural_sky(sun_direction=(0, 0, 0))


# ---------------------------------------------------------------------------------------------
# Config glue


def _cfg(lights, seed=4):
    return config_from_dict({"name": "t", "seed": seed, "scene": {"builtin": "cornell"}, "lights": lights})


def test_lights_from_config_combines_sources_by_type(box, box_caster):
    cfg = _cfg({"direct": {"count": 64}, "indirect": {"count": 2000},
                "sun": {"direction": [0, 1, 1], "irradiance": [1, 1, 1]},
                "environment": {"procedural": {"resolution": [32, 16]}, "count": 100}})
    sets = lights_from_config(cfg, box, box_caster, load_environment(cfg))
    assert set(sets) == {"oriented", "directional"}
    ori, dirl = sets["oriented"], sets["directional"]
    assert ori.meta["count_direct"] == 64 and ori.meta["count_indirect"] == len(ori) - 64
    assert not ori.indirect[:64].any() and ori.indirect[64:].all()
    np.testing.assert_allclose(ori.intensity[:64].sum(axis=0) * np.pi, power_of_emitters(box), rtol=1e-9)
    assert len(dirl) == 101 and dirl.meta["count_sun"] == 1 and dirl.meta["count_environment"] == 100
    np.testing.assert_allclose(dirl.position[0], np.array([0, 1, 1]) / np.sqrt(2))
    for ls in sets.values():
        assert ls.meta["scene"] == "closed-box" and ls.meta["seed"] == 4
        np.testing.assert_array_equal(ls.meta["bbox_min"], [0, 0, 0])
        np.testing.assert_array_equal(ls.meta["bbox_max"], [1, 1, 1])
        assert ls.meta["diagonal"] == pytest.approx(np.sqrt(3))
    # sub-seeds: dropping the other sources leaves the direct lights as they were
    only_direct = lights_from_config(_cfg({"direct": {"count": 64}}), box, box_caster)
    assert set(only_direct) == {"oriented"}
    assert np.array_equal(only_direct["oriented"].position, ori.position[:64])
    assert sub_seed(4, "direct") != sub_seed(4, "indirect") != sub_seed(4, "environment")


def test_lights_from_config_saves_and_loads(box, box_caster, tmp_path):
    sets = lights_from_config(_cfg({"direct": {"count": 8}}), box, box_caster)
    back = LightSet.load(sets["oriented"].save(tmp_path / "l.npz"))
    assert np.array_equal(back.position, sets["oriented"].position) and back.meta["count_direct"] == 8


def test_lights_from_config_errors(box, box_caster):
    dark = Scene(box.vertices, box.faces, 0.5, 0.0, 0.0, 0.0, name="dark")
    # the default direct count samples the emitters there are: none here, so no lights at all
    with pytest.raises(LightcutsError, match="lights: the config yields no lights"):
        lights_from_config(_cfg({}), dark, box_caster)
    with pytest.raises(LightcutsError, match="lights.direct: the scene has no emissive triangles"):
        lights_from_config(_cfg({"direct": {"count": 1024}}), dark, box_caster)
    with pytest.raises(LightcutsError, match="lights.indirect: the scene has no emissive triangles"):
        lights_from_config(_cfg({"direct": {"count": 0}, "indirect": {"count": 10}}), dark, box_caster)
    with pytest.raises(LightcutsError, match="lights.sun.direction"):
        lights_from_config(_cfg({"direct": {"count": 0}, "sun": {"direction": [0, 0, 0], "irradiance": [1, 1, 1]}}),
                           dark, box_caster)
    with pytest.raises(LightcutsError, match="no lights"):
        lights_from_config(_cfg({"direct": {"count": 0}}), box, box_caster)


def test_load_environment(tmp_path):
    assert load_environment(_cfg({})) is None
    EnvironmentMap(_test_map()).save(tmp_path / "sky.exr")
    cfg = config_from_dict({"scene": {"builtin": "cornell"},
                            "lights": {"environment": {"file": "sky.exr", "rotate": 30, "scale": 2}}},
                           base_dir=tmp_path)
    env = load_environment(cfg)
    assert env.rotate == 30 and env.scale == 2 and np.array_equal(env.pixels, _test_map())
    sky = load_environment(_cfg({"environment": {"procedural": {"resolution": [40, 20]}}}))
    assert sky.shape == (20, 40)
