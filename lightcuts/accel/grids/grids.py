"""Nested uniform grids over triangles' boxes: the layout shared by ``grid``, ``recursive-grid``,
``octree`` and ``hug`` (structure of arrays, saved as .npz).

A :class:`GridForest` is a set of uniform grids; grid 0 is the top one (the whole scene). Grid g
spans the box ``[lo[g], hi[g]]`` cut into ``res[g]`` voxels per axis; its voxels are numbered
``voxel0[g] + ix + nx * (iy + ny * iz)``. Voxel v references the triangles
``item_refs[vox_items[v]:vox_items[v + 1]]`` and the sub-grids ``sub_refs[vox_subs[v]:vox_subs[v + 1]]``
(a sub-grid is traversed, clipped to the voxel's stretch of the ray, when the ray crosses the voxel).

Voxel i along an axis is the closed interval ``[lo + i * cell, lo + (i + 1) * cell]``,
``cell = (hi - lo) / n``; a box ``[a, b]`` is referenced by the voxels ``floor((a - lo) / cell - EDGE)``
to ``floor((b - lo) / cell + EDGE)`` (clamped to the grid): every voxel that the closed box
overlaps, a box touching a voxel face counting for both voxels. An axis
on which the grid is flat (zero extent) has one voxel.

Cube-root criterion (Jansen; Cazals et al. 1995, 1.2.2): a grid for n objects has about n voxels.
The cells are made as close to cubes as the box allows (:func:`cube_root_res`); for a cubic box this
is the paper's ``n_x = n_y = n_z = n^(1/3)``, and a flat or long box spends its voxels along the axes
it extends over.

.npz keys (:meth:`GridForest.save`): ``lo``, ``hi`` (G, 3) float64; ``res`` (G, 3) int64;
``voxel0`` (G + 1,) int64; ``level`` (G,) int64 (a HUG grid's filter level, else its depth);
``vox_items``, ``vox_subs`` (V + 1,) int64; ``item_refs`` (R,) int32; ``sub_refs`` (S,) int32;
``n_faces`` () int64; ``kind`` () str.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.io import read_npz, save_npz

#: The arrays of a forest (what its memory figure counts and what is saved).
ARRAY_KEYS = ("lo", "hi", "res", "voxel0", "level", "vox_items", "item_refs", "vox_subs", "sub_refs")
#: An axis shorter than this fraction of the longest one gets one voxel (a flat box).
FLAT = 1e-3
#: Voxel fraction within which a box's end counts as on a boundary (both neighbours reference it,
#: so a hit exactly on a voxel face is found from either side).
EDGE = 1e-9


@dataclass(frozen=True)
class GridForest:
    """Nested uniform grids (module docstring for the arrays); n_faces: triangles indexed; kind: the
    builder's name."""

    lo: np.ndarray
    hi: np.ndarray
    res: np.ndarray
    voxel0: np.ndarray
    level: np.ndarray
    vox_items: np.ndarray
    item_refs: np.ndarray
    vox_subs: np.ndarray
    sub_refs: np.ndarray
    n_faces: int
    kind: str = ""

    @property
    def n_grids(self) -> int:
        return int(len(self.lo))

    @property
    def n_voxels(self) -> int:
        return int(self.voxel0[-1])

    @property
    def nbytes(self) -> int:
        """Bytes of the structure's arrays (grid headers, voxel offsets, reference lists)."""
        return int(sum(getattr(self, k).nbytes for k in ARRAY_KEYS))

    def parents(self) -> np.ndarray:
        """(G,) int64: the grid whose voxels first reference each grid (-1 for grid 0 and orphans)."""
        par = np.full(self.n_grids, -1, np.int64)
        owner = np.repeat(np.arange(self.n_grids), np.diff(self.voxel0))
        vox = np.repeat(np.arange(self.n_voxels), np.diff(self.vox_subs))
        par[self.sub_refs] = owner[vox]   # every builder nests a grid in one parent grid
        return par

    @property
    def depth(self) -> int:
        """Grids on the longest chain of nesting (1 for a single grid)."""
        return int(_depth(self.parents())) if self.n_grids else 0

    def grid_of_voxels(self) -> np.ndarray:
        """(V,) int64: the grid each voxel belongs to."""
        return np.repeat(np.arange(self.n_grids), np.diff(self.voxel0))

    def voxel_boxes(self, g: int) -> tuple[np.ndarray, np.ndarray]:
        """Boxes of grid g's voxels in voxel order: lo, hi (nx * ny * nz, 3) float64."""
        nx, ny, nz = (int(r) for r in self.res[g])
        iz, iy, ix = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
        idx = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)
        cell = (self.hi[g] - self.lo[g]) / self.res[g]
        return self.lo[g] + idx * cell, self.lo[g] + (idx + 1) * cell

    def save(self, path) -> None:
        save_npz(path, **{k: getattr(self, k) for k in ARRAY_KEYS}, n_faces=np.int64(self.n_faces),
                 kind=np.str_(self.kind))

    @classmethod
    def load(cls, path) -> "GridForest":
        z = read_npz(path, "grid")
        missing = [k for k in (*ARRAY_KEYS, "n_faces", "kind") if k not in z]
        if missing:
            raise LightcutsError(f"{path}: not a grid file (missing {', '.join(missing)})")
        f = cls(**{k: np.ascontiguousarray(z[k]) for k in ARRAY_KEYS}, n_faces=int(z["n_faces"]),
                kind=str(z["kind"]))
        check_forest(f, path)
        return f


def check_forest(f: GridForest, where) -> None:
    """LightcutsError naming ``where`` unless the arrays are consistent (so no kernel reads out of range)."""
    g, v = f.n_grids, len(f.vox_items) - 1

    def bad(msg):
        raise LightcutsError(f"{where}: grid file: {msg}")

    if g < 1 or f.lo.shape != (g, 3) or f.hi.shape != (g, 3) or f.res.shape != (g, 3) or f.voxel0.shape != (g + 1,):
        bad("grid arrays have inconsistent shapes")
    if (f.res < 1).any() or not (f.lo <= f.hi).all() or not np.isfinite(f.lo).all() or not np.isfinite(f.hi).all():
        bad("a grid has a bad box or resolution")
    if not np.array_equal(np.diff(f.voxel0), f.res.prod(axis=1)) or f.voxel0[0] != 0 or f.voxel0[-1] != v:
        bad("voxel0 does not match the resolutions")
    for name, off, refs, n in (("vox_items", f.vox_items, f.item_refs, f.n_faces), ("vox_subs", f.vox_subs, f.sub_refs, g)):
        if off.shape != (v + 1,) or off[0] != 0 or off[-1] != len(refs) or (np.diff(off) < 0).any():
            bad(f"{name} is not an offset array over the voxels")
        if len(refs) and (refs.min() < 0 or refs.max() >= n):
            bad(f"{name} references outside [0, {n})")
    if len(f.sub_refs) and (f.sub_refs == 0).any():
        bad("grid 0 is referenced as a sub-grid")


@njit(cache=True)
def _depth(par):
    d = np.ones(len(par), np.int64)
    for g in range(1, len(par)):   # every builder creates a parent before its children
        if par[g] >= 0:
            d[g] = d[par[g]] + 1
    return d.max()


@njit(cache=True)
def cube_root_res(lo, hi, n):
    """Voxels per axis (3,) int64 for a grid of about n voxels over the box [lo, hi] (module
    docstring): cells as close to cubes as the box allows; an axis under FLAT of the longest gets 1."""
    res = np.ones(3, np.int64)
    ext = hi - lo
    m = max(ext[0], max(ext[1], ext[2]))
    if n <= 1 or not m > 0.0:
        return res
    k = 0
    vol = 1.0
    for a in range(3):
        if ext[a] > FLAT * m:
            k += 1
            vol *= ext[a]
    s = (vol / n) ** (1.0 / k)
    for a in range(3):
        if ext[a] > FLAT * m:
            res[a] = max(1, min(int(round(ext[a] / s)), 1 << 20))
    return res


@njit(cache=True)
def voxel_range(a, b, lo, n, inv):
    """Voxel range [i0, i1] along one axis of a grid (lo, n voxels, inv = n / extent or 0) that the
    closed interval [a, b] overlaps, clamped to the grid; an end within EDGE of a voxel boundary
    counts for the voxels on both sides."""
    i0 = int(np.floor((a - lo) * inv - EDGE))
    i1 = int(np.floor((b - lo) * inv + EDGE))
    return min(max(i0, 0), n - 1), min(max(i1, 0), n - 1)


@njit(cache=True)
def grid_inv(lo, hi, res):
    """(3,) float64: n / extent per axis, 0 on a flat axis (every point maps to voxel 0)."""
    inv = np.zeros(3)
    for a in range(3):
        e = hi[a] - lo[a]
        inv[a] = res[a] / e if e > 0.0 else 0.0
    return inv


@njit(cache=True)
def fill_grids(glo, ghi, gres, item_start, items, blo, bhi):
    """Reference lists of a batch of grids: grid g holds the boxes ``items[item_start[g]:item_start[g+1]]``
    of ``blo, bhi (F, 3)``. Returns voxel0 (G + 1,) int64 (voxels of grid g from voxel0[g]), vox_items
    (V + 1,) int64 offsets and item_refs (R,) int32 (each voxel's items in the order given)."""
    G = glo.shape[0]
    voxel0 = np.zeros(G + 1, np.int64)
    for g in range(G):
        voxel0[g + 1] = voxel0[g] + gres[g, 0] * gres[g, 1] * gres[g, 2]
    counts = np.zeros(voxel0[G] + 1, np.int64)
    for rep in range(2):
        if rep == 1:
            for v in range(voxel0[G]):
                counts[v + 1] += counts[v]
            fill = counts[:-1].copy()
            refs = np.empty(counts[voxel0[G]], np.int32)
        for g in range(G):
            inv = grid_inv(glo[g], ghi[g], gres[g])
            nx, ny = gres[g, 0], gres[g, 1]
            for j in range(item_start[g], item_start[g + 1]):
                f = items[j]
                x0, x1 = voxel_range(blo[f, 0], bhi[f, 0], glo[g, 0], gres[g, 0], inv[0])
                y0, y1 = voxel_range(blo[f, 1], bhi[f, 1], glo[g, 1], gres[g, 1], inv[1])
                z0, z1 = voxel_range(blo[f, 2], bhi[f, 2], glo[g, 2], gres[g, 2], inv[2])
                for iz in range(z0, z1 + 1):
                    for iy in range(y0, y1 + 1):
                        for ix in range(x0, x1 + 1):
                            v = voxel0[g] + ix + nx * (iy + ny * iz)
                            if rep == 0:
                                counts[v + 1] += 1
                            else:
                                refs[fill[v]] = f
                                fill[v] += 1
    return voxel0, counts, refs


def assemble(lo, hi, res, level, counts_items, refs, counts_subs, subs, n_faces, kind) -> GridForest:
    """A GridForest from per-voxel counts (V,) and reference lists in voxel order."""
    vox_items = np.zeros(len(counts_items) + 1, np.int64)
    np.cumsum(counts_items, out=vox_items[1:])
    vox_subs = np.zeros(len(counts_subs) + 1, np.int64)
    np.cumsum(counts_subs, out=vox_subs[1:])
    res = np.ascontiguousarray(res, np.int64)
    voxel0 = np.zeros(len(res) + 1, np.int64)
    np.cumsum(res.prod(axis=1), out=voxel0[1:])
    return GridForest(np.ascontiguousarray(lo, np.float64), np.ascontiguousarray(hi, np.float64), res, voxel0,
                      np.ascontiguousarray(level, np.int64), vox_items, np.ascontiguousarray(refs, np.int32),
                      vox_subs, np.ascontiguousarray(subs, np.int32), int(n_faces), kind)
