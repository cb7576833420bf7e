"""The brute-force oracle of the caster tests: every triangle against every ray with the casters'
own watertight test (lightcuts.accel.triangles), so a numba caster's t must equal it bit for bit."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from lightcuts.accel.triangles import ray_frame, watertight_t


@njit(parallel=True, cache=True, error_model="numpy")
def brute_force_rays(tri, org, dirs, tnear, tfar, t_out, prim_out):
    """Closest hit of each ray over ALL triangles ``tri (F, 9)`` with :func:`watertight_t`; writes
    t_out (n,) (inf on a miss) and prim_out (n,) (-1); ties keep the lowest triangle id."""
    n = org.shape[0]
    for i in prange(n):
        ox, oy, oz, dx, dy, dz = org[i, 0], org[i, 1], org[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2]
        kx, ky, kz, sx, sy, sz = ray_frame(dx, dy, dz)
        best_t = np.inf
        best = -1
        for f in range(tri.shape[0]):
            t = watertight_t(tri, f, ox, oy, oz, kx, ky, kz, sx, sy, sz)
            if t != np.inf and tnear[i] <= t <= tfar[i] and (best < 0 or t < best_t):
                best_t = t
                best = f
        t_out[i] = best_t
        prim_out[i] = best


def corners(vertices, faces) -> np.ndarray:
    """(F, 9) float64 triangle corners of the mesh as the casters see it (float32 vertices)."""
    v = np.asarray(vertices, np.float32).astype(np.float64)
    return np.ascontiguousarray(v[np.asarray(faces, np.int64)].reshape(-1, 9))


def brute(vertices, faces, org, dirs, tnear=0.0, tfar=np.inf):
    """(t (n,) float64, prim (n,) int64, tri (F, 9)): the closest hits by :func:`brute_force_rays`."""
    tri = corners(vertices, faces)
    org, dirs = np.ascontiguousarray(org, np.float64), np.ascontiguousarray(dirs, np.float64)
    n = len(org)
    t, p = np.empty(n), np.empty(n, np.int64)
    brute_force_rays(tri, org, dirs, np.broadcast_to(np.asarray(tnear, np.float64), (n,)).copy(),
                     np.broadcast_to(np.asarray(tfar, np.float64), (n,)).copy(), t, p)
    return t, p, tri
