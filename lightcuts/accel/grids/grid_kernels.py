"""numba traversal of nested uniform grids (lightcuts.accel.grids.grids): closest hit and occlusion.

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

Triangles: the watertight test of Woop, Benthin and Wald (lightcuts.accel.triangles.watertight_t),
so no ray slips through an edge shared by two triangles.

Caster data ``(GRID_TAG, lo, hi, res, cell, inv, voxel0, vox_items, item_refs, vox_subs, sub_refs, tri, meta)``
(:data:`GRID_DEVICE`, kernel name ``lightcuts.grid``, the ``device`` of every grid caster's entry):
the forest's arrays, cell and inv (G, 3) float64 (extent / n and n / extent, 0 on a flat axis),
``tri (F, 9)`` float64 triangle corners, ``meta`` (3,) float64 = (scene scale, stack levels,
mailbox slots). The scratch (float64) is the ray counter, the mailbox and a stack of
``STATE`` values per nested grid: (grid, ix, iy, iz, sub-grid cursor, t entering the voxel, t
leaving it, t leaving the grid, axis of the next step).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import DeviceFunctions
from lightcuts.accel.packets import mark_lane_occluded, packet_get_ray
from lightcuts.accel.triangles import ray_frame, watertight_t
from lightcuts.parallel import on_threads

TOL = 1e-9
MAILBOX = 256
PROBES = 8
STATE = 9


@njit(cache=True, inline="always", error_model="numpy")
def _enter(glo, ghi, gres, ginv, g, t0, t1, o, d, inv, tol, wtol):
    """The ray over [t0, t1] clipped to grid g's box (widened by tol): (t0, t1, ix, iy, iz) of its
    first voxel, t0 > t1 if it misses the box."""
    for a in range(3):
        if d[a] == 0.0:
            if o[a] < glo[g, a] - wtol or o[a] > ghi[g, a] + wtol:
                return np.inf, -np.inf, 0, 0, 0
        else:
            ta = (glo[g, a] - o[a]) * inv[a]
            tb = (ghi[g, a] - o[a]) * inv[a]
            if ta > tb:
                ta, tb = tb, ta
            t0 = max(t0, ta - tol)
            t1 = min(t1, tb + tol)
    ix = min(max(int(np.floor((o[0] + t0 * d[0] - glo[g, 0]) * ginv[g, 0])), 0), gres[g, 0] - 1)
    iy = min(max(int(np.floor((o[1] + t0 * d[1] - glo[g, 1]) * ginv[g, 1])), 0), gres[g, 1] - 1)
    iz = min(max(int(np.floor((o[2] + t0 * d[2] - glo[g, 2]) * ginv[g, 2])), 0), gres[g, 2] - 1)
    return t0, t1, ix, iy, iz


@njit(cache=True, error_model="numpy")
def traverse(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar, any_hit):
    """(t, prim): the closest hit with tnear <= t <= tfar (any hit if ``any_hit``), (inf, -1) if none."""
    glo, ghi, gres, gcell, ginv = data[1], data[2], data[3], data[4], data[5]
    voxel0, vitems, irefs, vsubs, srefs, tri, meta = data[6], data[7], data[8], data[9], data[10], data[11], data[12]
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
    step = (1 if dx > 0.0 else -1, 1 if dy > 0.0 else -1, 1 if dz > 0.0 else -1)
    kx, ky, kz, sx, sy, sz = ray_frame(dx, dy, dz)
    scratch[0] += 1.0
    stamp = scratch[0]
    mb = int(meta[2])
    base = 1 + 2 * mb
    best_t = tfar
    best = np.int64(-1)
    # The current grid's state in locals; the grids it is nested in are saved on the stack.
    g = 0
    t_enter, t_end, i0, i1, i2 = _enter(glo, ghi, gres, ginv, 0, tnear, tfar, o, d, inv, tol, wtol)
    if t_enter > t_end:
        return np.inf, best
    level = 0
    cursor = -1
    t_exit = 0.0
    axis = 0
    while True:
        v = voxel0[g] + i0 + gres[g, 0] * (i1 + gres[g, 1] * i2)
        if cursor < 0:
            t_exit = np.inf
            for a in range(3):
                if d[a] == 0.0:
                    continue
                i = i0 if a == 0 else (i1 if a == 1 else i2)
                if d[a] > 0.0:
                    b = ghi[g, a] if i == gres[g, a] - 1 else glo[g, a] + (i + 1) * gcell[g, a]
                else:
                    b = glo[g, a] if i == 0 else glo[g, a] + i * gcell[g, a]
                tn = (b - o[a]) * inv[a]
                if tn < t_exit:
                    t_exit = tn
                    axis = a
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
                t = watertight_t(tri, f, ox, oy, oz, kx, ky, kz, sx, sy, sz)
                if t != np.inf and tnear <= t <= best_t and (best < 0 or t < best_t):
                    best_t = t
                    best = f
                    if any_hit:
                        return best_t, best
            cursor = vsubs[v]
        if cursor < vsubs[v + 1]:
            c = np.int64(srefs[cursor])
            cursor += 1
            c0, c1, j0, j1, j2 = _enter(glo, ghi, gres, ginv, c, max(t_enter - tol, tnear),
                                        min(min(t_exit, t_end), best_t) + tol, o, d, inv, tol, wtol)
            if c0 <= c1:
                s = base + STATE * level
                scratch[s] = g
                scratch[s + 1] = i0
                scratch[s + 2] = i1
                scratch[s + 3] = i2
                scratch[s + 4] = cursor
                scratch[s + 5] = t_enter
                scratch[s + 6] = t_exit
                scratch[s + 7] = t_end
                scratch[s + 8] = axis
                level += 1
                g, t_enter, t_end, i0, i1, i2, cursor = c, c0, c1, j0, j1, j2, -1
            continue
        end = t_end if any_hit else min(t_end, best_t + tol)
        done = t_exit >= end
        if not done:
            i = (i0 if axis == 0 else (i1 if axis == 1 else i2)) + step[axis]
            if i < 0 or i >= gres[g, axis]:
                done = True
            else:
                if axis == 0:
                    i0 = i
                elif axis == 1:
                    i1 = i
                else:
                    i2 = i
                t_enter = t_exit
                cursor = -1
        if done:
            if level == 0:
                break
            level -= 1
            s = base + STATE * level
            g = int(scratch[s])
            i0, i1, i2 = int(scratch[s + 1]), int(scratch[s + 2]), int(scratch[s + 3])
            cursor = int(scratch[s + 4])
            t_enter, t_exit, t_end = scratch[s + 5], scratch[s + 6], scratch[s + 7]
            axis = int(scratch[s + 8])
    if best < 0:
        return np.inf, best
    return best_t, best


@njit(cache=True, error_model="numpy")
def grid_new_scratch(data):
    """The per-thread scratch (module docstring): ray counter 0, empty mailbox, the stack."""
    meta = data[12]
    mb = int(meta[2])
    out = np.empty(1 + 2 * mb + STATE * max(int(meta[1]) - 1, 1))
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


@njit(cache=True, error_model="numpy")
def grid_packet_occluded(data, scratch, pk, width, n):
    """A packet of shadow rays, lane by lane (lightcuts.accel.kernel_api)."""
    for lane in range(n):
        ox, oy, oz, dx, dy, dz, tnear, tfar = packet_get_ray(pk, width, lane)
        if traverse(data, scratch, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0:
            mark_lane_occluded(pk, width, lane)


#: The grid casters' device functions (their registry entries declare them) and the first element of their data.
GRID_DEVICE = DeviceFunctions("lightcuts.grid", grid_intersect, grid_occluded, grid_packet_occluded, grid_new_scratch)
GRID_TAG = GRID_DEVICE.tag


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
