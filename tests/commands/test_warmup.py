"""The warm-up children compile the very specialisations the run then calls."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# On an empty cache: start the tree child as the render command does and wait for it.
_WARM = textwrap.dedent("""
    import sys
    from lightcuts.config import load_config
    from lightcuts.commands.plan import plan_run
    from lightcuts.commands.warmup import config_light_types, finish_warmup, start_tree_warmup
    cfg = load_config(sys.argv[1], sys.argv[2:])
    child = start_tree_warmup(plan_run(cfg).tree, config_light_types(cfg))
    finish_warmup(child)
    print(child.returncode)
""")

# In a fresh process on the cache the child filled: lights from the config (their kernels may
# compile), then the trees, counting every lightcuts kernel numba compiles while they are built.
_BUILD_AND_COUNT = textwrap.dedent("""
    import sys
    from numba.core import event
    from lightcuts.config import load_config
    from lightcuts.commands.plan import plan_run
    cfg = load_config(sys.argv[1], sys.argv[2:])
    plan = plan_run(cfg)
    scene = plan.scene()
    lights = plan.lights(scene)
    compiled = []
    class L(event.Listener):
        def on_start(self, ev):
            compiled.append(ev.data["dispatcher"].py_func.__module__ + "." + ev.data["dispatcher"].py_func.__name__)
        def on_end(self, ev):
            pass
    event.register("numba:compile", L())
    trees = plan.trees(lights)
    assert sum(len(t.left) for t in trees.values()) > 0
    print([c for c in compiled if c.startswith("lightcuts.")])
""")


@pytest.mark.slow
@pytest.mark.parametrize("config, overrides", [
    ("cornell.yaml", ["lights.indirect.count=3000", "lights.direct.count=256"]),
    ("sun-env.yaml", ["lights.environment.count=512"])])
def test_tree_warmup_child_compiles_what_the_build_calls(tmp_path, config, overrides):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    args = [str(ROOT / "configs" / config), *overrides]
    r = subprocess.run([sys.executable, "-c", _WARM, *args], env=env, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "0"  # the child ran and succeeded
    r = subprocess.run([sys.executable, "-c", _BUILD_AND_COUNT, *args], env=env,
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "[]"


def test_light_types_of_a_config():
    from lightcuts.commands.warmup import config_light_types
    from lightcuts.config import load_config

    assert config_light_types(load_config(ROOT / "configs" / "cornell.yaml")) == ["oriented"]
    assert "directional" in config_light_types(load_config(ROOT / "configs" / "sun-env.yaml"))
    assert config_light_types(load_config(ROOT / "configs" / "cornell.yaml",
                                          ["lights.direct.count=0", "lights.indirect.count=0",
                                           "lights.sun={direction: [0, 1, 0], irradiance: [1, 1, 1]}"])) \
        == ["directional"]
