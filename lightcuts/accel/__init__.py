"""Ray casting: closest hit and occlusion with per-ray tnear/tfar.

Ray casters are a registry (:mod:`lightcuts.accel.registry`; name -> class taking
``(vertices (V,3), faces (F,3))``):

- ``embree``: numba kernels calling the libembree4 that the embreex wheel ships, through ctypes
  (both cores; per-ray calls usable inside other numba kernels via ``kernel_handles``);
- ``embreex``: embreex's batch ``scene.run`` (one core, tnear emulated by offsetting origins); not
  callable from kernels, kept as an independent check of ``embree``.
"""

from lightcuts.accel.base import RayCaster
from lightcuts.accel.registry import RAY_CASTERS, make_caster

__all__ = ["RAY_CASTERS", "RayCaster", "make_caster"]
