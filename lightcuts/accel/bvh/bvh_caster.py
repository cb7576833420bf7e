"""BVH ray casters in numba: a topology builder + lightcuts.accel.bvh.bvh + lightcuts.accel.bvh.bvh_kernels.

Each caster name pairs :class:`BVHCaster` with one topology builder, a function
``builder(lo (F,3) float64, hi (F,3) float64) -> (left, right, prim, root)`` over the triangles'
boxes in the light-tree builders' convention (lightcuts.accel.bvh.bvh). :func:`register_bvh_caster` is
the hook: ``bvh-sah`` is the binned SAH builder (lightcuts.accel.bvh.bvh_build); another clustering
registers the same class under its own name with ``register_bvh_caster(name, builder)``;
``bvh-agglomerative`` and ``bvh-agglomerative-heap`` are the 2008 paper's locally-ordered (Fig. 4)
and heap (Fig. 3) clusterings with the surface area of the union's box as the dissimilarity
(lightcuts.accel.bvh.bvh_agglomerative). None has parameters. All are
kernel-callable (:attr:`BVHCaster.kernel_caster`), so they render, trace particles and render the
reference like ``embree``.
"""

from __future__ import annotations

import numpy as np

from lightcuts.accel.base import KernelCaster, RayCaster, check_mesh, check_rays
from lightcuts.accel.bvh.bvh import FlatBVH, from_topology
from lightcuts.accel.bvh.bvh_agglomerative import bvh_agglomerative, bvh_agglomerative_heap
from lightcuts.accel.bvh.bvh_build import build_binned_sah
from lightcuts.accel.bvh.bvh_kernels import BVH_DEVICE, BVH_TAG
from lightcuts.accel.packets import PACKET_WIDTH
from lightcuts.accel.registry import register_caster
from lightcuts.accel.triangles import triangle_boxes, triangle_corners
from lightcuts.errors import LightcutsError


class BVHCaster(RayCaster):
    """Closest hit and occlusion by traversing a :class:`~lightcuts.accel.bvh.bvh.FlatBVH` in numba.

    vertices (V, 3), faces (F, 3) : the mesh (vertices used as float32, like Embree's)
    builder : topology builder (module docstring); name : its name, stored in the BVH
    bvh : an already built (e.g. loaded) FlatBVH over this mesh instead of building one
    """

    def __init__(self, vertices, faces, builder=build_binned_sah, name: str = "bvh-sah",
                 bvh: FlatBVH | None = None):
        vertices, faces = check_mesh(vertices, faces)
        self.n_faces = len(faces)
        if bvh is None:
            lo, hi = triangle_boxes(vertices, faces)
            left, right, prim, root = builder(lo, hi)
            bvh = from_topology(left, right, prim, root, vertices, faces, builder=name)
        elif bvh.n_faces != self.n_faces:
            raise LightcutsError(f"ray caster {name!r}: the BVH indexes {bvh.n_faces} triangles; the mesh has "
                                 f"{self.n_faces}")
        self.bvh = bvh
        self.name = name
        self._tri = triangle_corners(vertices, faces)
        self._data = (BVH_TAG, bvh.lo, bvh.hi, bvh.right, bvh.prim, self._tri, np.int64(bvh.depth + 1))

    @classmethod
    def load(cls, path, vertices, faces) -> "BVHCaster":
        """A caster over the mesh with the BVH saved at ``path`` (:meth:`FlatBVH.save`)."""
        bvh = FlatBVH.load(path)
        return cls(vertices, faces, name=bvh.builder or "bvh", bvh=bvh)

    def save(self, path) -> None:
        """Save the BVH (.npz, keys in lightcuts.accel.bvh.bvh)."""
        self.bvh.save(path)

    def stats(self) -> dict:
        """The BVH's SAH statistics, nodes, depth and memory (:meth:`FlatBVH.sah_stats`; memory counts
        the node arrays and the caster's (F, 9) float64 triangle corners)."""
        s = self.bvh.sah_stats()
        return {**s, "memory_bytes": s["memory_bytes"] + self._tri.nbytes}

    @property
    def kernel_caster(self) -> KernelCaster:
        return KernelCaster(self._data, PACKET_WIDTH)

    def intersect(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.bvh.bvh_kernels import intersect_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        t = np.empty(len(org), np.float64)
        prim = np.empty(len(org), np.int32)
        if len(org):
            intersect_rays(self._data, org, dirs, tnear, tfar, t, prim)
        return t, prim

    def occluded(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.bvh.bvh_kernels import occluded_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        out = np.empty(len(org), np.bool_)
        if len(org):
            occluded_rays(self._data, org, dirs, tnear, tfar, out)
        return out


def register_bvh_caster(name: str, builder, description: str, replace: bool = False):
    """Register ``name`` as a kernel-callable ray caster: :class:`BVHCaster` over ``builder``'s topology
    (``builder(lo, hi) -> (left, right, prim, root)``, see the module docstring). Returns the factory."""

    def factory(vertices, faces):
        return BVHCaster(vertices, faces, builder=builder, name=name)

    factory.__doc__ = description
    factory.__name__ = f"bvh_caster_{name.replace('-', '_')}"
    register_caster(name, factory, device=BVH_DEVICE, description=description, replace=replace)
    return factory


register_bvh_caster("bvh-sah", build_binned_sah,
                    "numba BVH, binned SAH (Wald 2007: longest centroid axis, 16 bins), one triangle per leaf")
register_bvh_caster("bvh-agglomerative", bvh_agglomerative,
                    "numba BVH, locally-ordered agglomerative clustering (Walter et al. 2008, Fig. 4), "
                    "d(A, B) = surface area of the box of A u B, one triangle per leaf")
register_bvh_caster("bvh-agglomerative-heap", bvh_agglomerative_heap,
                    "numba BVH, heap-based agglomerative clustering (Walter et al. 2008, Fig. 3), "
                    "d(A, B) = surface area of the box of A u B, one triangle per leaf")
