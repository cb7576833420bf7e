"""numba traversal of nested uniform grids (lightcuts.accel.grids): closest hit and occlusion.

Per grid, the 3D DDA of Amanatides and Woo (1987): the ray enters the grid's box, starts in the
voxel holding its entry point, and steps to the neighbour across the nearest voxel boundary (each
boundary's t is computed from the voxel index, so no error accumulates). In each voxel the
triangles are tested, then every sub-grid it references is traversed over the ray's stretch in the
voxel (Cazals et al. 1995, 2.3.2). A hit anywhere along the ray is kept; a grid is left once the
nearest hit so far lies before the next voxel boundary, since no later voxel can hold a nearer one.
Intervals are widened by ``TOL`` of the scene's scale so that rounding at a boundary never skips
a voxel (visiting one twice costs only time).

Mailbox: each ray has an id (a counter in the scratch), and a small open-addressing table of
(ray id, triangle) slots, ``MAILBOX`` of them probed ``PROBES`` at a time, records the triangles the
ray has tested, so a triangle referenced by several voxels is tested once (if the probed slots are
all taken by the ray's other triangles it is tested again, which is only slower).

Caster data ``(lo, hi, res, cell, inv, voxel0, vox_items, item_refs, vox_subs, sub_refs, tri, meta)``:
the forest's arrays, cell and inv (G, 3) float64 (extent / n and n / extent, 0 on a flat axis),
``tri (F, 9)`` float64 triangle corners, ``meta`` (3,) float64 = (scene scale, stack levels,
mailbox slots). The scratch (float64) is the ray counter, the mailbox and a stack of
``STATE`` values per nested grid: (grid, ix, iy, iz, sub-grid cursor, t entering the voxel, t
leaving it, t leaving the grid, axis of the next step).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.parallel import on_threads

TOL = 1e-9
MAILBOX = 256
PROBES = 8
STATE = 9


@njit(cache=True, inline="always", error_model="numpy")
def tri_t(tri, f, ox, oy, oz, dx, dy, dz):
    """Distance along the ray to triangle f of tri (F, 9), inf on a miss (Moeller-Trumbore, float64)."""
    e1x, e1y, e1z = tri[f, 3] - tri[f, 0], tri[f, 4] - tri[f, 1], tri[f, 5] - tri[f, 2]
    e2x, e2y, e2z = tri[f, 6] - tri[f, 0], tri[f, 7] - tri[f, 1], tri[f, 8] - tri[f, 2]
    px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:
        return np.inf
    inv = 1.0 / det
    sx, sy, sz = ox - tri[f, 0], oy - tri[f, 1], oz - tri[f, 2]
    u = (sx * px + sy * py + sz * pz) * inv
    if u < 0.0 or u > 1.0:
        return np.inf
    qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if v < 0.0 or u + v > 1.0:
        return np.inf
    return (e2x * qx + e2y * qy + e2z * qz) * inv


@njit(cache=True, inline="always", error_model="numpy")
def _push(data, scratch, base, top, g, t0, t1, o, d, inv, tol, wtol):
    """Enter grid g over [t0, t1] (clipped to its box, widened by tol): its state on level ``top``;
    returns the new stack size (unchanged if the ray misses the box)."""
    glo, ghi, gres, ginv = data[0], data[1], data[2], data[4]
    for a in range(3):
        if d[a] == 0.0:
            if o[a] < glo[g, a] - wtol or o[a] > ghi[g, a] + wtol:
                return top
        else:
            ta = (glo[g, a] - o[a]) * inv[a]
            tb = (ghi[g, a] - o[a]) * inv[a]
            if ta > tb:
                ta, tb = tb, ta
            t0 = max(t0, ta - tol)
            t1 = min(t1, tb + tol)
    if t0 > t1:
        return top
    s = base + STATE * top
    scratch[s] = g
    for a in range(3):
        i = int(np.floor((o[a] + t0 * d[a] - glo[g, a]) * ginv[g, a]))
        scratch[s + 1 + a] = min(max(i, 0), gres[g, a] - 1)
    scratch[s + 4] = -1.0
    scratch[s + 5] = t0
    scratch[s + 6] = 0.0
    scratch[s + 7] = t1
    scratch[s + 8] = 0.0
    return top + 1


@njit(cache=True, error_model="numpy")
def traverse(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar, any_hit):
    """(t, prim): the closest hit with tnear <= t <= tfar (any hit if ``any_hit``), (inf, -1) if none."""
    glo, ghi, gres, gcell = data[0], data[1], data[2], data[3]
    voxel0, vitems, irefs, vsubs, srefs, tri, meta = data[5], data[6], data[7], data[8], data[9], data[10], data[11]
    if not tfar >= tnear or tri.shape[0] == 0:
        return np.inf, np.int64(-1)
    dl = np.sqrt(dx * dx + dy * dy + dz * dz)
    if dl == 0.0:
        return np.inf, np.int64(-1)
    wtol = TOL * meta[0]
    tol = wtol / dl
    o = (ox, oy, oz)
    d = (dx, dy, dz)
    inv = (1.0 / dx if dx != 0.0 else np.inf, 1.0 / dy if dy != 0.0 else np.inf, 1.0 / dz if dz != 0.0 else np.inf)
    scratch[0] += 1.0
    stamp = scratch[0]
    mb = int(meta[2])
    base = 1 + 2 * mb
    best_t = tfar
    best = np.int64(-1)
    top = _push(data, scratch, base, 0, 0, tnear, tfar, o, d, inv, tol, wtol)
    while top > 0:
        s = base + STATE * (top - 1)
        g = int(scratch[s])
        i0, i1, i2 = int(scratch[s + 1]), int(scratch[s + 2]), int(scratch[s + 3])
        v = voxel0[g] + i0 + gres[g, 0] * (i1 + gres[g, 1] * i2)
        cursor = int(scratch[s + 4])
        if cursor < 0:
            t_exit = np.inf
            axis = 0
            for a in range(3):
                i = i0 if a == 0 else (i1 if a == 1 else i2)
                if d[a] > 0.0:
                    b = ghi[g, a] if i == gres[g, a] - 1 else glo[g, a] + (i + 1) * gcell[g, a]
                elif d[a] < 0.0:
                    b = glo[g, a] if i == 0 else glo[g, a] + i * gcell[g, a]
                else:
                    continue
                tn = (b - o[a]) * inv[a]
                if tn < t_exit:
                    t_exit = tn
                    axis = a
            scratch[s + 6] = t_exit
            scratch[s + 8] = axis
            for j in range(vitems[v], vitems[v + 1]):
                f = np.int64(irefs[j])
                h = (f * 2654435761) & (mb - 1)
                seen = False
                for p in range(PROBES):
                    q = 1 + 2 * ((h + p) & (mb - 1))
                    if scratch[q] != stamp:
                        scratch[q] = stamp
                        scratch[q + 1] = f
                        break
                    if scratch[q + 1] == f:
                        seen = True
                        break
                if seen:
                    continue
                t = tri_t(tri, f, ox, oy, oz, dx, dy, dz)
                if t != np.inf and tnear <= t <= best_t and (best < 0 or t < best_t):
                    best_t = t
                    best = f
                    if any_hit:
                        return best_t, best
            cursor = vsubs[v]
            scratch[s + 4] = cursor
        t_enter, t_exit, t_end = scratch[s + 5], scratch[s + 6], scratch[s + 7]
        if cursor < vsubs[v + 1]:
            scratch[s + 4] = cursor + 1
            top = _push(data, scratch, base, top, np.int64(srefs[cursor]), max(t_enter - tol, tnear),
                        min(min(t_exit, t_end), best_t) + tol, o, d, inv, tol, wtol)
            continue
        end = t_end if any_hit else min(t_end, best_t + tol)
        if t_exit >= end:
            top -= 1
            continue
        axis = int(scratch[s + 8])
        i = int(scratch[s + 1 + axis]) + (1 if d[axis] > 0.0 else -1)
        if i < 0 or i >= gres[g, axis]:
            top -= 1
            continue
        scratch[s + 1 + axis] = i
        scratch[s + 5] = t_exit
        scratch[s + 4] = -1.0
    if best < 0:
        return np.inf, best
    return best_t, best


@njit(cache=True, error_model="numpy")
def grid_new_scratch(data):
    """The per-thread scratch (module docstring): ray counter 0, empty mailbox, the stack."""
    meta = data[11]
    mb = int(meta[2])
    out = np.empty(1 + 2 * mb + STATE * int(meta[1]))
    out[0] = 0.0
    for q in range(mb):
        out[1 + 2 * q] = -1.0
    return out


@njit(cache=True, error_model="numpy")
def grid_intersect(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Closest hit: (t float64, prim int64), (inf, -1) on a miss."""
    return traverse(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar, False)


@njit(cache=True, error_model="numpy")
def grid_occluded(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """Any hit with tnear <= t <= tfar."""
    return traverse(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0


@njit(cache=True, nogil=True, error_model="numpy")
def _intersect_range(data, org, dirs, tnear, tfar, t_out, prim_out, start, end):
    scratch = grid_new_scratch(data)
    for i in range(start, end):
        t, p = traverse(data, scratch, org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                        tnear[i], tfar[i], False)
        t_out[i] = t
        prim_out[i] = p


@njit(cache=True, nogil=True, error_model="numpy")
def _occluded_range(data, org, dirs, tnear, tfar, out, start, end):
    scratch = grid_new_scratch(data)
    for i in range(start, end):
        out[i] = traverse(data, scratch, org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                          tnear[i], tfar[i], True)[1] >= 0


def intersect_rays(data, org, dirs, tnear, tfar):
    """Closest hits of validated rays (lightcuts.accel.base.check_rays) on both cores: t (n,), prim (n,) int32."""
    n = len(org)
    t = np.empty(n)
    prim = np.empty(n, np.int64)
    on_threads(_intersect_range, n, 256, data, org, dirs, tnear, tfar, t, prim)
    return t, prim.astype(np.int32)


def occluded_rays(data, org, dirs, tnear, tfar):
    """(n,) bool occlusion of validated rays on both cores."""
    out = np.empty(len(org), np.bool_)
    on_threads(_occluded_range, len(org), 256, data, org, dirs, tnear, tfar, out)
    return out
