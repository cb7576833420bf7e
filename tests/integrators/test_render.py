"""The renderer: lightcuts against the brute-force reference, exact cases, determinism, eye rays.

A small Cornell box (48 x 48 pixels, about 2,000 direct and indirect lights, a glossy floor so that
the Phong bound is exercised) is rendered once with every light (the reference) and with lightcuts.
"""

import ctypes

import numpy as np
import pytest

from lightcuts.accel import make_caster
from lightcuts.errors import LightcutsError
from lightcuts.lights.direct import direct_lights
from lightcuts.lights.environment import EnvironmentMap
from lightcuts.lights.indirect import indirect_lights
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.integrators import MAX_CUT
from lightcuts.integrators.camera import eye_rays, strata
from lightcuts.integrators.forest import (LF_INDIRECT, LF_POS, NF_HI, NF_I, NF_LO, NK_ALL_INDIRECT, NK_LEFT, NK_REP,
                                     NK_RIGHT, build_forest)
from lightcuts.integrators.lightcut import render_image, render_reference
from lightcuts.scene.cornell import cornell_box
from lightcuts.scene.scene import Camera, Scene
from lightcuts.trees.build import build_tree

SIZE = 48


@pytest.fixture(scope="module")
def cornell():
    scene = cornell_box({"floor": {"specular": [0.3, 0.3, 0.3], "exponent": 40.0}})
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, SIZE, SIZE)
    caster = make_caster(scene, "embree")
    lights = LightSet.concatenate([direct_lights(scene, 256, seed=1), indirect_lights(scene, caster, 1800, seed=2)])
    assert 1900 < len(lights) < 2200 and lights.indirect.any() and not lights.indirect.all()
    tree = build_tree(lights, "divisive-6d", seed=3)
    lights, trees = {"oriented": lights}, {"oriented": tree}
    reference = render_reference(scene, caster, lights, camera=camera)
    yield scene, caster, camera, lights, trees, reference
    caster.close()


def luminance(image):
    return image.astype(np.float64) @ LUMINANCE


def relative_errors(image, reference):
    """Per-pixel relative error of the luminance, over pixels above 1e-3 of the brightest."""
    a, b = luminance(image), luminance(reference)
    keep = b > 1e-3 * b.max()
    return np.abs(a - b)[keep] / b[keep]


@pytest.mark.parametrize("eps, median, p99", [(0.01, 0.01, 0.05), (0.02, 0.02, 0.08)])
def test_lightcuts_matches_the_reference(cornell, eps, median, p99):
    scene, caster, camera, lights, trees, reference = cornell
    result = render_image(scene, caster, lights, trees, camera=camera, eps=eps)
    err = relative_errors(result.image, reference.image)
    assert np.median(err) <= median and np.percentile(err, 99) <= p99, (np.median(err), np.percentile(err, 99))
    # The point of lightcuts: far fewer shadow rays than lights.
    n = len(lights["oriented"])
    assert result.shadow_rays < 0.2 * reference.shadow_rays
    assert 1 <= result.cut_size.max() <= 1000 and result.cut_size.mean() < 0.2 * n


def test_error_falls_with_eps(cornell):
    scene, caster, camera, lights, trees, reference = cornell
    errors, cuts = [], []
    for eps in (0.04, 0.01, 0.0025):
        result = render_image(scene, caster, lights, trees, camera=camera, eps=eps)
        errors.append(relative_errors(result.image, reference.image).mean())
        cuts.append(result.cut_size.mean())
    assert errors[0] > errors[1] > errors[2] and cuts[0] < cuts[1] < cuts[2], (errors, cuts)


def test_eps_zero_evaluates_every_light_and_equals_the_reference(cornell):
    scene, caster, camera, lights, trees, reference = cornell
    n = len(lights["oriented"])
    result = render_image(scene, caster, lights, trees, camera=camera, eps=0.0, max_cut=n)
    np.testing.assert_allclose(result.image, reference.image, rtol=1e-5, atol=1e-9)
    # Every light with M G > 0 is reached as a representative exactly once, and casts one ray.
    assert result.shadow_rays == reference.shadow_rays
    assert result.clamped_energy == pytest.approx(reference.clamped_energy, rel=1e-6)


def test_same_inputs_give_identical_bytes_on_any_thread_count(cornell, thread_counts):
    scene, caster, camera, lights, trees, _ = cornell
    (n1, n2), num_threads = thread_counts
    kwargs = dict(camera=camera, spp=2, seed=7)
    with num_threads(n1):
        one = render_image(scene, caster, lights, trees, **kwargs)
    with num_threads(n2):
        two = render_image(scene, caster, lights, trees, **kwargs)
    again = render_image(scene, caster, lights, trees, **kwargs)
    assert one.image.tobytes() == two.image.tobytes() == again.image.tobytes()
    assert one.cut_size.tobytes() == two.cut_size.tobytes()
    assert one.shadow_rays == two.shadow_rays
    # A crop renders exactly the full image's pixels.
    crop = render_image(scene, caster, lights, trees, crop=(5, 30, 21, 41), **kwargs)
    assert crop.image.shape == (11, 16, 3)
    assert crop.image.tobytes() == np.ascontiguousarray(one.image[30:41, 5:21]).tobytes()
    # A list of pixels renders exactly those pixels of the full image, in the list's order.
    pix = np.array([[47, 0], [3, 9], [20, 33], [3, 9], [0, 47]])
    some = render_image(scene, caster, lights, trees, pixels=pix, **kwargs)
    assert some.image.shape == (5, 1, 3) and some.crop is None
    assert some.image[:, 0].tobytes() == np.ascontiguousarray(one.image[pix[:, 1], pix[:, 0]]).tobytes()
    assert some.cut_size[:, 0].tobytes() == np.ascontiguousarray(one.cut_size[pix[:, 1], pix[:, 0]]).tobytes()
    # Another seed moves the eye rays.
    other = render_image(scene, caster, lights, trees, camera=camera, spp=2, seed=8)
    assert other.image.tobytes() != one.image.tobytes()


class _Packets4:
    """The embree caster with 4-wide shadow-ray packets (rtcOccluded4), as on a processor without
    native 8-wide ones."""

    def __init__(self, caster):
        occluded4 = ctypes.CFUNCTYPE(None, *[ctypes.c_uint64] * 4)(("rtcOccluded4", caster._lib.lib))
        kc = caster.kernel_caster
        self.kernel_caster = kc._replace(width=4, data=(*kc.data[:3], occluded4, kc.data[4]))


def test_packet_width_does_not_change_the_image(cornell):
    """The cut refines the same nodes whatever the packet width (docs/math.md, "Deferred
    visibility"); only the order of the running total's additions differs, which could flip a stop
    test in a last-bit tie, and flips none here."""
    scene, caster, camera, lights, trees, _ = cornell
    assert caster.kernel_caster.width in (4, 8)
    kwargs = dict(camera=camera, spp=2, seed=3)
    native = render_image(scene, caster, lights, trees, **kwargs)
    four = render_image(scene, _Packets4(caster), lights, trees, **kwargs)
    assert four.image.tobytes() == native.image.tobytes()
    assert four.cut_size.tobytes() == native.cut_size.tobytes() and four.shadow_rays == native.shadow_rays


def test_clamping_removes_exactly_the_reported_energy(cornell):
    scene, caster, camera, lights, _, reference = cornell
    unclamped = render_reference(scene, caster, lights, camera=camera, clamp=False)
    assert unclamped.clamped_energy == 0.0
    assert reference.clamped_fraction > 0.0
    removed = luminance(unclamped.image).mean() - luminance(reference.image).mean()
    assert removed == pytest.approx(reference.clamped_energy, rel=1e-5)
    total = luminance(unclamped.image).mean()
    assert reference.clamped_fraction == pytest.approx(removed / total, rel=1e-5)
    assert np.all(luminance(unclamped.image) >= luminance(reference.image) * (1 - 1e-6))


def test_emitter_seen_directly_shows_its_radiance(cornell):
    scene, caster, camera, _, _, reference = cornell
    o, d = eye_rays(camera, spp=1, seed=0)
    _, prim = caster.intersect(o.reshape(-1, 3), d.reshape(-1, 3), 0.0, np.inf)
    on_light = np.isin(prim, scene.emitters).reshape(SIZE, SIZE)
    assert on_light.sum() >= 4
    le = scene.emission[scene.emitters[0]]
    # Without lights only the emission is left; with them, emission plus the light the emitter reflects.
    dark = render_reference(scene, caster, {}, camera=camera)
    np.testing.assert_array_equal(dark.image[on_light], np.broadcast_to(le.astype(np.float32), (on_light.sum(), 3)))
    assert np.all(dark.image[~on_light] == 0.0)
    assert np.all(reference.image[on_light] >= le.astype(np.float32))


def quad(y, half, normal_sign):
    """Two triangles: the square |x|, |z| <= half at height y, normal +y (sign 1) or -y (sign -1)."""
    v = np.array([[-half, y, -half], [half, y, -half], [half, y, half], [-half, y, half]])
    f = np.array([[0, 2, 1], [0, 3, 2]]) if normal_sign > 0 else np.array([[0, 1, 2], [0, 2, 3]])
    return v, f


ALBEDO = np.array([0.6, 0.5, 0.4])


def floor_scene(emission=(0.0, 0.0, 0.0), blocker=False, fov=20.0, size=9):
    """A grey floor (y = 0, normal +y, |x|, |z| <= 5) seen from (0, 4, 0) looking down; optionally a
    blocker square (|x|, |z| <= 0.5) at y = 1."""
    parts = [quad(0.0, 5.0, 1)]
    if blocker:
        parts.append(quad(1.0, 0.5, 1))
    vertices = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + 4 * i for i, p in enumerate(parts)])
    em = np.zeros((len(faces), 3))
    em[:2] = emission
    camera = Camera([0.0, 4.0, 0.001], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], fov, size, size)
    return Scene(vertices, faces, albedo=ALBEDO, specular=0.0, exponent=0.0, emission=em, camera=camera)


def one_light(kind, position, normal, intensity, indirect=False):
    return LightSet(np.array([position], float), np.array([normal], float), np.array([intensity], float), kind,
                    np.array([indirect]))


def test_each_light_type_gives_the_analytic_radiance():
    """On the floor: L = rho / pi * I * G * cos(theta_i), evaluated at the exact points the eye rays hit."""
    scene = floor_scene()
    i = np.array([2.0, 3.0, 4.0])
    o, d = eye_rays(scene.camera, spp=4, seed=0)
    p = o + (-o[..., 1:2] / d[..., 1:2]) * d            # hit points on y = 0, (9, 9, 4, 3)

    def point_light(y, n=None):
        v = y - p
        r2 = (v ** 2).sum(-1)
        w = v / np.sqrt(r2)[..., None]
        cos_l = 1.0 if n is None else np.maximum(0.0, -(w @ n))
        return w[..., 1] * cos_l / r2                       # cos_i G

    w = np.array([0.6, 0.8, 0.0])
    cases = {
        "omni": (one_light("omni", [0.3, 2.0, -0.2], [0, 0, 0], i), point_light(np.array([0.3, 2.0, -0.2]))),
        "oriented": (one_light("oriented", [1.0, 2.0, 0.0], [0.0, -0.6, -0.8], i),
                     point_light(np.array([1.0, 2.0, 0.0]), np.array([0.0, -0.6, -0.8]))),
        "directional": (one_light("directional", w, [0, 0, 0], i), np.full(p.shape[:-1], 0.8)),
    }
    with make_caster(scene, "embree") as caster:
        for kind, (light, cos_g) in cases.items():
            tree = build_tree(light, "divisive-6d", seed=0)
            result = render_image(scene, caster, {kind: light}, {kind: tree}, spp=4, seed=0)
            expected = ALBEDO / np.pi * i * cos_g.mean(axis=-1)[..., None]
            np.testing.assert_allclose(result.image, expected, rtol=1e-5, err_msg=kind)


def test_shadows_and_several_trees_at_once():
    scene = floor_scene(blocker=True, fov=60.0, size=21)
    w = np.array([0.6, 0.8, 0.0])
    sun = one_light("directional", w, [0, 0, 0], [1.0, 1.0, 1.0])
    # Analytic sun-only image: the eye ray hits the blocker's top (lit) or the floor, which is in
    # shadow where the ray towards the sun crosses the blocker square at y = 1.
    o, d = eye_rays(scene.camera, spp=1, seed=0)
    o, d = o[:, :, 0], d[:, :, 0]
    top = o + ((1.0 - o[..., 1]) / d[..., 1])[..., None] * d
    on_top = (np.abs(top[..., 0]) <= 0.5) & (np.abs(top[..., 2]) <= 0.5)
    floor = o + (-o[..., 1] / d[..., 1])[..., None] * d
    up = floor + (1.0 / w[1]) * w
    shadow = ~on_top & (np.abs(up[..., 0]) <= 0.5) & (np.abs(up[..., 2]) <= 0.5)
    edge = np.minimum.reduce([np.abs(np.abs(a) - 0.5) for a in (top[..., 0], top[..., 2], up[..., 0], up[..., 2])])
    clear = edge > 1e-3
    assert shadow[clear].sum() >= 5 and (~shadow & ~on_top)[clear].sum() >= 5 and on_top.sum() >= 5
    expected = np.where(shadow, 0.0, 0.8)[..., None] * ALBEDO / np.pi
    rng = np.random.default_rng(0)
    sets = {
        "omni": LightSet(rng.uniform([-3, 1.5, -3], [3, 3, 3], (40, 3)), np.zeros((40, 3)),
                         rng.uniform(0, 1, (40, 3)), "omni"),
        "oriented": LightSet(rng.uniform([-3, 1.5, -3], [3, 3, 3], (60, 3)), np.tile([0.0, -1.0, 0.0], (60, 1)),
                             rng.uniform(0, 1, (60, 3)), "oriented", rng.random(60) < 0.5),
        "directional": sun,
    }
    trees = {k: build_tree(v, "divisive-6d", seed=1) for k, v in sets.items()}
    with make_caster(scene, "embree") as caster:
        sun_only = render_reference(scene, caster, {"directional": sun})
        np.testing.assert_allclose(sun_only.image[clear], expected[clear], rtol=1e-6, atol=1e-7)
        ref = render_reference(scene, caster, sets)
        cut = render_image(scene, caster, sets, trees, eps=0.0, max_cut=200)
    np.testing.assert_allclose(cut.image, ref.image, rtol=1e-5, atol=1e-9)
    assert cut.shadow_rays == ref.shadow_rays


def test_back_of_an_emitter_is_black_and_misses_show_the_environment():
    scene = floor_scene(emission=(5.0, 5.0, 5.0))
    flipped = Scene(scene.vertices, scene.faces[:, ::-1], scene.albedo, scene.specular, scene.exponent,
                    scene.emission, scene.camera)
    with make_caster(scene, "embree") as caster:
        front = render_reference(scene, caster, {})
    with make_caster(flipped, "embree") as caster:
        back = render_reference(flipped, caster, {})
    np.testing.assert_array_equal(front.image, np.full_like(front.image, 5.0))
    np.testing.assert_array_equal(back.image, np.zeros_like(back.image))

    # A camera looking away from the floor sees only the environment map.
    pixels = np.random.default_rng(0).uniform(0, 2, (16, 32, 3)).astype(np.float32)
    env = EnvironmentMap(pixels, rotate=30.0, scale=1.5)
    sky = Camera([0.0, 1.0, 0.0], [0.3, 3.0, 0.2], [0.0, 0.0, 1.0], 60.0, 12, 10)
    with make_caster(scene, "embree") as caster:
        result = render_reference(scene, caster, {}, camera=sky, envmap=env, seed=4)
        dark = render_reference(scene, caster, {}, camera=sky, seed=4)
    _, dirs = eye_rays(sky, spp=1, seed=4)
    np.testing.assert_allclose(result.image, env.radiance(dirs.reshape(-1, 3)).reshape(10, 12, 3), rtol=1e-6)
    assert np.all(dark.image == 0.0) and result.image.max() > 0


def test_eye_rays_are_stratified_and_row_zero_is_at_the_top():
    camera = Camera([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0], 90.0, 4, 2)
    _, d = eye_rays(camera, spp=4, seed=0)
    assert d.shape == (2, 4, 4, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0)
    assert np.all(d[0, :, :, 1] > 0) and np.all(d[1, :, :, 1] < 0)      # row 0 looks up
    # x = cross(forward, up) = -x_world here: column 0 is on the camera's left, +x.
    assert np.all(d[:, 0, :, 0] > d[:, 3, :, 0].max())
    # 2 x 2 strata: the four samples of a pixel fall in different quadrants of it.
    # Film plane at distance 1: half-height tan(45 deg) = 1, half-width 1 * 4 / 2 = 2.
    film = d[..., :2] / d[..., 2:3]
    fx = (1.0 - film[..., 0] / 2.0) / 2.0 * 4 - np.arange(4)[None, :, None]   # position inside the pixel
    fy = (1.0 - film[..., 1]) / 2.0 * 2 - np.arange(2)[:, None, None]
    assert fx.min() >= 0 and fx.max() <= 1 and fy.min() >= 0 and fy.max() <= 1
    quadrant = (fx > 0.5).astype(int) + 2 * (fy > 0.5).astype(int)
    assert np.all(np.sort(quadrant, axis=-1) == [0, 1, 2, 3])
    assert strata(1) == (1, 1) and strata(6) == (3, 2) and strata(7) == (7, 1) and strata(16) == (4, 4)


def test_bad_inputs_raise_one_line_errors(cornell):
    scene, caster, camera, lights, trees, _ = cornell
    with pytest.raises(LightcutsError, match="render.spp"):
        render_image(scene, caster, lights, trees, camera=camera, spp=0)
    with pytest.raises(LightcutsError, match="render.crop"):
        render_image(scene, caster, lights, trees, camera=camera, crop=(0, 0, 49, 10))
    for bad in ([[48, 0]], [[0, -1]], np.zeros((0, 2))):
        with pytest.raises(LightcutsError, match="pixels"):
            render_image(scene, caster, lights, trees, camera=camera, pixels=bad)
    with pytest.raises(LightcutsError, match="render.eps"):
        render_image(scene, caster, lights, trees, camera=camera, eps=float("nan"))
    with pytest.raises(LightcutsError, match="render.max_cut"):
        render_image(scene, caster, lights, trees, camera=camera, max_cut=MAX_CUT + 1)
    with pytest.raises(LightcutsError, match="no tree for the"):
        render_image(scene, caster, lights, {}, camera=camera)
    small = build_tree(direct_lights(scene, 8, seed=0), "divisive-6d")
    with pytest.raises(LightcutsError, match="trees.oriented"):
        render_image(scene, caster, lights, {"oriented": small}, camera=camera)
    with pytest.raises(LightcutsError, match="ray_caster"):
        render_image(scene, make_caster(scene, "embreex"), lights, trees, camera=camera)


def test_forest_packs_every_tree_consistently():
    """Every forest node holds its cluster's box, summed intensity, a representative from the cluster
    and the all-indirect flag (which decides whether the clamped bound applies); siblings sit side by side."""
    rng = np.random.default_rng(5)
    n = 37
    oriented = LightSet(rng.uniform(-1, 1, (n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), rng.uniform(0, 1, (n, 3)),
                        "oriented", rng.random(n) < 0.6)
    omni = LightSet(rng.uniform(-1, 1, (5, 3)), np.zeros((5, 3)), rng.uniform(0, 1, (5, 3)), "omni",
                    np.ones(5, bool))
    sets = {"omni": omni, "oriented": oriented}
    trees = {k: build_tree(v, "divisive-6d", seed=0) for k, v in sets.items()}
    f = build_forest(sets, trees)
    assert f.light_f.shape == (n + 5, 8) and f.node_f.shape[0] == 2 * n - 1 + 2 * 5 - 1 and len(f.roots) == 2
    positions = f.light_f[:, LF_POS:LF_POS + 3]
    indirect = f.light_f[:, LF_INDIRECT] > 0

    def leaves(k):
        if f.node_k[k, NK_LEFT] < 0:
            return [f.node_k[k, NK_REP]]
        return leaves(f.node_k[k, NK_LEFT]) + leaves(f.node_k[k, NK_RIGHT])

    seen = []
    for root in f.roots:
        stack = [root]
        while stack:
            k = stack.pop()
            lights = leaves(k)
            seen += lights if f.node_k[k, NK_LEFT] < 0 else []
            assert f.node_k[k, NK_REP] in lights
            np.testing.assert_allclose(f.node_f[k, NF_I:NF_I + 3], f.light_i[lights].sum(axis=0), rtol=1e-12)
            assert np.all(positions[lights] >= f.node_f[k, NF_LO:NF_LO + 3])
            assert np.all(positions[lights] <= f.node_f[k, NF_HI:NF_HI + 3])
            assert f.node_k[k, NK_ALL_INDIRECT] == indirect[lights].all()
            if f.node_k[k, NK_LEFT] >= 0:
                assert f.node_k[k, NK_RIGHT] == f.node_k[k, NK_LEFT] + 1
                stack += [f.node_k[k, NK_LEFT], f.node_k[k, NK_RIGHT]]
    assert sorted(seen) == list(range(n + 5))
    assert f.node_k[:, NK_ALL_INDIRECT].any() and not f.node_k[:, NK_ALL_INDIRECT].all()
    # The kernel's rows (64 bytes) each sit on one cache line.
    assert f.node_b.ctypes.data % 64 == 0 and f.node_b.strides == (64, 4)
    assert f.light_f.ctypes.data % 64 == 0 and f.light_f.strides == (64, 8)


def test_warm_kernels_compiles_the_specialisation_renders_use(cornell):
    from lightcuts.scene.scene import Scene
    from lightcuts.scene.textures import TextureSet

    # lightcuts.pipeline.warmup compiles the render kernel in a child process through warm_kernels
    # (no lights, another scene): the real renders must then find that very specialisation in the cache.
    from lightcuts.pipeline.warmup import is_cached
    from lightcuts.integrators.lightcut import _render_band, warm_kernels

    scene, caster, _, lights, trees, _ = cornell
    warm_kernels()
    n = len(_render_band.signatures)   # other casters rendered earlier in this process have their own
    render_image(scene, caster, lights, trees, crop=(0, 0, 2, 2))
    render_reference(scene, caster, lights, crop=(0, 0, 2, 2))
    # a textured scene too (lightcuts.scene.textures: the same array types, now not empty)
    ts = TextureSet()
    ts.add(np.full((4, 4, 3), 0.5, np.float32), "grey")
    textured = Scene(scene.vertices, scene.faces, scene.albedo, scene.specular, scene.exponent, scene.emission,
                     scene.camera, uv=np.zeros((scene.n_faces, 3, 2)), texture=np.zeros(scene.n_faces),
                     textures=ts)
    render_image(textured, caster, lights, trees, crop=(0, 0, 2, 2))
    assert len(_render_band.signatures) == n
    assert sum("lightcuts.embree" in str(sig[0]) for sig in _render_band.signatures) == 1
    assert is_cached(_render_band)
