"""Grid ray casters: ``grid``, ``recursive-grid``, ``octree`` and ``hug``.

All four structures are nested uniform grids (lightcuts.accel.grids.grids) traversed by the same
kernels (lightcuts.accel.grids.grid_kernels), as in the comparison of Cazals et al. 1995 (section 3).
All are kernel-callable: they render, trace particles and render the reference like ``embree``.
Parameters are declared in the registry (a config names them as ``render.ray_caster: {type:
recursive-grid, maxp: 150}``): ``recursive-grid`` and ``octree`` read ``maxp`` and ``max_depth``,
``hug`` reads ``alpha`` and ``levels``, ``grid`` nothing. The names of the paper's sweep,
``recursive-grid-50/100/150`` and ``octree-50/100/150``, are aliases with ``maxp`` fixed.
"""

from __future__ import annotations

import time

import numpy as np

from lightcuts.accel.base import KernelCaster, RayCaster, check_mesh, check_rays
from lightcuts.accel.grids.grid_build import build_recursive, build_uniform
from lightcuts.accel.grids.grid_kernels import GRID_DEVICE, GRID_TAG, MAILBOX
from lightcuts.accel.grids.grids import GridForest
from lightcuts.accel.grids.hug import ALPHA, LEVELS, build_hug
from lightcuts.accel.packets import PACKET_WIDTH
from lightcuts.accel.registry import register_caster
from lightcuts.accel.triangles import triangle_boxes, triangle_corners
from lightcuts.errors import LightcutsError
from lightcuts.registry import Param

#: Depth limits (grids on a chain, the top grid counting 1): Cazals et al. saw recursive grids at
#: most 5 deep and octrees 10 to 20 deep.
RECURSIVE_DEPTH = 5
OCTREE_DEPTH = 16
#: Default MAXP (items a voxel holds before it is subdivided) of the comparators.
MAXP = 50
#: MAXP values of the paper's sweep, registered as aliases ``recursive-grid-50``, ...
MAXPS = (50, 100, 150)


def build_forest(vertices, faces, kind: str, maxp: int = MAXP, max_depth: int | None = None,
                 levels: int = LEVELS, alpha: float = ALPHA) -> tuple[GridForest, dict]:
    """The structure ``kind`` ("grid", "recursive-grid", "octree", "hug") over a checked mesh, and
    its build facts (``build_s`` and, for hug, the filter and clustering figures)."""
    if maxp < 1 or (max_depth is not None and max_depth < 1) or levels < 1 or not alpha > 0:
        raise LightcutsError(f"ray caster {kind!r}: maxp, max_depth and levels must be >= 1 and alpha > 0")
    t0 = time.perf_counter()
    blo, bhi = triangle_boxes(vertices, faces)
    info: dict = {}
    if kind == "grid":
        forest = build_uniform(blo, bhi)
    elif kind == "recursive-grid":
        forest = build_recursive(blo, bhi, maxp, max_depth or RECURSIVE_DEPTH, octree=False, kind=kind)
        info = {"maxp": maxp, "max_depth": max_depth or RECURSIVE_DEPTH}
    elif kind == "octree":
        forest = build_recursive(blo, bhi, maxp, max_depth or OCTREE_DEPTH, octree=True, kind=kind)
        info = {"maxp": maxp, "max_depth": max_depth or OCTREE_DEPTH}
    elif kind == "hug":
        forest, info = build_hug(blo, bhi, levels, alpha)
        info = {"alpha": alpha, **info}
    else:
        raise LightcutsError(f"unknown grid structure {kind!r}")
    return forest, {"build_s": time.perf_counter() - t0, **info}


class GridCaster(RayCaster):
    """Closest hit and occlusion through a :class:`~lightcuts.accel.grids.grids.GridForest` in numba.

    vertices (V, 3), faces (F, 3): the mesh (vertices used as float32, like Embree's); kind and the
    parameters as :func:`build_forest`; forest: an already built (e.g. loaded) forest instead.
    """

    def __init__(self, vertices, faces, kind: str = "hug", name: str | None = None, forest: GridForest | None = None,
                 **params):
        vertices, faces = check_mesh(vertices, faces)
        self.name = name or kind
        self.n_faces = len(faces)
        if forest is None:
            forest, self.info = build_forest(vertices, faces, kind, **params)
        else:
            if forest.n_faces != self.n_faces:
                raise LightcutsError(f"ray caster {self.name!r}: the grids index {forest.n_faces} triangles; "
                                     f"the mesh has {self.n_faces}")
            self.info = {"build_s": 0.0}
        self.forest = forest
        self._depth = forest.depth
        tri = triangle_corners(vertices, faces)
        ext = forest.hi - forest.lo
        res = forest.res.astype(np.float64)
        cell = np.ascontiguousarray(ext / res)
        inv = np.ascontiguousarray(np.where(ext > 0, res / np.where(ext > 0, ext, 1.0), 0.0))
        scale = float(np.abs(np.concatenate([forest.lo[0], forest.hi[0]])).max() + np.linalg.norm(ext[0])) or 1.0
        meta = np.array([scale, self._depth, MAILBOX], np.float64)
        self._data = (GRID_TAG, forest.lo, forest.hi, forest.res, cell, inv, forest.voxel0, forest.vox_items,
                      forest.item_refs, forest.vox_subs, forest.sub_refs, tri, meta)

    @classmethod
    def load(cls, path, vertices, faces) -> "GridCaster":
        """A caster over the mesh with the grids saved at ``path`` (:meth:`save`)."""
        forest = GridForest.load(path)
        return cls(vertices, faces, kind=forest.kind, forest=forest)

    def save(self, path) -> None:
        """Save the grids (.npz, keys in lightcuts.accel.grids.grids)."""
        self.forest.save(path)

    def stats(self) -> dict:
        """The study's figures: build_s, memory_bytes (the structure's arrays and the (F, 9) float64
        triangle corners the traversal reads, as the BVH casters count), structure_bytes (the grid
        arrays alone), voxels, items
        (triangles), nu_1 = voxels / items, depth (grids on the longest chain), refs_per_item (triangle
        references / items), grids; hug adds clustering_ratio, grids_per_level (filter level 0 = the
        smallest objects), clusters_per_level, levels, filter, alpha; the comparators maxp, max_depth."""
        f = self.forest
        items = max(self.n_faces, 1)
        out = {"caster": self.name, "build_s": float(self.info.get("build_s", 0.0)), "memory_bytes": f.nbytes + self._data[-2].nbytes,
               "structure_bytes": f.nbytes,
               "voxels": f.n_voxels, "items": self.n_faces, "nu_1": f.n_voxels / items, "depth": self._depth,
               "refs_per_item": len(f.item_refs) / items, "grids": f.n_grids}
        out.update({k: v for k, v in self.info.items() if k != "build_s"})
        return out

    @property
    def kernel_caster(self) -> KernelCaster:
        """For the render kernels (lightcuts.accel.kernel_api): the data tuple and packet width."""
        return KernelCaster(self._data, PACKET_WIDTH)

    def intersect(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.grids.grid_kernels import intersect_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        return intersect_rays(self._data, org, dirs, tnear, tfar)

    def occluded(self, org, dirs, tnear=0.0, tfar=np.inf):
        from lightcuts.accel.grids.grid_kernels import occluded_rays

        org, dirs, tnear, tfar = check_rays(org, dirs, tnear, tfar)
        return occluded_rays(self._data, org, dirs, tnear, tfar)


def _factory(kind: str, doc: str):
    def factory(vertices, faces, **params):
        return GridCaster(vertices, faces, kind=kind, **params)

    factory.__doc__ = doc
    factory.__name__ = "caster_" + kind.replace("-", "_")
    return factory


def _comparator_params(depth: int) -> dict:
    return {"maxp": Param(int, MAXP, lo=1, hi=1 << 31, doc="items a voxel holds before it becomes a sub-grid"),
            "max_depth": Param(int, depth, lo=1, hi=64, doc="grids on a chain at most, the top grid counting 1")}


def register_grid_casters() -> None:
    """Register the grid casters (module docstring)."""
    register_caster("grid", _factory("grid", "one uniform grid, cube-root criterion (about F voxels)"),
                    device=GRID_DEVICE)
    register_caster("hug", _factory("hug", "hierarchy of uniform grids (Cazals et al. 1995)"), device=GRID_DEVICE,
                    params={"alpha": Param(float, ALPHA, lo=1e-9, hi=1e3, doc="clustering gap over the level's mean "
                                                                      "object size (> 0)"),
                            "levels": Param(int, LEVELS, lo=1, hi=64, doc="filter levels (object sizes)")})
    for kind, depth, what in (("recursive-grid", RECURSIVE_DEPTH, "recursive grid (Jevans and Wyvill 1989)"),
                              ("octree", OCTREE_DEPTH, "object octree")):
        register_caster(kind, _factory(kind, what), device=GRID_DEVICE, params=_comparator_params(depth),
                        aliases={f"{kind}-{m}": {"maxp": m} for m in MAXPS})


register_grid_casters()
