"""Top-down grid builders: one uniform grid, the recursive grid and the octree (Cazals et al. 1995, 1.2).

- ``uniform``: one grid over the scene by the cube-root criterion (about n voxels for n triangles).
- ``recursive``: Jevans and Wyvill's recursive grid with Jansen's criterion: a voxel holding more
  than ``maxp`` items becomes a sub-grid over exactly that voxel, of about n_i voxels for its n_i
  items; with ``octree=True`` every sub-grid is 2 x 2 x 2 (an object octree: an object is referenced
  in every octant its box overlaps).

Coplanar piles never drop below ``maxp`` items, so three rules end the recursion: a depth limit
(``max_depth`` grids on any chain, the top grid counting 1); a voxel is subdivided only if its
non-empty sub-voxels would hold on average at most ``SEPARATES`` (three quarters) of its items, or
only one is non-empty (the items shrink into it); and the references of all sub-grids stay within
``REF_BUDGET`` times those of the top grid (sub-grids are made level by level, in voxel order,
while they fit). A pile of large overlapping coplanar triangles fills every sub-voxel its plane
crosses (4 children of 8 at each octree level), and the voxels along the edge of a pile's box split
again at every level; the first rule stops the one, the budget bounds the other.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.grids.grids import GridForest, assemble, cube_root_res, fill_grids

#: A subdivision is made only if its non-empty sub-voxels hold on average at most this fraction of
#: the voxel's items (or only one sub-voxel is non-empty).
SEPARATES = 0.75
#: All references (top grid and sub-grids) stay within this many times the top grid's.
REF_BUDGET = 16


def scene_box(blo: np.ndarray, bhi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box of all boxes (a zero box at the origin for an empty mesh)."""
    if len(blo) == 0:
        return np.zeros(3), np.zeros(3)
    return blo.min(axis=0), bhi.max(axis=0)


def build_uniform(blo: np.ndarray, bhi: np.ndarray) -> GridForest:
    """One grid of about F voxels over the boxes lo, hi (F, 3) float64."""
    n = len(blo)
    lo, hi = scene_box(blo, bhi)
    res = cube_root_res(lo, hi, n)[None]
    _, off, refs = fill_grids(lo[None], hi[None], res, np.array([0, n], np.int64), np.arange(n, dtype=np.int64),
                              blo, bhi)
    return assemble(lo[None], hi[None], res, np.zeros(1), np.diff(off), refs, np.zeros(len(off) - 1, np.int64),
                    np.zeros(0, np.int32), n, "grid")


@njit(cache=True)
def _sub_res(vlo, vhi, counts, octree):
    out = np.empty((len(counts), 3), np.int64)
    for i in range(len(counts)):
        if octree:
            out[i] = 2
        else:
            out[i] = cube_root_res(vlo[i], vhi[i], counts[i])
    return out


def _voxel_boxes(lo, hi, res, voxel0, vox):
    """Boxes (len(vox), 3) of the voxels ``vox`` (batch-local ids) of a batch of grids."""
    g = np.searchsorted(voxel0, vox, side="right") - 1
    local = vox - voxel0[g]
    nx, ny = res[g, 0], res[g, 1]
    idx = np.stack([local % nx, (local // nx) % ny, local // (nx * ny)], axis=1)
    cell = (hi[g] - lo[g]) / res[g]
    vlo = lo[g] + idx * cell
    vhi = np.where(idx + 1 == res[g], hi[g], lo[g] + (idx + 1) * cell)
    return vlo, vhi


def build_recursive(blo: np.ndarray, bhi: np.ndarray, maxp: int = 50, max_depth: int = 5,
                    octree: bool = False, kind: str = "recursive-grid") -> GridForest:
    """Recursive grid (or object octree) over the boxes lo, hi (F, 3) float64 (module docstring)."""
    n = len(blo)
    lo, hi = scene_box(blo, bhi)
    if octree:
        res = np.array([[2, 2, 2] if n > maxp else [1, 1, 1]], np.int64)
    else:
        res = cube_root_res(lo, hi, n)[None]
    voxel0, off, refs = fill_grids(lo[None], hi[None], res, np.array([0, n], np.int64),
                                   np.arange(n, dtype=np.int64), blo, bhi)
    levels = [dict(lo=lo[None], hi=hi[None], res=res, voxel0=voxel0, counts=np.diff(off), refs=refs)]
    budget = REF_BUDGET * max(len(refs), 1) - len(refs)
    split = []   # per level: batch-local voxels that became sub-grids
    depth = 1
    while True:
        cur = levels[-1]
        counts = cur["counts"]
        cand = np.flatnonzero(counts > maxp) if depth < max_depth else np.zeros(0, np.int64)
        if len(cand) == 0:
            split.append(cand)
            break
        off = np.zeros(len(counts) + 1, np.int64)
        np.cumsum(counts, out=off[1:])
        vlo, vhi = _voxel_boxes(cur["lo"], cur["hi"], cur["res"], cur["voxel0"], cand)
        nitems = counts[cand]
        item_start = np.zeros(len(cand) + 1, np.int64)
        np.cumsum(nitems, out=item_start[1:])
        items = cur["refs"][np.repeat(off[cand] - item_start[:-1], nitems) + np.arange(item_start[-1])].astype(np.int64)
        sres = _sub_res(vlo, vhi, nitems, octree)
        v0, soff, srefs = fill_grids(vlo, vhi, sres, item_start, items, blo, bhi)
        sc = np.diff(soff)
        nvox = np.diff(v0)
        grid_of = np.repeat(np.arange(len(cand)), nvox)
        nonempty = np.bincount(grid_of, weights=sc > 0, minlength=len(cand))
        refs_in = np.bincount(grid_of, weights=sc, minlength=len(cand))
        accept = ((nonempty == 1) | (refs_in <= SEPARATES * nonempty * nitems)) & (nvox > 1)
        # The budget: sub-grids in voxel order while their references fit.
        accept &= np.cumsum(np.where(accept, refs_in, 0)) <= budget
        budget -= int(refs_in[accept].sum())
        keep_vox = np.repeat(accept, nvox)
        keep_ref = np.repeat(keep_vox, sc)
        split.append(cand[accept])
        if not accept.any():
            break
        nres = sres[accept]
        nv0 = np.zeros(int(accept.sum()) + 1, np.int64)
        np.cumsum(nres.prod(axis=1), out=nv0[1:])
        levels.append(dict(lo=vlo[accept], hi=vhi[accept], res=nres, voxel0=nv0, counts=sc[keep_vox],
                           refs=srefs[keep_ref]))
        depth += 1
    # Concatenate the levels: a split voxel keeps no items and references its sub-grid.
    grid_base = np.cumsum([0] + [len(L["lo"]) for L in levels])
    c_items, r_items, c_subs, subs = [], [], [], []
    for d, L in enumerate(levels):
        counts = L["counts"].copy()
        is_split = np.zeros(len(counts), bool)
        is_split[split[d]] = True
        r_items.append(L["refs"][np.repeat(~is_split, counts)])
        counts[is_split] = 0
        c_items.append(counts)
        c_subs.append(is_split.astype(np.int64))
        subs.append(grid_base[d + 1] + np.arange(len(split[d])))
    cat = np.concatenate
    return assemble(cat([L["lo"] for L in levels]), cat([L["hi"] for L in levels]), cat([L["res"] for L in levels]),
                    cat([np.full(len(L["lo"]), d) for d, L in enumerate(levels)]), cat(c_items), cat(r_items),
                    cat(c_subs), cat(subs), n, kind)
