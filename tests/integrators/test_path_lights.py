"""Next-event estimation through light trees in the path integrator (``render.integrator: {type:
path, light_sampler: tree}``): the three samplers' images agree in expectation, tree NEE alone is
the exact direct light, its MIS weights are those of the probability it draws with, it lowers the
variance where emitters lie at very different distances, every builder's tree serves, bad values
are one line, and the bytes do not depend on the thread count."""

from __future__ import annotations

from pathlib import Path as FilePath

import numpy as np
import pytest

from lightcuts.accel import make_caster
from lightcuts.errors import LightcutsError
from lightcuts.integrators.path import Path, path_lights
from lightcuts.trees.spec import tree_spec

from lamps import direct_reference, lamp_scene

ROOT = FilePath(__file__).resolve().parents[2]
BUILDERS = ("agglomerative", "agglomerative-heap", "divisive-3d", "divisive-6d", "greedy", "saoh")


def render(scene, sampler, spp, seed, max_depth=1, builder=None):
    """The path integrator's image of ``scene`` with ``light_sampler`` ``sampler`` (a RenderResult)."""
    with make_caster(scene) as caster:
        return Path(spp=spp, max_depth=max_depth, light_sampler=sampler,
                    tree=tree_spec(builder) if builder else None).render(scene, caster, {}, None, seed=seed)


def _stack(scene, sampler, seeds, spp=16, max_depth=1, builder=None):
    return np.stack([render(scene, sampler, spp, s, max_depth, builder).image.astype(np.float64) for s in seeds])


def _z(d):
    """The sum of independent zero-mean differences ``d`` over its standard error (from the
    differences themselves): about N(0, 1) when their mean is 0."""
    return float(d.sum() / np.sqrt((d * d).sum()))


SEEDS = range(8)
#: 300 small emitters from the patch the camera sees to six times farther, a third of the power near.
MANY = dict(n_far=300, far_radius=(1.0, 6.0), far_power=3.0)


@pytest.fixture(scope="module")
def exact_direct():
    """The scene of ``MANY`` and the exact expectation of its max_depth 1 images for SEEDS."""
    scene = lamp_scene(**MANY)
    return scene, np.stack([direct_reference(scene, 16, s) for s in SEEDS])


@pytest.mark.parametrize("builder", BUILDERS)
def test_tree_nee_alone_is_the_exact_direct_light(exact_direct, builder):
    """max_depth 1 (the first hit's next-event estimation alone) through every builder's tree over
    306 small emitters: per eye ray, the image's expectation is the direct light computed exactly
    (Lambert's form factor of each triangle from the shading point); the images' differences from
    it, over 8 seeds' pixels, average to 0 within 4 standard errors."""
    scene, exact = exact_direct
    images = _stack(scene, "tree", SEEDS, builder=builder)
    assert abs(_z(images - exact)) < 4.0
    assert abs(images.mean() / exact.mean() - 1.0) < 0.02
    with make_caster(scene) as caster:
        r = Path(light_sampler="tree", tree=tree_spec(builder)).render(scene, caster, {}, None, crop=(0, 0, 1, 1))
    assert r.light_sampler["builder"] == builder and r.light_sampler["lights"] == 306
    assert 0 < r.light_sampler["bytes_per_light"] <= 100


def test_the_three_samplers_agree_in_expectation():
    """A glossy floor under the same emitters, up to 3 vertices (next-event estimation and BRDF
    draws weighted by MIS): uniform and tree images against power's, seed by seed, differ by 0 on
    average over the pixels (z-score) and pixel by pixel within their standard errors (mean squared
    z-score near 1)."""
    scene = lamp_scene(**MANY, specular=0.3, exponent=30.0)
    images = {s: _stack(scene, s, SEEDS, max_depth=3) for s in ("power", "uniform", "tree")}
    for s in ("uniform", "tree"):
        d = images[s] - images["power"]
        assert abs(_z(d)) < 4.0, s
        se2 = (images[s].var(axis=0, ddof=1) + images["power"].var(axis=0, ddof=1)) / len(SEEDS)
        assert np.all(se2 > 0) and np.mean(d.mean(axis=0) ** 2 / se2) < 2.0, s


def test_mis_weights_use_the_probability_nee_draws_with():
    """A glossy floor under emitters large enough that BRDF draws and next-event estimation both
    matter: a BRDF draw that hits an emitter is weighted against the probability that tree
    next-event estimation at the previous vertex, from its point and normal, draws that triangle.
    With any other probability there (power's, the tree's at the hit point or without the normal)
    the weights no longer sum to 1 and the image moves away from power's (z-scores 5 to 60 over 16
    seeds); with it, the two agree."""
    scene = lamp_scene(n_far=100, far_radius=(2.0, 10.0), far_power=3.0, near_radius=(0.0, 1.5), size=1.0,
                       specular=0.3, exponent=5.0)
    seeds = range(16)
    d = _stack(scene, "tree", seeds, max_depth=2) - _stack(scene, "power", seeds, max_depth=2)
    assert abs(_z(d)) < 4.0


def test_tree_nee_has_far_lower_variance_where_emitters_lie_at_very_different_distances():
    """Six emitters over the floor the camera sees and 2,000 a hundred times farther with 30 times
    their power: power sampling spends most shadow rays on the far ones, the tree on the near; at
    equal spp the per-pixel variance (over 8 seeds) is several times lower with the default
    (agglomerative) tree and more than ten times with a top-down (saoh) one."""
    scene = lamp_scene(n_far=2000, far_power=30.0)
    power = _stack(scene, "power", SEEDS).var(axis=0, ddof=1).mean()
    assert power / _stack(scene, "tree", SEEDS).var(axis=0, ddof=1).mean() > 3.0
    assert power / _stack(scene, "tree", SEEDS, builder="saoh").var(axis=0, ddof=1).mean() > 10.0


def test_light_order_is_the_triangle_lights_one():
    """The kernel's light k is lightcuts.lights.triangles' light k (the tree's leaves): the same
    triangles in the same order, and tri_light its inverse."""
    from lightcuts.lights.triangles import triangle_lights

    scene = lamp_scene(n_far=50)
    em_tri, *_, tri_light = path_lights(scene, "tree").kernel[:7]
    assert np.array_equal(em_tri, triangle_lights(scene).tri)
    assert np.array_equal(tri_light[em_tri], np.arange(len(em_tri)))
    assert np.count_nonzero(tri_light >= 0) == len(em_tri)


def test_same_bytes_on_any_thread_count(thread_counts):
    """Tree next-event estimation and its MIS keep the path integrator's bytes independent of the
    thread count (an image large enough that every thread takes pixels)."""
    (n1, n2), num_threads = thread_counts
    scene = lamp_scene(**MANY, specular=0.3, exponent=30.0, width=64, height=64)
    with num_threads(n1):
        a = render(scene, "tree", 8, 3, max_depth=4)
    with num_threads(n2):
        b = render(scene, "tree", 8, 3, max_depth=4)
    assert a.image.tobytes() == b.image.tobytes() and a.shadow_rays == b.shadow_rays


def test_bad_light_sampler_and_a_tree_without_emitters_are_one_line():
    """An unknown light_sampler is refused by the plan, naming the key and the choices; a tree over
    a scene without emitting triangles is refused when the render makes it (power renders black)."""
    import lightcuts
    from lightcuts.pipeline.plan import plan_run

    cfg = lightcuts.load_config(ROOT / "configs" / "cornell.yaml",
                                **{"render.integrator": {"type": "path", "light_sampler": "foo"}})
    with pytest.raises(LightcutsError) as e:
        plan_run(cfg, render=True)
    assert str(e.value) == "render.integrator.light_sampler: 'foo' is not one of power, uniform, tree"
    dark = lamp_scene(n_far=0, n_near=0)
    with make_caster(dark) as caster:
        assert Path().render(dark, caster, {}, None).image.max() == 0.0  # power: nothing to draw, a black image
        with pytest.raises(LightcutsError) as e:
            Path(light_sampler="tree").render(dark, caster, {}, None)
    assert str(e.value).startswith("render.integrator.light_sampler: tree: the scene has no emitting triangles")
    assert "\n" not in str(e.value)


def test_the_tree_is_built_once_per_render_inside_its_timed_seconds(monkeypatch):
    """render_timed (every command's image) makes the light tree once for the kernel's load and the
    image, and counts its making in the render's seconds; report.json records the sampler."""
    import time

    import lightcuts
    from lightcuts.integrators import path
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.timing import render_timed

    made = []

    def slow_path_lights(*args):
        made.append(args[1])
        time.sleep(0.5)
        return build(*args)

    build = path.path_lights
    monkeypatch.setattr(path, "path_lights", slow_path_lights)
    cfg = lightcuts.load_config(ROOT / "configs" / "cornell.yaml", **{
        "camera.resolution": [8, 8], "lights.direct.count": 8, "lights.indirect.count": 0,
        "render.integrator": {"type": "path", "light_sampler": "tree", "max_depth": 2}})
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        result, seconds, _ = render_timed(cfg, scene, caster, {}, {}, no_progress=True, integrator=plan.integrator)
    assert made == ["tree"] and seconds >= 0.5
    assert result.light_sampler["type"] == "tree" and 0 < result.light_sampler["build_seconds"] < seconds
    run = lightcuts.render(cfg, progress=False)
    assert run.report["light_sampler"]["builder"] == "agglomerative" and run.report["light_sampler"]["lights"] == 2
