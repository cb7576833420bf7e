"""A render whose integrator does not render from the config's lights and trees (the path tracer,
which draws the scene's emitting triangles itself) makes neither, in any pass: report.json says so,
its time is the image's alone, and its image is the one rendered when they were made. An integrator
that cuts light trees still makes them for every pass."""

from pathlib import Path

import numpy as np
import pytest

import lightcuts
from lightcuts.pipeline.plan import Plan, plan_run

CORNELL = Path(__file__).resolve().parents[2] / "configs" / "cornell.yaml"
#: cornell's own 100,000 indirect VPLs, which a path render must not trace.
PATH = {"camera.resolution": [16, 12], "render.spp": 2, "render.passes": 2,
        "render.integrator": {"type": "path", "max_depth": 4}}


def _no_lights_or_trees(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("made the config's lights or trees")

    monkeypatch.setattr(Plan, "lights", refuse)
    monkeypatch.setattr(Plan, "trees", refuse)


@pytest.mark.parametrize("integrator, uses", [("lightcuts", True), ("multidimensional", True),
                                              ("stochastic-lightcuts", True), ({"type": "path"}, False),
                                              ({"type": "path", "light_sampler": "tree"}, False)])
def test_the_plan_says_which_integrators_use_lights_and_trees(integrator, uses):
    assert plan_run(lightcuts.load_config(CORNELL, **{"render.integrator": integrator})).uses_trees is uses


def test_a_path_render_makes_no_lights_or_trees_and_reports_none(monkeypatch, tmp_path):
    _no_lights_or_trees(monkeypatch)
    r = lightcuts.render(lightcuts.load_config(CORNELL, **PATH), progress=False)
    rep = r.report
    assert rep["lights"] == {} and rep["lights_indirect"] == 0
    assert rep["builder"] is None and rep["metric"] is None and rep["c"] == {}
    assert rep["light_sampler"]["type"] == "power" and rep["light_sampler"]["lights"] == 2
    assert rep["build_seconds"] == 0.0
    parts = rep["image_seconds_parts"]
    assert parts["lights"] == parts["trees"] == 0.0 and rep["image_seconds"] == parts["passes"] > 0
    assert len(rep["passes"]) == 2
    assert all(p["lights_seconds"] == p["build_seconds"] == 0.0 for p in rep["passes"])
    assert "2 lights drawn by power:" in r.summary()
    r.save(tmp_path / "out")  # report.html and cutsize.png read the report's lights and builder
    assert (tmp_path / "out" / "report.html").stat().st_size > 0


def test_a_path_tree_sampler_reports_its_own_builder(monkeypatch):
    _no_lights_or_trees(monkeypatch)
    cfg = lightcuts.load_config(CORNELL, **{**PATH, "render.passes": 1, "tree.builder": "saoh",
                                            "render.integrator": {"type": "path", "max_depth": 4,
                                                                  "light_sampler": "tree"}})
    r = lightcuts.render(cfg, progress=False)
    assert r.report["lights"] == {} and r.report["builder"] == r.report["light_sampler"]["builder"] == "saoh"
    assert r.report["c"] == {}
    assert "drawn by tree, builder saoh" in r.summary()


def test_the_path_image_is_the_one_rendered_with_the_lights_and_trees():
    """Each pass rendered as before, from its traced VPLs and their trees (which the path tracer
    ignores), and the passes averaged as render_passes does: the same bytes."""
    from lightcuts.integrators.registry import make_integrator
    from lightcuts.pipeline.passes import pass_seed

    cfg = lightcuts.load_config(CORNELL, **{**PATH, "lights.indirect.count": 3000})
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    caster, envmap = plan.make_caster(scene), plan.environment()
    integ = make_integrator(cfg, plan.integrator)
    acc = 0.0
    for p in range(2):
        seed = pass_seed(cfg.seed, p)
        lights = plan.lights(scene, caster, envmap, seed=seed)
        assert sum(len(ls) for ls in lights.values()) > 1000
        trees = plan.trees(lights, seed=seed)
        acc = acc + integ.render(scene, caster, lights, trees, envmap=envmap, seed=seed).image.astype(np.float64)
    expected = (acc / 2).astype(np.float32)
    assert lightcuts.render(cfg, progress=False).image.tobytes() == expected.tobytes()


def test_a_lightcuts_render_makes_lights_and_trees_every_pass(monkeypatch):
    made = {"lights": 0, "trees": 0}
    for name in made:
        real = getattr(Plan, name)

        def spy(self, *args, _real=real, _name=name, **kwargs):
            made[_name] += 1
            return _real(self, *args, **kwargs)

        monkeypatch.setattr(Plan, name, spy)
    cfg = lightcuts.load_config(CORNELL, **{"camera.resolution": [12, 12], "lights.direct.count": 64,
                                            "lights.indirect.count": 2000, "render.passes": 2})
    rep = lightcuts.render(cfg, progress=False).report
    assert made == {"lights": 2, "trees": 2}
    assert rep["lights"]["oriented"] > 1000 and rep["builder"] == "agglomerative" and rep["c"]["oriented"] > 0
    assert rep["image_seconds_parts"]["lights"] > 0 and rep["image_seconds_parts"]["trees"] > 0
    assert all(p["lights_seconds"] > 0 and p["build_seconds"] > 0 for p in rep["passes"][1:])
