"""The clustering-metric type: :class:`Metric` and :func:`as_metric` (entries of
``lightcuts.trees.registry.METRICS`` are always Metrics). A module that registers nothing, so the
registry can coerce its entries without importing the built-in registrations
(:mod:`lightcuts.trees.metrics`, which documents the metrics)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba.core.dispatcher import Dispatcher

from lightcuts.cluster.dissimilarity import SURFACE_AREA, WALTER2005, WALTER2008, surface_area, walter2005, walter2008
from lightcuts.errors import LightcutsError

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
