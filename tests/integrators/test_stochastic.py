"""The stochastic lightcuts integrator (lightcuts.integrators.stochastic, stochastic_cut): unbiased for
the sum over its lights (the lightcut's all-lights reference) whatever the cut size and the builder,
exact when the cut holds every light, the emitting triangles as lights against the path tracer's
direct light, its refusals, and images that do not depend on the threads."""

from pathlib import Path

import numpy as np
import pytest

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.integrators.path import Path as PathTracer
from lightcuts.integrators.registry import make_integrator
from lightcuts.integrators.stochastic import StochasticLightcuts, sampled_forest
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.parallel import num_threads
from lightcuts.pipeline.plan import plan_run
from lightcuts.scene.scene import Scene
from lightcuts.trees import BUILDERS, build_tree

ROOT = Path(__file__).parents[2]
#: A few pixels (x, y) of the 16 x 16 Cornell box: the walls, the floor, the blocks.
PIXELS = [[3, 8], [5, 14], [11, 9], [6, 5], [13, 4]]
#: Area lights added to the Cornell box for the triangle-light tests: 16 small quads under the
#: ceiling and a disc of 8 triangles on the left wall (42 emitting triangles with the box's own).
EMITTERS = [{"grid": {"lo": [110, 540, 110], "hi": [440, 540, 440], "count": [4, 1, 4]}, "normal": [0, -1, 0],
             "size": [40, 40], "radiance": [20, 14, 8]},
            {"shape": "disc", "position": [2, 220, 280], "normal": [1, 0, 0], "radius": 60, "segments": 8,
             "radiance": [3, 8, 16]}]


def _config(**over):
    base = {"camera.resolution": [16, 16], "lights.direct.count": 64, "lights.indirect.count": 300,
            "render.clamp.enabled": False, "render.spp": 2}
    return lightcuts.load_config(ROOT / "configs" / "cornell.yaml", **{**base, **over})


@pytest.fixture(scope="module")
def box():
    """The small Cornell box run's scene, caster, lights (64 direct + ~300 indirect VPLs) and trees."""
    cfg = _config()
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        lights = plan.lights(scene, caster)
        yield scene, caster, lights, plan.trees(lights)


def _lum(image):
    return np.asarray(image, np.float64) @ LUMINANCE


def _differences(integ, other, scene, caster, lights, trees, seeds, **kw):
    """(seeds, ...) luminance of integ's image minus other's, each pair on the same eye rays."""
    out = []
    for seed in range(seeds):
        a = integ.render(scene, caster, lights, trees, seed=seed, **kw).image
        b = other.render(scene, caster, lights, trees, seed=seed, **kw).image
        out.append(_lum(a) - _lum(b))
    return np.array(out)


def _within_3_se(d, scale, power=0.03):
    """Each column of d (seeds, ...) averages to 0 within 3 standard errors, and the test can see a
    bias of ``power`` times ``scale`` (one value, or one per column): its standard error is small
    enough."""
    d = d.reshape(len(d), -1)
    scale = np.ravel(scale)
    mean, se = d.mean(axis=0), d.std(axis=0, ddof=1) / np.sqrt(len(d))
    assert np.all(np.abs(mean) <= 3 * se + 1e-9 * scale), (mean, se)
    assert np.all(3 * se < power * scale), (se, scale)
    assert np.all(se > 0)  # the estimates are noisy: the equality is not trivial


@pytest.mark.parametrize("max_cut", [1, 4, 32])
def test_unbiased_for_the_sum_over_its_lights(box, max_cut):
    """Over independent draws on the same eye rays, the image's total and a few pixels average to
    the all-lights reference's (clamping off), whatever the cut size."""
    scene, caster, lights, trees = box
    integ = StochasticLightcuts(spp=2, max_cut=max_cut, clamp=False)
    ref = integ.reference()
    total = _differences(integ, ref, scene, caster, lights, trees, 72).mean(axis=(1, 2))
    level = _lum(ref.render(scene, caster, lights, None).image).mean()
    _within_3_se(total, level)
    integ32 = StochasticLightcuts(spp=32, max_cut=max_cut, clamp=False)
    ref32 = integ32.reference()
    d = _differences(integ32, ref32, scene, caster, lights, trees, 64, pixels=PIXELS)
    _within_3_se(d, _lum(ref32.render(scene, caster, lights, None, pixels=PIXELS).image), power=0.1)


def test_a_cut_of_every_light_is_the_reference(box):
    """With max_cut the number of lights every cut is all its leaves, each exact: the reference's
    image (to rounding), and each cut counts the lights that can light the point."""
    scene, caster, lights, trees = box
    n = sum(len(ls) for ls in lights.values())
    integ = StochasticLightcuts(spp=2, max_cut=n)
    a = integ.render(scene, caster, lights, trees, seed=5)
    b = integ.reference().render(scene, caster, lights, None, seed=5)
    np.testing.assert_allclose(a.image, b.image, rtol=1e-6, atol=0)
    assert a.cut_size.max() <= n and a.cut_size.mean() > 0.5 * n
    small = StochasticLightcuts(spp=2, max_cut=8).render(scene, caster, lights, trees, seed=5)
    assert small.cut_size.max() <= 8 and not np.allclose(small.image, b.image, rtol=1e-3)


@pytest.mark.parametrize("builder", BUILDERS.names())
def test_every_builders_tree(box, builder):
    """Any builder's tree: exact with a cut of every light, unbiased with a cut of 4 nodes."""
    scene, caster, lights, _ = box
    trees = {t: build_tree(ls, builder, seed=1) for t, ls in lights.items()}
    n = sum(len(ls) for ls in lights.values())
    ref = StochasticLightcuts(spp=2).reference()
    exact = StochasticLightcuts(spp=2, max_cut=n).render(scene, caster, lights, trees, seed=2)
    np.testing.assert_allclose(exact.image, ref.render(scene, caster, lights, None, seed=2).image, rtol=1e-6, atol=0)
    integ = StochasticLightcuts(spp=2, max_cut=4)
    total = _differences(integ, ref, scene, caster, lights, trees, 32).mean(axis=(1, 2))
    _within_3_se(total, _lum(ref.render(scene, caster, lights, None).image).mean())


@pytest.fixture(scope="module")
def lamps():
    """The Cornell box with 42 emitting triangles, its triangle lights (no VPLs) and their trees, and
    the path tracer's direct light ({type: path, max_depth: 1})."""
    over = {"scene.emitters": EMITTERS, "lights.indirect.count": 0, "lights.direct.source": "triangles",
            "render.integrator": {"type": "stochastic-lightcuts", "max_cut": 4}, "render.spp": 8}
    cfg = _config(**over)
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        lights = plan.lights(scene, caster)
        path = make_integrator(_config(**{**over, "lights.direct.source": "samples",
                                          "render.integrator": {"type": "path", "max_depth": 1}}))
        yield cfg, plan, scene, caster, lights, plan.trees(lights), path


def test_triangle_lights_are_the_emitting_triangles(lamps):
    """lights.direct.source: triangles makes every emitting triangle one oriented light (no direct
    VPLs), and the forest samples them with their triangles' corners and boxes."""
    cfg, plan, scene, caster, lights, trees, _ = lamps
    ls = lights["oriented"]
    assert len(ls) == len(scene.emitters) == 42 and ls.meta["direct_source"] == "triangles"
    np.testing.assert_allclose(ls.intensity, scene.emission[scene.emitters] * scene.face_areas[scene.emitters, None])
    f = sampled_forest(lights, trees, scene)
    np.testing.assert_array_equal(f.light_tri, np.arange(42))
    corners = f.tri_geo[:, :3, None] + np.stack([np.zeros((42, 3)), f.tri_geo[:, 3:6], f.tri_geo[:, 6:]], axis=2)
    np.testing.assert_allclose(corners.mean(axis=2), ls.position)
    rec, roots = f.sampler[0], f.sampler[3]  # the root's box holds every triangle, not only the centroids
    assert np.all(rec[roots[0], :3] <= corners.min(axis=(0, 2))) and np.all(rec[roots[0], 3:6] >= corners.max(axis=(0, 2)))


@pytest.mark.parametrize("max_cut", [1, 8])
def test_triangle_lights_give_the_path_tracers_direct_light(lamps, max_cut):
    """Drawing a triangle through the tree and a uniform point of it is unbiased for the direct
    light: the image's total and a few pixels average to the path tracer's (max_depth 1), on the
    same eye rays."""
    cfg, plan, scene, caster, lights, trees, path = lamps
    integ = StochasticLightcuts(spp=8, max_cut=max_cut)
    total = _differences(integ, path, scene, caster, lights, trees, 32).mean(axis=(1, 2))
    _within_3_se(total, _lum(path.render(scene, caster, {}, None).image).mean())
    d = _differences(StochasticLightcuts(spp=64, max_cut=max_cut), PathTracer(spp=64, max_depth=1), scene, caster, lights,
                     trees, 48, pixels=PIXELS)
    _within_3_se(d, _lum(StochasticLightcuts(spp=64, max_cut=64).render(scene, caster, lights, trees,
                                                                         pixels=PIXELS).image), power=0.1)


def test_triangle_lights_of_another_scene_are_refused(lamps, box):
    cfg, plan, scene, caster, lights, trees, _ = lamps
    with pytest.raises(LightcutsError, match=r"^lights.oriented: its first 42 lights are not the scene's 2 emitting"):
        sampled_forest(lights, trees, box[0])
    with pytest.raises(LightcutsError, match=r"^lights.direct.source: integrator Lightcuts renders point lights only"):
        StochasticLightcuts().reference().render(scene, caster, lights, None, crop=(0, 0, 1, 1))


def test_bad_settings_are_one_line():
    for spec, message in (({"type": "stochastic-lightcuts", "max_cut": 0},
                           "render.integrator.max_cut: 0 is below the minimum 1"),
                          ({"type": "stochastic-lightcuts", "max_cut": 2.5}, "render.integrator.max_cut: expected int"),
                          ({"type": "stochastic-lightcuts", "eps": 0.1},
                           "render.integrator.eps: integrator 'stochastic-lightcuts' has no parameter 'eps'")):
        with pytest.raises(LightcutsError) as e:
            plan_run(_config(**{"render.integrator": spec}), render=True)
        assert str(e.value).startswith(message) and "\n" not in str(e.value)
    with pytest.raises(LightcutsError, match=r"^lights.direct.source: integrator 'lightcuts' renders point lights "
                                             r"only; use render.integrator: stochastic-lightcuts"):
        plan_run(_config(**{"lights.direct.source": "triangles"}), render=True)
    with pytest.raises(LightcutsError, match=r"lights.direct.source"):
        _config(**{"lights.direct.source": "points"})
    with pytest.raises(LightcutsError, match=r"^trees: stochastic lightcuts draw their lights through the light trees"):
        StochasticLightcuts().forest({"oriented": lightcuts.lights.LightSet(np.zeros((1, 3)), [[0, 0, 1.0]],
                                                                           np.ones((1, 3)), "oriented")}, None, None)


def test_a_scene_without_emitters_has_no_triangle_lights():
    from lightcuts.lights.generate import lights_from_config

    cfg = _config(**{"lights.direct.source": "triangles", "lights.indirect.count": 0,
                     "lights.sun": {"direction": [0, 1, 0], "irradiance": [1, 1, 1]},
                     "render.integrator": "stochastic-lightcuts"})
    floor = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], float)
    scene = Scene(floor, np.array([[0, 1, 2], [0, 2, 3]]), albedo=0.5, specular=0.0, exponent=0.0,
                  emission=np.zeros((2, 3)))
    with pytest.raises(LightcutsError, match=r"^lights.direct.source: triangles, but the scene has no emissive"):
        lights_from_config(cfg, scene)


def test_the_image_does_not_depend_on_the_threads(box):
    """The same bytes twice, on one thread and on all, and for a crop window of the image."""
    scene, caster, lights, trees = box
    integ = StochasticLightcuts(spp=3, max_cut=8, clamp=True)
    with num_threads(1):
        one = integ.render(scene, caster, lights, trees, seed=9)
    many = integ.render(scene, caster, lights, trees, seed=9)
    again = integ.render(scene, caster, lights, trees, seed=9)
    assert one.image.tobytes() == many.image.tobytes() == again.image.tobytes()
    assert one.shadow_rays_image.tobytes() == many.shadow_rays_image.tobytes()
    crop = integ.render(scene, caster, lights, trees, seed=9, crop=(5, 3, 14, 11))
    assert crop.image.tobytes() == many.image[3:11, 5:14].tobytes()
    other = integ.render(scene, caster, lights, trees, seed=10)
    assert other.image.tobytes() != many.image.tobytes()


def test_clamping_is_off_unless_the_config_sets_it():
    """render.clamp.enabled as the config gives it; left out, the lightcut clamps and this does not."""
    kitchen = ROOT / "configs" / "kitchen.yaml"
    slc = {"render.integrator": "stochastic-lightcuts"}
    assert make_integrator(lightcuts.load_config(kitchen)).clamp
    assert not make_integrator(lightcuts.load_config(kitchen, **slc)).clamp
    assert make_integrator(lightcuts.load_config(kitchen, **slc, **{"render.clamp.enabled": True})).clamp
    assert not make_integrator(lightcuts.load_config(kitchen, **slc, **{"render.clamp.min_distance": 0.1})).clamp


def test_a_run_through_the_pipeline_with_passes():
    """lightcuts.render with the integrator: its cut unit, passes averaged, a clamp that removes light."""
    cfg = _config(**{"render.integrator": {"type": "stochastic-lightcuts", "max_cut": 8}, "render.passes": 2,
                     "render.clamp.enabled": True})
    r = lightcuts.render(cfg, progress=False)
    assert r.report["cut_size_unit"] == "cut nodes per eye ray" and r.cut_size.max() <= 8
    assert len(r.report["passes"]) == 2 and r.report["clamping"]["clamped_energy_fraction"] > 0
    assert r.report["clamping"]["enabled"] is True
    assert r.report["plugins"]["integrator"] == {"type": "stochastic-lightcuts", "max_cut": 8}
