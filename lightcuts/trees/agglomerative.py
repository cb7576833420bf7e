r"""Fast agglomerative light-tree builders (Walter, Bala, Kulkarni, Pingali 2008): ``agglomerative``
(locally-ordered clustering, Fig. 4, in rounds on the threads) and ``agglomerative-heap`` (the
heap-based version, Fig. 3).

Both are the clustering engine of :mod:`lightcuts.cluster.agglomerate` run on the lights: each light a
cluster whose box is its position (the box of unit directions for directional lights), its box of
normals its normal, its intensity its luminance, under a built-in metric of
:mod:`lightcuts.trees.metrics` (the engine's dissimilarities). With a non-decreasing metric both
build the greedy tree (Fig. 2) up to ties; with box-of-normals cones the metric is not monotone, and
the tree may differ from the greedy one in a few clusters (docs/math.md, "Non-decreasing metrics";
``benchmarks/bench_agglomerative.py`` measures how many).

Node ids of the returned topology: leaves 0..N-1 are lights 0..N-1, merge m makes node N + m, the
root is 2N - 2.
"""

from __future__ import annotations

import numpy as np

from lightcuts.cluster.agglomerate import PARALLEL_MIN, agglomerate
from lightcuts.cluster.kd_tree import LEAF_SIZE
from lightcuts.errors import LightcutsError
from lightcuts.trees.metric_type import Metric
from lightcuts.trees.registry import BUILDERS


def _arguments(position, normal, luminance, light_type: str, metric: Metric, c: float, name: str):
    """The kernels' arguments, in the one dtype combination they are compiled for."""
    if not getattr(metric, "builtin", False):
        raise LightcutsError(f"builder {name!r}: metric {metric.name!r} is a user metric; the kd-tree search "
                             "needs a lower bound, available for the built-in metrics only "
                             "(walter2008, walter2005, surface-area); use builder 'greedy' instead")
    position = np.ascontiguousarray(position, np.float64)
    normal = np.ascontiguousarray(normal, np.float64)
    luminance = np.ascontiguousarray(luminance, np.float64)
    if len(position) == 0:
        raise LightcutsError(f"builder {name!r}: no lights")
    has_cone = light_type == "oriented"
    return position, normal, luminance, int(metric.id), has_cone, bool(has_cone and metric.uses_cone), float(c)


def agglomerative_stats(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int,
                        heap: bool = False, leafsize: int = LEAF_SIZE, parallel_min: int = PARALLEL_MIN):
    """Either builder with its work counters: ``(left, right, light, root, stats)``.

    stats : dict with ``searches`` (kd-tree findBestMatch searches) and, for the locally-ordered
    builder, ``rounds``, for the heap builder ``stale`` (entries skipped because their cluster was
    gone).
    leafsize : clusters per kd leaf; parallel_min : the smallest round searched on several threads
    (tuning knobs: the tree depends on neither, except among ties for the leaf size)
    seed : unused (both are deterministic)
    """
    if int(leafsize) < 1:
        raise ValueError(f"leafsize must be >= 1, got {leafsize}")
    name = "agglomerative-heap" if heap else "agglomerative"
    position, normal, luminance, metric_id, has_cone, use_cone, c = _arguments(
        position, normal, luminance, light_type, metric, c, name)
    return agglomerate(position, position, normal, luminance, metric_id, has_cone, use_cone, c, heap=heap,
                       leafsize=leafsize, parallel_min=parallel_min,
                       what=(f"builder {name!r}", "check the lights' and tree.c's magnitudes"))


@BUILDERS.register("agglomerative", reads=("metric", "c"), builtin_metrics_only=True, compare_row=2)
def agglomerative(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int):
    """Locally-ordered agglomerative clustering (Walter et al. 2008, Fig. 4): mutual best matches merge in rounds.

    position, normal : (N, 3) float64; luminance : (N,) float64 scalar intensity
    light_type : "omni", "oriented" (the only type with a cone term) or "directional"
    metric : a built-in Metric; c : cone-term scale, world units; seed : unused (deterministic)
    Returns ``(left, right, light, root)`` over 2N-1 nodes (leaves 0..N-1, root 2N-2).
    """
    return agglomerative_stats(position, normal, luminance, light_type, metric, c, seed)[:4]


@BUILDERS.register("agglomerative-heap", reads=("metric", "c"), builtin_metrics_only=True, compare_row=1)
def agglomerative_heap(position, normal, luminance, light_type: str, metric: Metric, c: float, seed: int):
    """Heap-based agglomerative clustering (Walter et al. 2008, Fig. 3): a lazy min-heap of best matches.

    Same arguments and result as :func:`agglomerative`.
    """
    return agglomerative_stats(position, normal, luminance, light_type, metric, c, seed, heap=True)[:4]
