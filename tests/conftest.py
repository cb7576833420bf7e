"""Fixtures shared by the test modules: small light sets, thread counts, scratch registries."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from lightcuts.lights import LightSet
from lightcuts.parallel import num_threads

#: The thread counts a determinism test compares: one, and two where the machine has them.
MAX_THREADS = numba.config.NUMBA_NUM_THREADS


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_lights(n, light_type, seed=0, duplicates=False):
    """n lights of one type in a unit box; duplicates: every position (and normal) appears twice."""
    rng = np.random.default_rng(seed)
    m = (n + 1) // 2 if duplicates else n
    pos = rng.random((m, 3))
    nrm = unit(rng.normal(size=(m, 3)))
    if duplicates:
        pos, nrm = np.repeat(pos, 2, axis=0)[:n], np.repeat(nrm, 2, axis=0)[:n]
    if light_type == "directional":
        pos = nrm.copy()
    if light_type != "oriented":
        nrm = np.zeros_like(pos)
    return LightSet(pos, nrm, rng.random((n, 3)) * [1.0, 2.0, 0.5], light_type)


@pytest.fixture
def scratch_registries():
    """Builders, metrics, ray casters, scene types, integrators and reference renderers registered in a
    test are forgotten after it."""
    from lightcuts.accel import RAY_CASTERS
    from lightcuts.integrators.references import REFERENCES
    from lightcuts.integrators.registry import INTEGRATORS
    from lightcuts.scene.registry import SCENES
    from lightcuts.trees import BUILDERS, METRICS

    with BUILDERS.scratch(), METRICS.scratch(), RAY_CASTERS.scratch(), SCENES.scratch(), INTEGRATORS.scratch(), \
            REFERENCES.scratch():
        yield


@pytest.fixture
def thread_counts():
    """(1, 2) and the :func:`lightcuts.parallel.num_threads` context manager; skips on one thread."""
    if MAX_THREADS < 2:
        pytest.skip("needs two numba threads to compare one against two")
    return (1, 2), num_threads


@pytest.fixture
def stage_calls(monkeypatch):
    """The names of the stage functions called in this process, in order (a scene, lights, a tree
    made): a call that leaves the list empty did no work."""
    import lightcuts.lights.generate
    import lightcuts.scene.build
    import lightcuts.trees.build

    calls = []
    for module, name in ((lightcuts.scene.build, "scene_from_config"),
                         (lightcuts.lights.generate, "lights_from_config"),
                         (lightcuts.trees.build, "build_tree")):
        fn = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _fn=fn, _name=name, **k: (calls.append(_name), _fn(*a, **k))[1])
    return calls


_RECORDING = """
import json, sys
import lightcuts.scene.build, lightcuts.lights.generate, lightcuts.trees.build
calls = []
def recording(module, name):
    fn = getattr(module, name)
    def wrapper(*args, **kwargs):
        calls.append(name)
        return fn(*args, **kwargs)
    setattr(module, name, wrapper)
recording(lightcuts.scene.build, "scene_from_config")
recording(lightcuts.lights.generate, "lights_from_config")
recording(lightcuts.trees.build, "build_tree")
{setup}
from lightcuts.cli import main
rc = main(json.loads(sys.argv[1]))
print(json.dumps([rc, calls]))
"""


def cli_recording_work(argv, cwd, setup=""):
    """Run ``lightcuts ARGV`` in a fresh process that records whether a scene, lights or a tree were
    made: returns (exit code, [names of the stage functions called], stderr)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    import lightcuts

    env = dict(os.environ, PYTHONPATH=str(Path(lightcuts.__file__).parents[1]))
    r = subprocess.run([sys.executable, "-c", _RECORDING.replace("{setup}", setup), json.dumps(list(argv))],
                       cwd=cwd, capture_output=True, text=True, env=env, timeout=300)
    assert r.stdout.strip(), r.stderr
    rc, calls = json.loads(r.stdout.strip().splitlines()[-1])
    return rc, calls, r.stderr


#: Names whose use in a test's body starts a process (the CLI or a fresh interpreter): such a test
#: is marked ``slow`` (``pytest -m "not slow"`` is the quick loop).
_SPAWNING = {"subprocess", "run_cli", "_cli", "cli_recording_work", "_loaded_after_import"}
#: Tests slow for their own work (large scenes, many builds), by name.
_SLOW_BY_NAME = {"test_coplanar_piles_terminate_for_every_structure",
                 "test_resume_skips_finished_rows_and_recomputes_changed_ones",
                 "test_objects_referenced_by_exactly_the_voxels_their_box_overlaps"}


def _names(code) -> set[str]:
    """The global and attribute names a code object uses, with those of its nested code (lambdas,
    comprehensions)."""
    out = set(code.co_names)
    for c in code.co_consts:
        if hasattr(c, "co_names"):
            out |= _names(c)
    return out


def pytest_collection_modifyitems(config, items):
    for item in items:
        fn = getattr(item, "function", None)
        if fn is None:
            continue
        if fn.__name__ in _SLOW_BY_NAME or _SPAWNING & _names(fn.__code__):
            item.add_marker(pytest.mark.slow)
