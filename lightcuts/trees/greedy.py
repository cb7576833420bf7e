r"""The ``greedy`` builder: the reference agglomerative clustering (Walter et al. 2008, Fig. 2).

The clustering engine's greedy oracle (:mod:`lightcuts.cluster.greedy`) run on the lights: each
light a cluster with its position as its box, its normal and its luminance, the registered metric
as the cost (user metrics included). Globally cheapest pair first, ties to the smaller cluster id,
then the larger one; O(N^2) for typical inputs, so at most ``GREEDY_MAX_LIGHTS`` lights.
"""

from __future__ import annotations

import numpy as np

from lightcuts.cluster.greedy import greedy_cluster
from lightcuts.trees.registry import BUILDERS

#: The largest light set ``greedy`` accepts: it is O(N^2) (seconds at this size, hours at 10^5).
GREEDY_MAX_LIGHTS = 20000


@BUILDERS.register("greedy", reads=("metric", "c"), max_lights=GREEDY_MAX_LIGHTS)
def greedy(position, normal, luminance, light_type, metric, c, seed):
    """Reference builder: globally cheapest pair first (O(N^2)); any metric, user metrics included."""
    has_cone = light_type == "oriented" and metric.uses_cone
    position = np.ascontiguousarray(position, np.float64)
    left, right, light = greedy_cluster(metric.fn, has_cone, c, position, position, normal, luminance)
    return left, right, light, 2 * len(position) - 2
