r"""What every caster family shares about triangles: their boxes and corners as the casters see them
(float32 vertices held in float64), and the watertight ray-triangle test.

Ray-triangle test: Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013). The
ray's largest direction component becomes z (axes kx, ky, kz, swapped to keep the winding); the
triangle's vertices, relative to the origin, are sheared so the ray is the +z axis, and three edge
functions U, V, W (2D cross products of sheared vertex pairs) decide the hit: all >= 0 or all <= 0.
A sheared vertex depends only on the vertex and the ray, and the edge function of an edge shared by
two triangles is computed from the same two values (exactly negated on the other side), so a ray
through a shared edge or vertex hits at least one of its triangles: none slips through a closed
mesh. Everything is float64 on the float32 vertices, which stands in for the paper's
double-precision fallback; an edge function of exactly 0 counts as inside on both sides.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def triangle_boxes(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Per-triangle boxes lo, hi (F, 3) float64 of the mesh as the casters see it (float32 vertices)."""
    v = np.asarray(vertices, np.float32).astype(np.float64)[np.asarray(faces, np.int64)]
    return np.ascontiguousarray(v.min(axis=1)), np.ascontiguousarray(v.max(axis=1))


def triangle_corners(vertices, faces) -> np.ndarray:
    """(F, 9) float64: the corners of each triangle (x, y, z of vertex 0, 1, 2) of a checked mesh
    (lightcuts.accel.base.check_mesh: float32 vertices, uint32 faces); what :func:`watertight_t` reads."""
    v = vertices.astype(np.float64)
    return np.ascontiguousarray(v[faces.astype(np.int64)].reshape(-1, 9))


@njit(cache=True, forceinline=True, error_model="numpy")
def ray_frame(dx, dy, dz):
    """Woop et al.'s permutation (kx, ky, kz) and shear (sx, sy, sz) for direction d."""
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    kz = 0
    if ay > ax and ay >= az:
        kz = 1
    elif az > ax and az > ay:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    dkz = dz if kz == 2 else (dy if kz == 1 else dx)
    if dkz < 0.0:
        kx, ky = ky, kx
    dkx = dz if kx == 2 else (dy if kx == 1 else dx)
    dky = dz if ky == 2 else (dy if ky == 1 else dx)
    return kx, ky, kz, dkx / dkz, dky / dkz, 1.0 / dkz


@njit(cache=True, forceinline=True, error_model="numpy")
def watertight_t(tri, f, ox, oy, oz, kx, ky, kz, sx, sy, sz):
    """Hit distance of the ray (origin o; frame from :func:`ray_frame`) with triangle f of
    ``tri (F, 9)``, or inf if it misses (or lies in the triangle's plane). t may be negative."""
    ax_ = tri[f, kx] - (ox if kx == 0 else (oy if kx == 1 else oz))
    ay_ = tri[f, ky] - (ox if ky == 0 else (oy if ky == 1 else oz))
    az_ = tri[f, kz] - (ox if kz == 0 else (oy if kz == 1 else oz))
    bx_ = tri[f, 3 + kx] - (ox if kx == 0 else (oy if kx == 1 else oz))
    by_ = tri[f, 3 + ky] - (ox if ky == 0 else (oy if ky == 1 else oz))
    bz_ = tri[f, 3 + kz] - (ox if kz == 0 else (oy if kz == 1 else oz))
    cx_ = tri[f, 6 + kx] - (ox if kx == 0 else (oy if kx == 1 else oz))
    cy_ = tri[f, 6 + ky] - (ox if ky == 0 else (oy if ky == 1 else oz))
    cz_ = tri[f, 6 + kz] - (ox if kz == 0 else (oy if kz == 1 else oz))
    ax = ax_ - sx * az_
    ay = ay_ - sy * az_
    bx = bx_ - sx * bz_
    by = by_ - sy * bz_
    cx = cx_ - sx * cz_
    cy = cy_ - sy * cz_
    u = cx * by - cy * bx
    v = ax * cy - ay * cx
    w = bx * ay - by * ax
    if (u < 0.0 or v < 0.0 or w < 0.0) and (u > 0.0 or v > 0.0 or w > 0.0):
        return np.inf
    det = u + v + w
    if det == 0.0:
        return np.inf
    return (u * sz * az_ + v * sz * bz_ + w * sz * cz_) / det
