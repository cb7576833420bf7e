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
from lightcuts.trees import BUILDERS, METRICS, Metric, build_tree, register_metric, tree_spec, validate_tree
from lightcuts.trees.metrics import metric_values

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
    reg = Registry("builder", builtins=("lightcuts.trees.divisive",), params=("metric", "c"))
    # divisive registers into BUILDERS, not this registry: it only shows the module was imported
    assert reg.names() == [] and "lightcuts.trees.divisive" in sys.modules


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
