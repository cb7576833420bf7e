"""Ray casting: closest hit and occlusion with per-ray tnear/tfar, by interchangeable casters.

Core (shared by every family):

- ``base``: the :class:`RayCaster` interface (``intersect``, ``occluded``, ``close``, ``with``
  blocks), :class:`KernelCaster` and the checks of rays and meshes;
- ``registry``: :data:`RAY_CASTERS` (name -> caster with its declared parameters and traits),
  :func:`~lightcuts.accel.registry.register_caster` and :func:`make_caster`;
- ``kernel_api``: casting from inside numba kernels, whatever the caster (device functions picked
  at compile time by a tag in the caster's data); ``packets``: the shadow-ray packet;
- ``triangles``: triangle boxes and corners, and the watertight ray-triangle test.

Families (subpackages that never import each other):

- ``embree``: ``embree`` (numba kernels calling the libembree4 that the embreex wheel ships, through
  ctypes; all cores, per-ray calls and ``rtcOccluded8`` packets) and ``embreex`` (embreex's batch
  ``scene.run``, one core, not kernel-callable; an independent check of ``embree``);
- ``bvh``: numba BVHs with the watertight test: ``bvh-sah`` (binned SAH), ``bvh-agglomerative`` and
  ``bvh-agglomerative-heap`` (Walter et al. 2008, Figs. 4 and 3); others register through
  :func:`lightcuts.accel.bvh.bvh_caster.register_bvh_caster`;
- ``grids``: nested uniform grids (Cazals et al. 1995): ``grid``, ``recursive-grid`` and ``octree``
  (parameters ``maxp``, ``max_depth``; aliases ``recursive-grid-50/100/150``, ``octree-50/100/150``)
  and ``hug`` (parameters ``alpha``, ``levels``).

Every caster but ``embreex`` is kernel-callable: it renders, traces particles and renders the reference.
"""

from lightcuts.accel.base import KernelCaster, RayCaster
from lightcuts.accel.registry import RAY_CASTERS, make_caster, register_caster

__all__ = ["KernelCaster", "RAY_CASTERS", "RayCaster", "make_caster", "register_caster"]
