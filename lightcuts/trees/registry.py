"""The builder and metric registries (see :mod:`lightcuts.registry`).

A builder is a function

    builder(position (N,3) float64, normal (N,3) float64, luminance (N,) float64,
            light_type: str, metric: Metric | None, c: float | None, seed: int)
        -> (left (2N-1,) int32, right (2N-1,) int32, light (2N-1,) int32, root: int)

that returns only the topology; ``lightcuts.trees.build.build_tree`` then computes every node's box,
cone, summed intensity and representative the same way for all builders. A builder declares what it
reads: ``metric`` (a clustering metric; with the trait ``builtin_metrics_only`` if its kernels need a
built-in metric's lower bound) and ``c`` (the cone-term scale); it receives None for what it does not
read. The trait ``max_lights`` bounds the light sets it accepts (the O(N^2) reference). For
``lightcuts compare``: ``compare_row`` (an int) puts a builder in the default rows, in that order
(the 2008 paper's Fig. 8), and ``compare_baseline`` marks the row the cut sizes are divided by.

A metric entry's object is always a :class:`~lightcuts.trees.metric_type.Metric` (an njit function
registered or named by an entry point is wrapped); it reads ``c`` when it has a cone term.

Outside packages add builders through the entry-point group ``lightcuts.builders`` (with
:func:`lightcuts.registry.declare` on the function; undeclared builders read both parameters),
metrics through ``lightcuts.metrics``, or at run time with ``BUILDERS.register("name", fn, reads=...)``.
"""

from __future__ import annotations

from lightcuts.config.schema import DEFAULT_METRIC
from lightcuts.limits import MAX_COORD
from lightcuts.registry import Param, Registry


def _as_metric(name, obj):
    from lightcuts.trees.metric_type import as_metric

    return as_metric(obj, name)


#: The parameters builders read (``reads=`` picks from them): a config gives them flat (``tree.metric``,
#: ``tree.c``) or in the builder's mapping (``tree.builder: {type: agglomerative, metric: ..., c: ...}``).
BUILDER_PARAMS = {
    "metric": Param(str, DEFAULT_METRIC, doc="the clustering metric (a METRICS name)"),
    "c": Param(float, None, above=0, hi=MAX_COORD,
               doc="the cone-term scale; None: the scene diagonal / 16 (larger values would overflow the metric)"),
}

BUILDERS: Registry = Registry(
    "builder", group="lightcuts.builders",
    builtins=("lightcuts.trees.divisive", "lightcuts.trees.greedy", "lightcuts.trees.agglomerative",
              "lightcuts.trees.saoh"),
    params=BUILDER_PARAMS, default_reads=("metric", "c"))
METRICS: Registry = Registry("metric", group="lightcuts.metrics", builtins=("lightcuts.trees.metrics",),
                             params=("c",), coerce=_as_metric)


def get_builder(name: str):
    """The builder function registered as ``name``."""
    return BUILDERS.get(name)


def get_metric(name: str):
    """The :class:`~lightcuts.trees.metrics.Metric` registered as ``name``."""
    return METRICS.get(name)
