"""The converging renderer: compensation (clamped and glossy light), stochastic representatives and
progressive passes, against exact furnace radiance and a brute-force path tracer.

Furnaces: a closed surface of albedo a (diffuse, or with a Phong lobe) emitting Le everywhere. A
diffuse one has the radiance Le / (1 - a) at every point, exactly; a glossy one's radiance comes
from the path tracer of tests/integrators/pathtracer.py, itself checked on the diffuse furnace first.
Every comparison is seeded, so each test gives the same verdict on every run.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import lightcuts
from lightcuts.accel import make_caster
from lightcuts.pipeline.passes import pass_seed
from lightcuts.lights.direct import direct_lights
from lightcuts.lights.indirect import indirect_lights
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.integrators.lightcut import render_image, render_reference
from lightcuts.scene.cornell import cornell_box
from lightcuts.scene.scene import Camera, Scene
from lightcuts.trees.build import build_tree
from pathtracer import path_trace

LE = 1.0


def sphere_mesh():
    """A unit icosphere (320 faces) whose faces look inwards."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    return np.asarray(m.vertices), np.asarray(m.faces)[:, ::-1].copy()


def furnace(albedo, specular=0.0, exponent=0.0, size=8):
    """The inward sphere emitting LE everywhere, seen from its centre."""
    v, f = sphere_mesh()
    camera = Camera([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0], 60.0, size, size)
    return Scene(v, f, albedo=albedo, specular=specular, exponent=exponent, emission=LE, camera=camera)


def furnace_config(tmp_path, albedo, specular=0.0, exponent=0.0, **render):
    """A run config of :func:`furnace` (the sphere as a PLY file): 8 x 8 pixels."""
    v, f = sphere_mesh()
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "sphere.ply")
    values = {"name": "furnace", "seed": 3,
              "scene.meshes": [{"file": "sphere.ply", "material": {
                  "albedo": [albedo] * 3, "specular": [specular] * 3, "exponent": exponent, "emission": [LE] * 3}}],
              "camera.position": [0.0, 0.0, 0.0], "camera.look_at": [0.0, 0.0, 1.0], "camera.up": [0.0, 1.0, 0.0],
              "camera.fov": 60.0, "camera.resolution": [8, 8], "lights.direct.count": 256,
              "lights.indirect.count": 1500, "render.clamp.min_distance": 0.3, "render.spp": 4,
              **{f"render.{k}": val for k, val in render.items()}}
    (tmp_path / "furnace.yaml").write_text("scene: {}\n")
    return lightcuts.load_config(tmp_path / "furnace.yaml", **values)


def mean_luminance(image):
    return float((np.asarray(image, np.float64) @ LUMINANCE).mean())


@pytest.fixture(scope="module")
def oracle_furnaces():
    """The path tracer on the diffuse and the glossy furnace (8 x 8 pixels, 4,096 paths each)."""
    out = {}
    for name, material in (("diffuse", (0.5, 0.0, 0.0)), ("glossy", (0.3, 0.4, 12.0))):
        scene = furnace(*material)
        with make_caster(scene, "embree") as caster:
            out[name] = mean_luminance(path_trace(scene, caster, scene.camera, 4096, seed=11))
    return out


def test_the_path_tracer_gives_the_diffuse_furnace_its_exact_radiance(oracle_furnaces):
    assert oracle_furnaces["diffuse"] == pytest.approx(LE / (1 - 0.5), rel=0.005)
    # and a glossy lobe of the same total albedo is brighter than its diffuse part alone
    assert LE / (1 - 0.3) < oracle_furnaces["glossy"] < LE / (1 - 0.7)


@pytest.mark.parametrize("kind", ["diffuse", "glossy"])
def test_furnace_with_compensation_and_passes_has_the_exact_radiance(tmp_path, oracle_furnaces, kind):
    """Within 1% of the exact radiance with compensation; without it, clamping (and the glossy lobe the
    VPLs do not carry) make the image measurably darker."""
    material = (0.5,) if kind == "diffuse" else (0.3, 0.4, 12.0)
    exact = oracle_furnaces[kind]
    on = lightcuts.render(furnace_config(tmp_path, *material, compensation=True, representatives="stochastic",
                                         passes=6), progress=False)
    off = lightcuts.render(furnace_config(tmp_path, *material, passes=6), progress=False)
    assert mean_luminance(on.image) == pytest.approx(exact, rel=0.01)
    assert mean_luminance(off.image) < 0.97 * exact
    assert len(on.report["passes"]) == 6
    # several continuations per eye ray: the same expectation, less noise for the cut
    many = lightcuts.render(furnace_config(tmp_path, *material, compensation=True, continuation_rays=4, passes=3),
                            progress=False)
    assert mean_luminance(many.image) == pytest.approx(exact, rel=0.01)
    assert many.report["continuation_rays"] == 4


def inward_box(lo, hi, albedo, specular, exponent, emission):
    """The six faces of the box [lo, hi] as 12 triangles facing inwards, faces in the order -x, +x, -y,
    +y, -z, +z, two triangles each; per-face materials (6, 3) / (6,)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[lo[0], lo[1], lo[2]], [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [lo[0], hi[1], lo[2]],
                  [lo[0], lo[1], hi[2]], [hi[0], lo[1], hi[2]], [hi[0], hi[1], hi[2]], [lo[0], hi[1], hi[2]]])
    quads = [(0, 3, 7, 4), (1, 5, 6, 2), (0, 4, 5, 1), (3, 2, 6, 7), (0, 1, 2, 3), (4, 7, 6, 5)]
    faces = []
    centre = (lo + hi) / 2
    for q in quads:
        for tri in ((q[0], q[1], q[2]), (q[0], q[2], q[3])):
            n = np.cross(c[tri[1]] - c[tri[0]], c[tri[2]] - c[tri[0]])
            faces.append(tri if np.dot(n, centre - c[tri[0]]) > 0 else tri[::-1])
    rep = lambda a: np.repeat(np.asarray(a, float), 2, axis=0)  # noqa: E731
    return c, np.array(faces), rep(albedo), rep(specular), rep(exponent), rep(emission)


@pytest.fixture(scope="module")
def glossy_box():
    """A closed room: a bright ceiling, coloured diffuse walls, a glossy floor and back wall, seen from
    near the front wall (12 x 9 pixels); and the path tracer's image with per-batch images."""
    albedo = [[0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.25, 0.25, 0.25], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5],
              [0.3, 0.3, 0.4]]
    specular = [[0, 0, 0], [0, 0, 0], [0.6, 0.6, 0.6], [0, 0, 0], [0.3, 0.3, 0.3], [0, 0, 0]]
    exponent = [0, 0, 20, 0, 8, 0]
    emission = [[0, 0, 0], [0, 0, 0], [0, 0, 0], [3.0, 3.0, 3.0], [0, 0, 0], [0, 0, 0]]
    v, f, a, s, e, em = inward_box([-1, -1, -1], [1, 1, 1], albedo, specular, exponent, emission)
    camera = Camera([0.0, 0.2, 0.9], [0.0, -0.6, -1.0], [0.0, 1.0, 0.0], 70.0, 12, 9)
    scene = Scene(v, f, a, s, e, em, camera=camera)
    caster = make_caster(scene, "embree")
    batches = np.stack([path_trace(scene, caster, camera, 1024, seed=100 + b) for b in range(8)])
    yield scene, caster, batches
    caster.close()


def converging_passes(scene, caster, passes, compensation, seed=0):
    """Per-pass images of the lightcuts estimator: each pass its own lights, tree and eye rays."""
    images = []
    for p in range(passes):
        s = pass_seed(seed, p)
        lights = LightSet.concatenate([direct_lights(scene, 128, seed=s),
                                       indirect_lights(scene, caster, 1500, seed=s + 1, glossy=compensation)])
        trees = {"oriented": build_tree(lights, "agglomerative", seed=s)}
        r = render_image(scene, caster, {"oriented": lights}, trees, spp=4, eps=0.02, seed=s,
                         clamp_min_distance=0.1, compensation=compensation, representatives="stochastic")
        images.append(r.image.astype(np.float64))
    return np.stack(images)


def regions(images):
    """(..., 5) luminance means: the four quadrants of the image and the whole image."""
    lum = images @ LUMINANCE
    h, w = lum.shape[-2] // 2, lum.shape[-1] // 2
    parts = [lum[..., :h, :w], lum[..., :h, w:], lum[..., h:, :w], lum[..., h:, w:], lum]
    return np.stack([p.mean(axis=(-2, -1)) for p in parts], axis=-1)


def test_vpls_and_the_continuation_partition_the_paths(glossy_box):
    """The VPLs' light and the eye-path continuation's add up to the path tracer's image (each of five
    regions within 3 standard errors); without the continuation the image is off by more."""
    scene, caster, batches = glossy_box
    truth = regions(batches)
    t_mean, t_se = truth.mean(axis=0), truth.std(axis=0, ddof=1) / np.sqrt(len(truth))
    for compensation in (True, False):
        est = regions(converging_passes(scene, caster, 12, compensation))
        e_mean, e_se = est.mean(axis=0), est.std(axis=0, ddof=1) / np.sqrt(len(est))
        z = np.abs(e_mean - t_mean) / np.sqrt(t_se ** 2 + e_se ** 2)
        if compensation:
            assert np.all(z < 3.0), (z, e_mean / t_mean)
        else:
            assert z[-1] > 3.0 and e_mean[-1] < t_mean[-1], (z, e_mean / t_mean)


def test_the_exact_path_tracer_agrees_with_the_oracle(glossy_box, oracle_furnaces):
    """lightcuts.integrators.path (next-event estimation and BRDF draws with MIS) against the
    brute-force oracle on the glossy room (five regions within 3 standard errors) and the diffuse
    furnace's exact radiance (within 0.5%)."""
    from lightcuts.integrators.path import path_trace as exact

    scene, caster, batches = glossy_box
    truth = regions(batches)
    est = regions(np.stack([exact(scene, caster, spp=256, seed=s)[0].astype(np.float64) for s in range(8)]))
    se = np.sqrt(truth.var(axis=0, ddof=1) / len(truth) + est.var(axis=0, ddof=1) / len(est))
    assert np.all(np.abs(est.mean(axis=0) - truth.mean(axis=0)) < 3 * se), est.mean(axis=0) / truth.mean(axis=0)
    f = furnace(0.5)
    with make_caster(f, "embree") as c:
        image, _ = exact(f, c, spp=1024, seed=1)
    assert mean_luminance(image) == pytest.approx(LE / (1 - 0.5), rel=0.005)


@pytest.fixture(scope="module")
def cornell_lights():
    scene = cornell_box({"floor": {"specular": [0.3, 0.3, 0.3], "exponent": 40.0}})
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, 32, 32)
    caster = make_caster(scene, "embree")
    lights = LightSet.concatenate([direct_lights(scene, 256, seed=1), indirect_lights(scene, caster, 3000, seed=2)])
    trees = {"oriented": build_tree(lights, "agglomerative", seed=3)}
    yield scene, caster, camera, {"oriented": lights}, trees
    caster.close()


def test_stochastic_representatives_are_unbiased_for_the_lights(cornell_lights):
    """Over seeds, a pixel's stochastic estimate minus the all-lights value of the same eye ray has
    mean zero (within 3 standard errors, per pixel and over the pixels); fixed representatives do
    not vary with the seed beyond their eye ray."""
    scene, caster, camera, lights, trees = cornell_lights
    pixels = np.array([[x, y] for x in (4, 12, 20, 28) for y in (6, 16, 26)], np.int64)
    diffs = []
    for seed in range(48):
        kw = dict(camera=camera, seed=seed, pixels=pixels)
        est = render_image(scene, caster, lights, trees, eps=0.05, representatives="stochastic", **kw)
        ref = render_reference(scene, caster, lights, **kw)
        diffs.append((est.image.astype(np.float64) - ref.image) @ LUMINANCE)
    d = np.concatenate(diffs, axis=1)  # (pixels, seeds)
    se = d.std(axis=1, ddof=1) / np.sqrt(d.shape[1])
    assert np.all(se > 0)  # the estimate does move with the seed
    assert np.all(np.abs(d.mean(axis=1)) < 3 * se)
    total = d.mean(axis=0)
    assert abs(total.mean()) < 3 * total.std(ddof=1) / np.sqrt(len(total))


def test_default_settings_give_the_plain_render_bytes(cornell_lights):
    """passes 1, no compensation and fixed representatives are the plain render, byte for byte."""
    scene, caster, camera, lights, trees = cornell_lights
    plain = render_image(scene, caster, lights, trees, camera=camera, seed=5)
    explicit = render_image(scene, caster, lights, trees, camera=camera, seed=5, compensation=False,
                            representatives="fixed")
    assert plain.image.tobytes() == explicit.image.tobytes()
    assert plain.cut_size.tobytes() == explicit.cut_size.tobytes()


def test_passes_average_independent_renders(tmp_path):
    """passes: 2 is the mean of the run at its seed and at pass_seed(seed, 1), and its report records both."""
    cfg = furnace_config(tmp_path, 0.5, passes=2)
    two = lightcuts.render(cfg, progress=False)
    one = lightcuts.render(cfg.model_copy(update={"render": cfg.render.model_copy(update={"passes": 1})}),
                           progress=False)
    second = lightcuts.render(cfg.model_copy(update={"seed": pass_seed(cfg.seed, 1),
                                                     "render": cfg.render.model_copy(update={"passes": 1})}),
                              progress=False)
    expected = ((one.image.astype(np.float64) + second.image) / 2).astype(np.float32)
    assert np.array_equal(two.image, expected)
    assert not np.array_equal(one.image, second.image)
    records = two.report["passes"]
    assert [r["seed"] for r in records] == [cfg.seed, pass_seed(cfg.seed, 1)]
    assert records[0]["change"] is None and records[1]["change"] > 0


def test_converging_render_is_identical_on_any_thread_count(cornell_lights, thread_counts):
    scene, caster, camera, lights, trees = cornell_lights
    counts, num_threads = thread_counts
    images = []
    for n in counts:
        with num_threads(n):
            r = render_image(scene, caster, lights, trees, camera=camera, seed=2, compensation=True,
                             representatives="stochastic")
        images.append(r.image.tobytes())
    assert images[0] == images[1]


def test_passes_work_with_the_multidimensional_integrator_which_refuses_compensation(tmp_path):
    from lightcuts.errors import LightcutsError

    cfg = furnace_config(tmp_path, 0.5, passes=2, integrator="multidimensional")
    two = lightcuts.render(cfg, progress=False)
    one = lightcuts.render(cfg.model_copy(update={"render": cfg.render.model_copy(update={"passes": 1})}),
                           progress=False)
    assert len(two.report["passes"]) == 2 and not np.array_equal(one.image, two.image)
    assert mean_luminance(two.image) == pytest.approx(mean_luminance(one.image), rel=0.1)
    with pytest.raises(LightcutsError, match="render.continuation_rays: 4 continuations per eye ray need"):
        lightcuts.render(furnace_config(tmp_path, 0.5, continuation_rays=4), progress=False)
    with pytest.raises(LightcutsError, match="render.compensation: integrator 'multidimensional' does not"):
        lightcuts.render(furnace_config(tmp_path, 0.5, compensation=True, integrator="multidimensional"),
                         progress=False)
