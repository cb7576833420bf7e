"""The ray-caster interface and registry."""

from __future__ import annotations

import numpy as np

from lightcuts.registry import Registry

RAY_CASTERS: Registry = Registry("ray caster", group="lightcuts.ray_casters")


class RayCaster:
    """Closest hit and occlusion over a triangle mesh.

    All arrays: org, dirs (n, 3) float64 (dirs need not be unit: t is in units of |dir|);
    tnear, tfar (n,) float64 (tfar may be inf).
    """

    #: (intersect1, occluded1, scene_handle) for per-ray calls from numba kernels, or None.
    kernel_handles = None

    def intersect(self, org, dirs, tnear, tfar) -> tuple[np.ndarray, np.ndarray]:
        """Closest hit with t in (tnear, tfar]: (t (n,) float64, inf on a miss; prim (n,) int32, -1 on a miss)."""
        raise NotImplementedError

    def occluded(self, org, dirs, tnear, tfar) -> np.ndarray:
        """(n,) bool: True where some triangle is hit with t in [tnear, tfar]."""
        raise NotImplementedError


def make_caster(scene, name: str = "embree") -> RayCaster:
    """Build the ray caster ``name`` over ``scene`` (a Scene, or a (vertices, faces) pair)."""
    import lightcuts.accel.embree  # noqa: F401  (registers the built-in casters)

    if isinstance(scene, tuple):
        vertices, faces = scene
    else:
        vertices, faces = scene.vertices, scene.faces
    return RAY_CASTERS.get(name)(np.asarray(vertices), np.asarray(faces))
