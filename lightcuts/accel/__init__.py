"""Ray casting: closest hit and occlusion with per-ray tnear/tfar.

Ray casters are a registry (:mod:`lightcuts.accel.registry`; name -> class taking
``(vertices (V,3), faces (F,3))``):

- ``embree``: numba kernels calling the libembree4 that the embreex wheel ships, through ctypes
  (both cores; per-ray calls and ``rtcOccluded8`` packets inside other numba kernels);
- ``embreex``: embreex's batch ``scene.run`` (one core, tnear emulated by offsetting origins); not
  callable from kernels, kept as an independent check of ``embree``;
- ``bvh-sah``: a numba BVH (lightcuts.accel.bvh, bvh_build, bvh_kernels, bvh_caster), binned SAH,
  watertight ray-triangle test; other topology builders register through
  :func:`lightcuts.accel.bvh_caster.register_bvh_caster`.

Kernel-callable casters (``embree``, the BVH casters) are cast from inside numba kernels through
lightcuts.accel.kernel_api (the interface: lightcuts.accel.base).
"""

from lightcuts.accel.base import KernelCaster, RayCaster
from lightcuts.accel.registry import RAY_CASTERS, make_caster

__all__ = ["KernelCaster", "RAY_CASTERS", "RayCaster", "make_caster"]
