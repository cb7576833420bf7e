"""The builder and metric registries.

A builder is a function

    builder(position (N,3) float64, normal (N,3) float64, luminance (N,) float64,
            light_type: str, metric: Metric, c: float, seed: int)
        -> (left (2N-1,) int32, right (2N-1,) int32, light (2N-1,) int32, root: int)

that returns only the topology; ``lightcuts.trees.build.build_tree`` then computes every node's
box, cone, summed intensity and representative the same way for all builders.

Outside packages add builders without editing lightcuts, through the entry-point group
``lightcuts.builders`` (an entry point names the builder function), or at run time with
``BUILDERS.register("name", fn)``. Metrics likewise (group ``lightcuts.metrics``).
"""

from __future__ import annotations

import importlib

from lightcuts.registry import Registry

BUILDERS: Registry = Registry("builder", group="lightcuts.builders")
METRICS: Registry = Registry("metric", group="lightcuts.metrics")

# Modules whose import registers the built-in builders and metrics.
_BUILTIN_MODULES = ("lightcuts.trees.metrics", "lightcuts.trees.divisive", "lightcuts.trees.greedy",
                    "lightcuts.trees.agglomerative")
_loaded = False


def load_builtins() -> None:
    """Import the built-in builder and metric modules once (they register themselves)."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in _BUILTIN_MODULES:
        importlib.import_module(mod)


def get_builder(name: str):
    load_builtins()
    return BUILDERS.get(name)


def get_metric(name: str):
    load_builtins()
    return METRICS.get(name)
