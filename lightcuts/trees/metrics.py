r"""Clustering metrics: the cost of merging two clusters into C = A u B (smaller merges first).

Built-in metrics (registered in ``lightcuts.trees.registry.METRICS``; their kernels are the clustering
engine's built-in dissimilarities, :mod:`lightcuts.cluster.dissimilarity`), with I = C's scalar intensity
(luminance of its summed RGB), L = the diagonal of C's spatial box, beta = C's cone half-angle and
c = the cone-term scale (scene diagonal / 16 by default):

=================  ==  =====================================================================
name               id  d(C)
=================  ==  =====================================================================
``walter2008``     0   I (L^2 + c^2 S^2)^2, S = sin(beta), 1 when beta >= 90 degrees (default)
``walter2005``     1   I (L^2 + c^2 (1 - cos beta)^2)
``surface-area``   2   surface area of C's box (the 2008 paper's BVH metric; alias ``sah``)
=================  ==  =====================================================================

Omni and directional lights have no cone term (``has_cone`` False): walter2008 is then I L^4 and
walter2005 I L^2. L^2 is the box's squared diagonal, the sum of its squared extents. The 2008 paper
prints eq. 2's cone term as c^2 (1 - S)^2, which falls as the cone widens; c^2 S^2 is the reading
that agrees with its eq. 1 (docs/math.md, "Reading eq. 2 with S^2").

User metrics
------------
A user metric is an ``@numba.njit`` function with :func:`metric_eval`'s signature minus
``metric_id``::

    @njit
    def my_metric(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
        return intensity * ((hi0 - lo0) + (hi1 - lo1) + (hi2 - lo2))

    register_metric("my-metric", my_metric, uses_cone=False, description="I times box perimeter")

or, from another package, an entry point in group ``lightcuts.metrics`` naming such a function or a
:class:`Metric`. It gets ``id = USER_METRIC_ID`` (-1). Every Metric has such an ``fn`` (built-ins
too: the code metric_eval runs), which the ``greedy`` builder calls through a first-class function
argument (one cached kernel for every metric). Builders that need a lower bound of the metric (the
kd-tree of ``agglomerative``) accept built-in metrics only; the divisive builders read no metric.
"""

from __future__ import annotations

from typing import Callable

from lightcuts.cluster.dissimilarity import SURFACE_AREA, WALTER2005, WALTER2008, metric_eval  # noqa: F401
from lightcuts.trees.metric_type import USER_METRIC_ID, Metric, as_metric, metric_values  # noqa: F401
from lightcuts.trees.registry import METRICS


def register_metric(name: str, fn: Callable, *, uses_cone: bool = True, description: str = "",
                    aliases: tuple[str, ...] = (), replace: bool = False) -> Metric:
    """Register a user metric ``fn`` (an njit function, see the module docstring) under ``name``."""
    metric = as_metric(fn, name, uses_cone=uses_cone, description=description)
    METRICS.register(name, metric, aliases=aliases, replace=replace)
    return metric


METRICS.register("walter2008", Metric(
    "walter2008", WALTER2008, True,
    "I (L^2 + c^2 S^2)^2, S = sine of the cone half-angle (1 past 90 degrees); Walter et al. 2008, eq. 2"))
METRICS.register("walter2005", Metric(
    "walter2005", WALTER2005, True, "I (L^2 + c^2 (1 - cos beta)^2); Walter et al. 2005"))
METRICS.register("surface-area", Metric(
    "surface-area", SURFACE_AREA, False, "surface area of the union box; the 2008 paper's BVH metric"),
    aliases=("sah",))
