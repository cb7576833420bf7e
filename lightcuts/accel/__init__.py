"""Ray casting: closest hit and occlusion with per-ray tmin/tmax, Embree as the backend.

Ray casters are a registry (name -> factory taking ``(vertices (V,3), faces (F,3))``):

- ``embree``: numba kernels calling the libembree4 that the embreex wheel ships, through ctypes
  (both cores; per-ray calls usable inside other numba kernels via ``kernel_handles``);
- ``embreex``: embreex's batch ``scene.run`` (one core, tnear emulated by offsetting origins).
"""

from lightcuts.accel.base import RAY_CASTERS, RayCaster, make_caster

__all__ = ["RAY_CASTERS", "RayCaster", "make_caster"]
