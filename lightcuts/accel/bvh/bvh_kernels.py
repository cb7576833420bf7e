r"""numba kernels of the BVH casters: the traversals, with the watertight ray-triangle test of
lightcuts.accel.triangles.

Traversal: the BVH's depth-first arrays (lightcuts.accel.bvh.bvh); at an internal node both children's
boxes are tested (a slab test widened by ``SLACK`` relative, so rounding never culls a box a hit
lies in; a 0 * inf NaN from a ray in a slab plane leaves that slab unbounded), the nearer child is
visited and the farther pushed with its entry distance; a popped node beyond the closest hit so far
is skipped. Occlusion stops at the first hit (any hit). The stack lives in the caster's scratch
(float64, ``2 * (depth + 1)``: node index and entry t per level), so it cannot overflow.

Kernel caster ``lightcuts.bvh`` (lightcuts.accel.kernel_api; :data:`BVH_DEVICE`, the ``device`` of every
BVH caster's registry entry); its data
``(BVH_TAG, lo, hi, right, prim, tri, stack)``: the BVH's node arrays (left child = node + 1),
``tri (F, 9) float64`` the corners of each triangle, and the stack depth as int64.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from lightcuts.accel.kernel_api import DeviceFunctions
from lightcuts.accel.packets import mark_lane_occluded, packet_get_ray
from lightcuts.accel.triangles import ray_frame, watertight_t

#: Relative widening of the slab test's interval.
SLACK = 1e-9


@njit(cache=True, forceinline=True, error_model="numpy")
def _box_entry(lo, hi, n, ox, oy, oz, ix, iy, iz, tnear, tfar):
    """Entry distance of the ray into node n's box clipped to [tnear, tfar], or inf if it misses."""
    tmin = tnear
    tmax = tfar
    for a in range(3):
        o = ox if a == 0 else (oy if a == 1 else oz)
        inv = ix if a == 0 else (iy if a == 1 else iz)
        t0 = (lo[n, a] - o) * inv
        t1 = (hi[n, a] - o) * inv
        if t0 > t1:
            t0, t1 = t1, t0
        t0 -= abs(t0) * SLACK
        t1 += abs(t1) * SLACK
        if t0 > tmin:      # NaN (0 * inf) compares false: the slab is left unbounded
            tmin = t0
        if t1 < tmax:
            tmax = t1
    return tmin if tmin <= tmax else np.inf


@njit(cache=True, error_model="numpy")
def _traverse(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar, any_hit):
    lo, hi, right, prim, tri = data[1], data[2], data[3], data[4], data[5]
    if not tfar >= tnear or prim.shape[0] == 0:
        return np.inf, np.int64(-1)
    kx, ky, kz, sx, sy, sz = ray_frame(dx, dy, dz)
    ix, iy, iz = 1.0 / dx if dx != 0.0 else np.inf, 1.0 / dy if dy != 0.0 else np.inf, \
        1.0 / dz if dz != 0.0 else np.inf
    best_t = tfar
    best = np.int64(-1)
    if _box_entry(lo, hi, 0, ox, oy, oz, ix, iy, iz, tnear, best_t) == np.inf:
        return np.inf, best
    node = 0
    top = 0
    while True:
        f = prim[node]
        if f >= 0:
            t = watertight_t(tri, f, ox, oy, oz, kx, ky, kz, sx, sy, sz)
            if t != np.inf and tnear <= t <= best_t and (best < 0 or t < best_t):
                best_t = t
                best = np.int64(f)
                if any_hit:
                    return best_t, best
            node = -1
        else:
            l = node + 1
            r = right[node]
            tl = _box_entry(lo, hi, l, ox, oy, oz, ix, iy, iz, tnear, best_t)
            tr = _box_entry(lo, hi, r, ox, oy, oz, ix, iy, iz, tnear, best_t)
            if tl < np.inf and tr < np.inf:
                if tr < tl:
                    stack[2 * top] = l
                    stack[2 * top + 1] = tl
                    node = r
                else:
                    stack[2 * top] = r
                    stack[2 * top + 1] = tr
                    node = l
                top += 1
            elif tl < np.inf:
                node = l
            elif tr < np.inf:
                node = r
            else:
                node = -1
        while node < 0:
            if top == 0:
                return (best_t, best) if best >= 0 else (np.inf, best)
            top -= 1
            if stack[2 * top + 1] <= best_t:
                node = np.int64(stack[2 * top])


# Device functions of the kernel caster "lightcuts.bvh".

@njit(cache=True, error_model="numpy")
def bvh_new_scratch(data):
    """Per-thread traversal stack, float64 ``(2 * data[6],)``."""
    return np.empty(2 * data[6], np.float64)


@njit(cache=True, error_model="numpy")
def bvh_intersect(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """KernelCaster.intersect: ordered (nearer child first) closest-hit traversal."""
    return _traverse(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar, False)


@njit(cache=True, error_model="numpy")
def bvh_occluded(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar):
    """KernelCaster.occluded: any-hit traversal."""
    return _traverse(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0


@njit(cache=True, error_model="numpy")
def bvh_packet_occluded(data, stack, pk, width, n):
    """KernelCaster.packet_occluded: lanes one by one (the BVH has no packet traversal)."""
    for lane in range(n):
        ox, oy, oz, dx, dy, dz, tnear, tfar = packet_get_ray(pk, width, lane)
        if _traverse(data, stack, ox, oy, oz, dx, dy, dz, tnear, tfar, True)[1] >= 0:
            mark_lane_occluded(pk, width, lane)


#: Rays per prange iteration of the batch kernels.
CHUNK = 64


# Batch kernels of BVHCaster.intersect / occluded. Here rather than generic over casters: numba keys
# a kernel's cache on its own module's source, so these recompile when the traversal above changes.

@njit(parallel=True, cache=True, error_model="numpy")
def intersect_rays(data, org, dirs, tnear, tfar, t_out, prim_out):
    """Closest hit of each ray: org, dirs (n, 3), tnear, tfar (n,) float64; writes t_out (n,)
    float64 (inf on a miss) and prim_out (n,) int32 (-1 on a miss)."""
    n = org.shape[0]
    for c in prange((n + CHUNK - 1) // CHUNK):
        stack = bvh_new_scratch(data)
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            t, p = bvh_intersect(data, stack, org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                                 tnear[i], tfar[i])
            t_out[i] = t
            prim_out[i] = p


@njit(parallel=True, cache=True, error_model="numpy")
def occluded_rays(data, org, dirs, tnear, tfar, out):
    """Any hit of each ray segment: arrays as :func:`intersect_rays`; writes out (n,) bool."""
    n = org.shape[0]
    for c in prange((n + CHUNK - 1) // CHUNK):
        stack = bvh_new_scratch(data)
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            out[i] = bvh_occluded(data, stack, org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2],
                                  tnear[i], tfar[i])


#: The BVH casters' device functions (their registry entries declare them) and the first element of their data.
BVH_DEVICE = DeviceFunctions("lightcuts.bvh", bvh_intersect, bvh_occluded, bvh_packet_occluded, bvh_new_scratch)
BVH_TAG = BVH_DEVICE.tag
