"""Plugins: one contract test per registry over every registered name, and the plan step's checks.

A new builder or metric is tested by registering it: the parametrisations below read the registries'
names (ray casters: tests/accel/test_casters.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from numba import njit

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.registry import Registry, declare
from lightcuts.integrators.registry import INTEGRATORS
from lightcuts.scene.registry import SCENES
from lightcuts.trees import BUILDERS, METRICS, Metric, build_tree, register_metric, tree_spec, validate_tree
from lightcuts.trees.metric_type import metric_values

from conftest import cli_recording_work, random_lights

ROOT = Path(lightcuts.__file__).parents[1]


# ------------------------------------------------------------------------------------- builders

@pytest.mark.parametrize("name", BUILDERS.names())
@pytest.mark.parametrize("light_type", ["omni", "oriented", "directional"])
def test_builder_contract(name, light_type):
    """Every builder: a valid tree for every light type, given only what it reads, and a meta that
    records exactly that."""
    entry = BUILDERS.entry(name)
    assert entry.reads <= BUILDERS.params
    lights = random_lights(70, light_type, seed=3)
    tree = build_tree(lights, builder=name, seed=2)
    validate_tree(tree, lights)
    assert tree.meta["builder"] == name
    assert ("metric" in tree.meta) == ("metric" in entry.reads)
    spec = tree_spec(name)
    assert ("c" in tree.meta) == spec.reads_c
    if spec.reads_c:
        assert tree.meta["c"] > 0


@pytest.mark.parametrize("name", BUILDERS.names())
def test_builder_refuses_what_it_does_not_read(name):
    entry = BUILDERS.entry(name)
    lights = random_lights(10, "oriented")
    if "metric" not in entry.reads:
        with pytest.raises(LightcutsError, match=rf"tree.metric: builder '{name}' reads no metric"):
            build_tree(lights, builder=name, metric="walter2008")
    if "c" not in entry.reads:
        with pytest.raises(LightcutsError, match=rf"tree.c: builder '{name}' reads no c"):
            build_tree(lights, builder=name, c=1.0)
    spec = tree_spec(name, "walter2005", 0.5, drop_unread=True)
    assert (spec.metric is not None) == ("metric" in entry.reads)
    assert (spec.c is not None) == spec.reads_c


def test_builtin_only_builders_refuse_a_user_metric(scratch_registries):
    @njit
    def perimeter(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
        return intensity * ((hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2))

    register_metric("test-perimeter", perimeter, uses_cone=False)
    strict = [e.name for e in BUILDERS.entries() if e.trait("builtin_metrics_only")]
    assert "agglomerative" in strict
    for name in strict:
        with pytest.raises(LightcutsError, match="needs a built-in metric"):
            tree_spec(name, "test-perimeter")
    with pytest.raises(LightcutsError, match="metric 'test-perimeter' has no cone term"):
        tree_spec("greedy", "test-perimeter", 1.0)
    assert tree_spec("greedy", "test-perimeter").metric.name == "test-perimeter"


def test_size_limit_names_the_builders_to_use():
    limited = [e for e in BUILDERS.entries() if e.trait("max_lights") is not None]
    assert [e.name for e in limited] == ["greedy"]
    spec = tree_spec("greedy")
    limit = limited[0].trait("max_lights")
    spec.check_size(limit)
    with pytest.raises(LightcutsError, match="at most 20,000 lights.*agglomerative"):
        spec.check_size(limit + 1)


# -------------------------------------------------------------------------------------- metrics

@pytest.mark.parametrize("name", METRICS.names())
def test_metric_contract(name):
    """Every metric is a Metric, reads c exactly when it has a cone term, and is finite and >= 0."""
    m = METRICS.get(name)
    assert isinstance(m, Metric) and m.name == name
    assert ("c" in METRICS.entry(name).reads) == m.uses_cone
    rng = np.random.default_rng(1)
    lo = rng.random((50, 3))
    hi = lo + rng.random((50, 3))
    v = metric_values(m, rng.random(50), lo, hi, rng.uniform(-1, 1, 50), True, 0.3)
    assert np.all(np.isfinite(v)) and np.all(v >= 0)


def test_a_bare_function_registers_as_a_metric(scratch_registries):
    @njit
    def f(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
        return intensity

    METRICS.register("test-bare", f)
    assert isinstance(METRICS.get("test-bare"), Metric)
    assert "test-bare" not in METRICS.names() or METRICS.get("test-bare").fn is f


def test_scratch_forgets_registrations():
    with BUILDERS.scratch():
        BUILDERS.register("test-gone", lambda *a: None, reads=())
        assert "test-gone" in BUILDERS
    assert "test-gone" not in BUILDERS


def test_registry_loads_builtins_on_first_listing():
    # In a fresh interpreter, so that no other test has imported the module already: a registry
    # imports its built-in modules on the first listing, not before. (divisive registers into
    # BUILDERS, not this registry: the listing stays empty, the import is what shows.)
    code = ("import sys\n"
            "from lightcuts.registry import Registry\n"
            "reg = Registry('builder', builtins=('lightcuts.trees.divisive',), params=('metric', 'c'))\n"
            "before = 'lightcuts.trees.divisive' in sys.modules\n"
            "names = reg.names()\n"
            "print(before, names, 'lightcuts.trees.divisive' in sys.modules)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["False", "[]", "True"]


def test_declared_parameters_are_checked():
    reg = Registry("builder", params=("metric", "c"))
    with pytest.raises(LightcutsError, match="unknown parameters"):
        reg.register("x", lambda: None, reads=("eps",))
    reg.register("y", declare(lambda: None, reads=("c",), max_lights=5))
    assert reg.entry("y").reads == {"c"} and reg.entry("y").trait("max_lights") == 5


# ------------------------------------------------------------------------------- the plan step

def _cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lightcuts", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


CONFIG = "scene: {builtin: cornell}\nlights: {direct: {count: 16}}\ncamera: {resolution: [8, 8]}\n"
PARAMETER_ERRORS = [
    (["tree", "run.yaml", "--builder", "divisive-3d", "--metric", "walter2008"],
     "", "--metric: builder 'divisive-3d' reads no metric"),
    (["tree", "run.yaml", "--builder", "divisive-3d", "--c", "2"], "", "--c: builder 'divisive-3d' reads no c"),
    (["render", "run.yaml"], "tree: {builder: divisive-3d, metric: walter2008}\n",
     "tree.metric: builder 'divisive-3d' reads no metric"),
    (["render", "run.yaml"], "tree: {builder: divisive-6d, metric: walter2005}\n",
     "tree.metric: builder 'divisive-6d' reads no metric"),
    (["render", "run.yaml"], "tree: {metric: surface-area, c: 3}\n", "tree.c: metric 'surface-area' has no cone term"),
    (["render", "run.yaml"], "render: {ray_caster: embreex}\n",
     "render.ray_caster: 'embreex' cannot be called from the render kernels"),
    (["render", "run.yaml"], "tree: {builder: greedy}\nlights: {direct: {count: 30000}}\n",
     "tree.builder: builder 'greedy' is a reference for at most 20,000 lights"),
    (["lights", "run.yaml"], "render: {ray_caster: nope}\n", "render.ray_caster: unknown ray caster 'nope'"),
]


@pytest.mark.parametrize("argv, extra, message", PARAMETER_ERRORS)
def test_parameter_errors_one_line_nothing_built(tmp_path, argv, extra, message):
    (tmp_path / "run.yaml").write_text(CONFIG + extra)
    r = _cli(*argv, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.yaml"]


def test_switching_builders_on_a_shipped_config_just_works(tmp_path):
    cfg = ROOT / "configs" / "cornell.yaml"
    r = _cli("tree", str(cfg), "--set", "lights.indirect.count=0", "--set", "lights.direct.count=64",
             "--set", "tree.builder=divisive-3d", "--out", str(tmp_path / "t.npz"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "builder divisive-3d:" in r.stdout and "metric" not in r.stdout


def test_user_metric_with_agglomerative_fails_in_the_plan(tmp_path):
    (tmp_path / "run.yaml").write_text(CONFIG + "tree: {metric: user-perimeter}\n")
    setup = textwrap.dedent("""
        from numba import njit
        from lightcuts.trees import register_metric

        @njit
        def perimeter(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
            return intensity * ((hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2))

        register_metric("user-perimeter", perimeter)
    """)
    rc, calls, err = cli_recording_work(["render", "run.yaml"], tmp_path, setup)
    assert (rc, calls) == (2, [])
    assert "needs a built-in metric" in err and len(err.strip().splitlines()) == 1


def test_the_recorder_sees_work(tmp_path):
    (tmp_path / "run.yaml").write_text(CONFIG)
    rc, calls, err = cli_recording_work(["tree", "run.yaml", "--out", "t.npz"], tmp_path)
    assert rc == 0 and calls == ["scene_from_config", "lights_from_config", "build_tree"], err


# --------------------------------------------------------------------------------- scene types

@pytest.mark.parametrize("name", SCENES.names())
def test_scene_type_contract(name, tmp_path):
    """Every scene type: declared parameters with defaults that pass their own checks, a
    ``resolution`` trait equal to the built scene's camera, emitters, and the same bytes twice."""
    from lightcuts.scene.loaders import load_mesh
    from lightcuts.scene.registry import make_scene

    entry = SCENES.entry(name)
    for p, decl in entry.params.items():
        assert decl.default is not None and decl.check(decl.default, p) == decl.default
    params = {p: max(decl.lo, 10_000) for p, decl in entry.params.items() if p == "triangles"}
    exhibits = offsets = []
    if entry.trait("exhibits"):
        obj = tmp_path / "t.obj"
        obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
        exhibits, offsets = [load_mesh(obj, 0.3, [0, 0, 0], [0, 0, 0], None)], [[0, 0, 0]]
    scenes = [make_scene({"type": name, **params}, None, exhibits, offsets, name="s") for _ in range(2)]
    cam = scenes[0].camera
    assert (cam.width, cam.height) == tuple(entry.trait("resolution"))
    assert len(scenes[0].emitters) > 0 and scenes[0].n_faces > 0
    a, b = (s.save(tmp_path / f"{i}.npz").read_bytes() for i, s in enumerate(scenes))
    assert a == b


# --------------------------------------------------------------------------------- integrators

@pytest.fixture(scope="module")
def small_cornell():
    """A 12 x 10 Cornell box run: its scene, caster, lights and trees, made by the plan's stages."""
    from lightcuts.pipeline.plan import plan_run

    cfg = lightcuts.load_config(ROOT / "configs" / "cornell.yaml", **{"camera.resolution": [12, 10],
                                                                      "lights.direct.count": 64,
                                                                      "lights.indirect.count": 300})
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        lights = plan.lights(scene, caster)
        yield cfg, scene, caster, lights, plan.trees(lights)


@pytest.mark.parametrize("name", INTEGRATORS.names())
def test_integrator_contract(name, small_cornell):
    """Every integrator, made from a config as the commands make it (make_integrator: the config's
    settings and the entry's declared defaults): an image of the window's size, finite, non-negative
    and lit, a cut per pixel within its bound (``max_cut`` per eye ray, in its ``cut_unit``); a crop
    window and a pixel list hold exactly those pixels of the whole image; its reference, where its
    ``reference`` trait says it has one, renders the same window (else asking for it is one line)."""
    from lightcuts.integrators.registry import Integrator, make_integrator

    cfg, scene, caster, lights, trees = small_cornell
    entry = INTEGRATORS.entry(name)
    assert entry.trait("cut_unit") and entry.trait("kernels") and isinstance(entry.trait("reference"), bool)
    integ = make_integrator(cfg.model_copy(update={"render": cfg.render.model_copy(update={"integrator": name})}))
    assert type(integ) is entry.obj and isinstance(integ, Integrator) and integ.spp == cfg.render.spp
    whole = integ.render(scene, caster, lights, trees)
    assert whole.image.shape == (10, 12, 3) and np.all(np.isfinite(whole.image)) and np.all(whole.image >= 0)
    assert whole.image.sum() > 0 and whole.cut_size.shape == (10, 12) and whole.eye_rays == 120 * integ.spp
    assert 0 <= whole.cut_size.min() and whole.cut_size.max() <= whole.max_cut * integ.spp
    crop = integ.render(scene, caster, lights, trees, crop=(3, 2, 9, 7))
    assert crop.image.tobytes() == whole.image[2:7, 3:9].tobytes()
    assert crop.cut_size.tobytes() == whole.cut_size[2:7, 3:9].tobytes()
    some = integ.render(scene, caster, lights, trees, pixels=[[11, 9], [0, 0], [5, 4]])
    assert some.image[:, 0].tobytes() == whole.image[[9, 0, 4], [11, 0, 5]].tobytes()
    if entry.trait("reference"):
        ref = integ.reference()
        assert ref.brute_force and not integ.brute_force
        result = ref.render(scene, caster, lights, None, crop=(3, 2, 9, 7))
        assert result.reference and result.image.shape == (5, 6, 3) and np.all(np.isfinite(result.image))
    else:
        with pytest.raises(LightcutsError, match="^render.integrator: .* has no brute-force reference$"):
            integ.reference()


#: (constructor keyword, a bad value, the config key its one-line error names), for the integrators
#: that take the keyword.
BAD_SETTINGS = [("spp", 0, "render.spp"), ("spp", 2.5, "render.spp"), ("eps", float("nan"), "render.eps"),
                ("eps", -0.1, "render.eps"), ("max_cut", 0, "render.max_cut"), ("max_cut", 1 << 21, "render.max_cut"),
                ("clamp_min_distance", -1.0, "render.clamp.min_distance"), ("clamp_vpls", -1.0, "render.clamp.vpls"),
                ("continuation_rays", 65, "render.continuation_rays"),
                ("representatives", "random", "render.representatives"), ("aperture", float("inf"), "camera.aperture"),
                ("focus_distance", 0.0, "camera.focus_distance")]


@pytest.mark.parametrize("name", INTEGRATORS.names())
def test_integrator_refuses_bad_settings_when_made(name):
    """An integrator checks what it is given when it is made, not when it renders: a bad setting or
    an own parameter out of its declared range (or not one of its choices) is one LightcutsError
    line naming the config key."""
    import inspect

    cls = INTEGRATORS.get(name)
    takes = inspect.signature(cls).parameters
    params = INTEGRATORS.entry(name).params
    own = [(p, decl.hi + 1 if decl.choices is None else "none of them", f"render.integrator.{p}")
           for p, decl in params.items()]
    cases = [c for c in BAD_SETTINGS if c[0] in takes and c[0] not in params] + own
    assert [c for c in cases if c[0] == "spp"] and all(p in takes for p, _, _ in own)
    for key, value, config_key in cases:
        with pytest.raises(LightcutsError) as e:
            cls(**{key: value})
        assert str(e.value).startswith(f"{config_key}: ") and "\n" not in str(e.value), (key, str(e.value))
    cls()  # the defaults are valid


def test_the_lightcuts_entry_is_render_image(small_cornell):
    from lightcuts.integrators.lightcut import render_image

    cfg, scene, caster, lights, trees = small_cornell
    a = INTEGRATORS.get("lightcuts")(eps=0.01).render(scene, caster, lights, trees, seed=3)
    b = render_image(scene, caster, lights, trees, eps=0.01, seed=3)
    assert a.image.tobytes() == b.image.tobytes() and np.array_equal(a.cut_size, b.cut_size)


# ------------------------------------------------------- one plugin shape: {type: NAME, param: value}

UNDECLARED = [  # (config addition, the key the one-line error names), a plugin of each kind
    ("tree: {builder: {type: agglomerative, leafsize: 4}}\n", "tree.builder.leafsize: builder 'agglomerative' has no"),
    ("tree: {builder: {type: divisive-3d, c: 2}}\n", "tree.builder.c: builder 'divisive-3d' reads no c"),
    ("render: {integrator: {type: lightcuts, bounces: 2}}\n",
     "render.integrator.bounces: integrator 'lightcuts' has no parameter 'bounces'"),
]


@pytest.mark.parametrize("command", ["render", "tree"])
@pytest.mark.parametrize("extra, message", UNDECLARED + [
    ("scene: {procedural: {type: kitchen, rooms: 2}}\n", "scene.procedural.rooms: scene type 'kitchen' has no")])
def test_undeclared_parameter_one_line_before_any_work(tmp_path, command, extra, message):
    text = CONFIG + extra if extra.startswith(("tree", "render")) else CONFIG.replace(
        "scene: {builtin: cornell}\n", extra)
    (tmp_path / "run.yaml").write_text(text)
    argv = [command, "run.yaml"] + (["--out", "t.npz"] if command == "tree" else [])
    rc, calls, err = cli_recording_work(argv, tmp_path)
    assert (rc, calls) == (2, []), err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {message}"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.yaml"]


@pytest.mark.parametrize("tree_section, message", [
    ("{builder: {type: agglomerative, c: 2}, c: 3}", "tree.c: given twice, also as tree.builder.c"),
    ("{builder: {type: agglomerative, metric: walter2005}, metric: walter2008}",
     "tree.metric: given twice, also as tree.builder.metric"),
    ("{builder: {type: agglomerative, c: 0}}", "tree.builder.c: 0.0 must be above 0"),
    ("{builder: {type: agglomerative, metric: 3}}", "tree.builder.metric: expected str"),
    ("{builder: {type: agglomerative, metric: nope}}", "tree.builder.metric: unknown metric 'nope'"),
    ("{builder: {type: nope}}", "tree.builder: unknown builder 'nope'"),
])
def test_builder_mapping_errors_name_the_key(tmp_path, tree_section, message):
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    (tmp_path / "run.yaml").write_text(CONFIG + f"tree: {tree_section}\n")
    with pytest.raises(LightcutsError) as e:
        plan_run(load_config(tmp_path / "run.yaml"))
    assert str(e.value).startswith(message) and "\n" not in str(e.value), str(e.value)


def test_builder_mapping_and_flat_form_give_the_same_tree(tmp_path):
    """``tree.builder: {type: agglomerative, metric: walter2005, c: 2}`` and the flat keys write the
    same tree file; a c of the default writes another."""
    from lightcuts.cli import main

    (tmp_path / "run.yaml").write_text(CONFIG)
    forms = {"nested": ["--set", "tree.builder={type: agglomerative, metric: walter2005, c: 2.0}"],
             "flat": ["--set", "tree.builder=agglomerative", "--set", "tree.metric=walter2005", "--set", "tree.c=2"],
             "default": ["--set", "tree.builder={type: agglomerative, metric: walter2005}"]}
    out = {}
    for name, sets in forms.items():
        assert main(["tree", str(tmp_path / "run.yaml"), "--out", str(tmp_path / f"{name}.npz"), *sets]) == 0
        out[name] = (tmp_path / f"{name}.npz").read_bytes()
    assert out["nested"] == out["flat"] != out["default"]


def test_compare_rows_come_from_builder_traits():
    from lightcuts.pipeline.comparing import default_builders

    rows = default_builders()
    assert rows == ["agglomerative-heap", "agglomerative", "divisive-6d", "divisive-3d", "saoh"]
    assert [b for b in BUILDERS.names() if BUILDERS.entry(b).trait("compare_baseline")] == ["divisive-6d"]
    with BUILDERS.scratch():
        BUILDERS.register("test-late", lambda *a: None, reads=(), compare_row=9)
        assert default_builders() == rows + ["test-late"]


def test_plan_records_every_plugin(tmp_path):
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    (tmp_path / "run.yaml").write_text("scene: {procedural: {type: rooms, rooms: 2}}\n"
                                       "tree: {builder: {type: divisive-6d, c: 0.5}}\n")
    assert plan_run(load_config(tmp_path / "run.yaml")).record() == {
        "scene": {"type": "rooms", "rooms": 2, "seed": 0, "triangles": 100_000},
        "builder": {"type": "divisive-6d", "c": 0.5},
        "ray_caster": {"type": "embree"},
        "integrator": {"type": "lightcuts"}}
