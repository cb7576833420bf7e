"""The path integrator (``render.integrator: {type: path, max_depth: K}``): a run like any other,
its passes the mean of its pass seeds' images, its paths at most K vertices, the runs it cannot
render refused in one line before any work. That it is the reference command's path tracer, byte
for byte: tests/commands/test_reference_pathtrace.py; on a cluster: tests/distributed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import lightcuts
from lightcuts.accel import make_caster
from lightcuts.pipeline.passes import pass_seed
from lightcuts.errors import LightcutsError
from lightcuts.integrators.path import path_trace
from lightcuts.integrators.registry import make_integrator

from conftest import cli_recording_work

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "configs" / "cornell.yaml"
SMALL = {"camera.resolution": [16, 16], "lights.direct.count": 32, "lights.indirect.count": 200}


def path_config(**overrides):
    return lightcuts.load_config(CORNELL, **{**SMALL, "render.integrator": "path", **overrides})


def run_scene(cfg):
    from lightcuts.pipeline.plan import plan_run

    return plan_run(cfg, render=True).scene()


def test_passes_are_the_mean_of_the_pass_seeds_path_images():
    """render.passes with the path integrator: pass p's image is the path tracer's at pass_seed(seed,
    p), and the run's image their mean, summed in pass order (lightcuts.pipeline.passes.PassMean)."""
    cfg = path_config(**{"render.passes": 3, "render.spp": 2, "seed": 11})
    run = lightcuts.render(cfg, progress=False)
    scene = run_scene(cfg)
    with make_caster(scene) as caster:
        images = [path_trace(scene, caster, spp=2, seed=pass_seed(11, p))[0] for p in range(3)]
    acc = images[0].astype(np.float64)
    for image in images[1:]:
        acc = acc + image
    assert run.image.tobytes() == (acc / 3).astype(np.float32).tobytes()
    assert [p["seed"] for p in run.report["passes"]] == [pass_seed(11, p) for p in range(3)]
    assert run.report["cut_size_unit"] == "path vertices per eye ray"
    assert run.report["plugins"]["integrator"] == {"type": "path", "max_depth": 64, "light_sampler": "power"}
    assert run.report["light_sampler"]["type"] == "power" and run.report["light_sampler"]["lights"] == 2


def test_paths_have_at_most_max_depth_vertices():
    """cut_size counts path vertices per eye ray: within max_depth; with max_depth 1 a path is its
    first hit (the emitters it sees and their direct light: less light than every bounce), one
    next-event shadow ray at most per vertex."""
    images = {}
    for k in (1, 3, 64):
        cfg = path_config(**{"render.integrator": {"type": "path", "max_depth": k}, "render.spp": 4})
        scene = run_scene(cfg)
        with make_caster(scene) as caster:
            r = make_integrator(cfg).render(scene, caster, {}, None, seed=cfg.seed)
        assert 0 < r.cut_size.max() <= k and r.max_cut == k
        assert 0 < r.shadow_rays <= r.cut_size.sum() * 4 and r.shadow_rays_image.shape == (16, 16)
        images[k] = r
    assert set(np.unique(images[1].cut_size)) <= {0.0, 0.25, 0.5, 0.75, 1.0}
    assert images[1].cut_size.max() == 1.0 and images[3].cut_size.max() > 1.0
    assert images[1].image.mean() < images[3].image.mean()


@pytest.mark.parametrize("sets, message", [
    ({"lights.sun": {"direction": [0, -1, 0], "irradiance": [1, 1, 1]}}, "lights.sun: integrator 'path' renders"),
    ({"render.integrator": {"type": "path", "max_depth": 65}},
     "render.integrator.max_depth: 65 is above the maximum 64"),
])
def test_the_plan_refuses_what_the_path_integrator_cannot_render(sets, message):
    from lightcuts.pipeline.plan import plan_run

    with pytest.raises(LightcutsError) as e:
        plan_run(path_config(**sets), render=True)
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_a_sun_a_reference_or_a_compare_is_one_line_before_any_work(tmp_path):
    """What the path integrator cannot do stops the command in one line, exit status 2, before a
    scene, lights or trees are made; an environment map given to its render is one line too."""
    path = ["--set", "render.integrator=path"]
    for argv, message in [(["render", str(ROOT / "configs" / "sun-env.yaml"), *path],
                           "error: lights.sun: integrator 'path' renders the scene's emitting triangles only"),
                          (["render", str(CORNELL), *path, "--reference"],
                           "error: --reference: integrator 'path' has no brute-force reference"),
                          (["compare", str(CORNELL), *path],
                           "error: render.integrator: integrator 'path' does not render the config's lights through their "
                           "trees")]:
        rc, calls, err = cli_recording_work(argv + ["--out", "out"], tmp_path)
        assert (rc, calls) == (2, []), err
        assert err.strip().splitlines() == [err.strip()] and err.strip().startswith(message), err
    with pytest.raises(LightcutsError, match="^envmap: integrator 'path' renders"):
        from lightcuts.lights.environment import EnvironmentMap

        scene = run_scene(path_config())
        env = EnvironmentMap(np.ones((4, 8, 3), np.float32))
        with make_caster(scene) as caster:
            make_integrator(path_config()).render(scene, caster, {}, None, envmap=env)


def test_warm_kernels_compiles_the_specialisation_renders_use():
    """The commands compile the path kernel in a child process through warm_kernels (the ``kernels``
    trait's module; another scene, no lights): a run's render then finds that very specialisation."""
    from lightcuts.pipeline.warmup import is_cached
    from lightcuts.integrators import path
    from lightcuts.integrators.registry import INTEGRATORS

    assert INTEGRATORS.entry("path").trait("kernels") == path.__name__
    path.warm_kernels()
    n = len(path._render_band.signatures)
    cfg = path_config(**{"render.integrator": {"type": "path", "max_depth": 5}})
    scene = run_scene(cfg)
    with make_caster(scene) as caster:
        make_integrator(cfg).render(scene, caster, {}, None, crop=(0, 0, 2, 2))
        path_trace(scene, caster, spp=3, seed=2, crop=(3, 3, 5, 4))
    assert len(path._render_band.signatures) == n and is_cached(path._render_band)
