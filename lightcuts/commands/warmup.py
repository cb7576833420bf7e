"""numba on the commands' side: a notice when kernels first compile, and kernels compiled on the side.

On an empty cache a render spends most of its time compiling kernels (``cache=True``: later runs
load them), one kernel at a time (numba compiles under one lock per process). So the commands
compile in child processes what they need later while this process traces the lights: the tree
builder's kernels (:func:`start_tree_warmup`, a tree over a few thousand random lights of each type)
and the render kernel (:func:`start_render_warmup`, one pixel, the ``_render_band`` of the
integrator's ``kernels`` module); :func:`finish_warmup` waits for a child before its kernels are
first called, which then load from the cache. Correct however a child
ends: the cache is a cache (numba writes each entry atomically), so a child that failed, was killed
or found no writable cache only leaves this process to compile those kernels itself.
"""

from __future__ import annotations

import os
import subprocess
import sys

#: The child: on Linux it asks to be killed with its parent (a command stopped by a signal exits at
#: once), then compiles the render kernel.
_CHILD = """
try:
    import ctypes, signal
    ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
except Exception:
    pass
import importlib, sys
importlib.import_module(sys.argv[1]).warm_kernels()
"""

#: The tree child: killed with its parent as :data:`_CHILD` is, then builds a tree over random lights of each given type
#: with the builder, metric and c given as JSON in argv[1] (the kernels' types are those of every
#: build; 4,096 lights take the builders' general paths, not their few-light shortcuts).
_CHILD_TREES = _CHILD.split("import importlib")[0] + """
import json, sys
import numpy as np
from lightcuts.lights.lightset import LightSet
from lightcuts.trees.build import build_tree
from lightcuts.trees.spec import tree_spec
a = json.loads(sys.argv[1])
spec = tree_spec(a["builder"], a["metric"], a["c"])
rng = np.random.default_rng(0)
for typ in a["types"]:
    normal = rng.normal(size=(4096, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    position = normal.copy() if typ == "directional" else rng.random((4096, 3))
    build_tree(LightSet(position, normal if typ == "oriented" else np.zeros_like(normal),
                        rng.random((4096, 3)) + 0.1, typ), spec, seed=0)
"""

#: Longest wait for the child before the render compiles the kernel itself, seconds.
WARMUP_TIMEOUT = 600.0


_ANNOUNCING = False
NOTICE = ("compiling numba kernels once (light tracing, tree builder, renderer: about half a minute on 2 cores); "
          "later runs load them from the cache")


def announce_compiles() -> None:
    """Print :data:`NOTICE` to stderr once, when numba first compiles a kernel in this process (not
    on cache hits: numba's ``numba:compile`` event fires on cache misses only)."""
    global _ANNOUNCING
    if _ANNOUNCING:
        return
    _ANNOUNCING = True
    from numba.core import event

    class Once(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                print(NOTICE, file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    event.register("numba:compile", Once())


def is_cached(dispatcher) -> bool:
    """Whether numba's cache holds a compiled version of the current source of ``dispatcher``
    (a ``cache=True`` kernel; True when that cannot be told, e.g. caching disabled)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # numba internals differ, no cache: do not claim the cache is cold
        return True


def _start_child(code: str, *args: str) -> subprocess.Popen | None:
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in [env.get("PYTHONPATH")] if p])
    try:
        return subprocess.Popen([sys.executable, "-c", code, *args], env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None


def start_render_warmup(kernels: str | None = "lightcuts.render.integrator") -> subprocess.Popen | None:
    """If the render kernel is not in the cache, start a child process that compiles it (and writes
    it to the cache) by rendering one pixel of a small scene; None if it is cached, ``kernels`` is
    None or the child cannot start.

    kernels : the module of the render kernel ``_render_band`` and of ``warm_kernels()``, which
        compiles it (an integrator's ``kernels`` trait)
    """
    import importlib

    if kernels is None or is_cached(importlib.import_module(kernels)._render_band):
        return None
    return _start_child(_CHILD, kernels)


def start_tree_warmup(spec, light_types) -> subprocess.Popen | None:
    """If the tree kernels are not in the cache, start a child process that compiles those of
    ``spec`` (a TreeSpec) by building trees over random lights of each of ``light_types``; None if
    they are cached, the metric is not a registered one (the child could not name it), or the child
    cannot start. The fill kernel every builder calls stands for the builder's own kernels in the
    cache check (a run with a builder not used before compiles that builder's kernels itself)."""
    import json

    from lightcuts.trees.fill import _fill_ranges
    from lightcuts.trees.registry import METRICS

    if is_cached(_fill_ranges) or not light_types:
        return None
    metric = spec.metric.name if spec.metric is not None else None
    if metric is not None and (metric not in METRICS or METRICS.get(metric) is not spec.metric):
        return None
    return _start_child(_CHILD_TREES, json.dumps({"builder": spec.name, "metric": metric, "c": spec.c,
                                                  "types": sorted(light_types)}))


def finish_warmup(proc: subprocess.Popen | None, timeout: float = WARMUP_TIMEOUT) -> None:
    """Wait for a child of :func:`start_render_warmup` or :func:`start_tree_warmup` (None: nothing to do); after ``timeout``
    seconds it is killed, and the caller compiles what it needs itself."""
    if proc is None:
        return
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        pass
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def config_light_types(cfg) -> list[str]:
    """The light types a run config asks for (as lightcuts.lights.generate makes them)."""
    lc = cfg.lights
    types = []
    if lc.direct.count > 0 or lc.indirect.count > 0:
        types.append("oriented")
    if lc.sun is not None or (lc.environment is not None and lc.environment.count > 0):
        types.append("directional")
    return types
