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

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba.core.dispatcher import Dispatcher

from lightcuts.cluster.dissimilarity import (SURFACE_AREA, WALTER2005, WALTER2008, metric_eval,  # noqa: F401
                                             surface_area, walter2005, walter2008)
from lightcuts.errors import LightcutsError
from lightcuts.trees.registry import METRICS

USER_METRIC_ID = -1

_BUILTIN_FN = {WALTER2008: walter2008, WALTER2005: walter2005, SURFACE_AREA: surface_area}


@dataclass(frozen=True)
class Metric:
    """A clustering metric.

    name : registry name
    id : built-in id for :func:`metric_eval` (WALTER2008, WALTER2005, SURFACE_AREA), or
        ``USER_METRIC_ID`` for a user metric
    uses_cone : whether the metric has a cone term (only used for oriented lights)
    description : one line, with the formula
    fn : njit function ``fn(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)``; filled
        in for built-ins (the same code metric_eval runs), required for user metrics
    """

    name: str
    id: int
    uses_cone: bool
    description: str
    fn: Callable | None = None

    def __post_init__(self):
        if self.id in _BUILTIN_FN:
            if self.fn is None:
                object.__setattr__(self, "fn", _BUILTIN_FN[self.id])
        elif self.id != USER_METRIC_ID:
            raise ValueError(f"metric {self.name!r}: id {self.id} is neither built-in nor USER_METRIC_ID")
        if not isinstance(self.fn, Dispatcher):
            raise LightcutsError(f"metric {self.name!r}: fn must be an @numba.njit function "
                                 f"fn(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)")

    @property
    def reads(self) -> tuple[str, ...]:
        """The run parameters the metric uses: ``c`` with a cone term (the registry reads this)."""
        return ("c",) if self.uses_cone else ()

    @property
    def builtin(self) -> bool:
        """Whether kernels may call ``metric_eval(self.id, ...)`` instead of ``self.fn``."""
        return self.id >= 0


def register_metric(name: str, fn: Callable, *, uses_cone: bool = True, description: str = "",
                    aliases: tuple[str, ...] = (), replace: bool = False) -> Metric:
    """Register a user metric ``fn`` (an njit function, see the module docstring) under ``name``."""
    metric = as_metric(fn, name, uses_cone=uses_cone, description=description)
    METRICS.register(name, metric, aliases=aliases, replace=replace)
    return metric


def as_metric(obj, name: str, *, uses_cone: bool = True, description: str = "") -> Metric:
    """A :class:`Metric` from a registry entry: a Metric as is, an njit function as a user metric.

    Entry points may name either; anything else is a LightcutsError naming the metric.
    """
    if isinstance(obj, Metric):
        return obj
    if isinstance(obj, Dispatcher):
        return Metric(name, USER_METRIC_ID, uses_cone, description or f"user metric {obj.py_func.__qualname__}", obj)
    raise LightcutsError(
        f"metric {name!r}: expected a Metric or an @numba.njit function "
        f"fn(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c), got {type(obj).__name__}")


def metric_values(metric: Metric, intensity: np.ndarray, lo: np.ndarray, hi: np.ndarray, cone_cos: np.ndarray,
                  has_cone: bool, c: float) -> np.ndarray:
    """(K,) float64 metric of K clusters through ``metric.fn`` (for analysis and tests; builders use kernels).

    intensity : (K,) scalar intensities; lo, hi : (K, 3) boxes; cone_cos : (K,)
    """
    return np.array([metric.fn(float(intensity[k]), *map(float, lo[k]), *map(float, hi[k]), float(cone_cos[k]),
                               bool(has_cone), float(c)) for k in range(len(intensity))])


METRICS.register("walter2008", Metric(
    "walter2008", WALTER2008, True,
    "I (L^2 + c^2 S^2)^2, S = sine of the cone half-angle (1 past 90 degrees); Walter et al. 2008, eq. 2"))
METRICS.register("walter2005", Metric(
    "walter2005", WALTER2005, True, "I (L^2 + c^2 (1 - cos beta)^2); Walter et al. 2005"))
METRICS.register("surface-area", Metric(
    "surface-area", SURFACE_AREA, False, "surface area of the union box; the 2008 paper's BVH metric"),
    aliases=("sah",))
