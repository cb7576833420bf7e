"""Many primitives at once as flat numpy arrays: boxes, quads split into tiles, octahedra. The
many-emitter scenes (``city``, ``office``) have hundreds of thousands of them, too many for one
trimesh call each.

Every function returns ``(vertices (V, 3) float64, faces (F, 3) int64)``, a part for
:class:`~lightcuts.scene.shapes.PartList`; item i owns the rows ``[i f, (i + 1) f)`` of ``faces``
(f faces per item) and its own vertices (items share none). Units: metres, y up.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import trimesh


@lru_cache(maxsize=1)
def _unit_box() -> tuple[np.ndarray, np.ndarray]:
    """trimesh's unit cube centred on the origin: 8 corners, 12 outward-wound triangles."""
    m = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _stack(verts: np.ndarray, faces: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` items of a template's ``faces`` over ``verts`` (n, k, 3), each item's own k vertices."""
    k = verts.shape[1]
    return verts.reshape(-1, 3), (faces[None, :, :] + k * np.arange(n)[:, None, None]).reshape(-1, 3)


def boxes(lo, hi, rot_y=None) -> tuple[np.ndarray, np.ndarray]:
    """Closed boxes [lo, hi] ((B, 3) each), 12 triangles a box with outward normals, optionally
    turned by ``rot_y`` (B,) radians about the vertical axis through the box's centre."""
    lo, hi = np.atleast_2d(np.asarray(lo, np.float64)), np.atleast_2d(np.asarray(hi, np.float64))
    unit, faces = _unit_box()
    local = unit[None, :, :] * (hi - lo)[:, None, :]
    if rot_y is not None:
        c, s = np.cos(rot_y)[:, None], np.sin(rot_y)[:, None]
        x, z = local[..., 0].copy(), local[..., 2].copy()
        local[..., 0], local[..., 2] = c * x + s * z, -s * x + c * z
    return _stack(local + (0.5 * (lo + hi))[:, None, :], faces, len(lo))


def quads(corner, u, v) -> tuple[np.ndarray, np.ndarray]:
    """Open rectangles ``corner + [0, 1] u + [0, 1] v`` ((Q, 3) each), two triangles each, wound
    so that the normal is ``u x v`` (an emitter's emitting side)."""
    corner, u, v = np.broadcast_arrays(*(np.atleast_2d(np.asarray(a, np.float64)) for a in (corner, u, v)))
    verts = np.stack([corner, corner + u, corner + u + v, corner + v], axis=1)
    return _stack(verts, np.array([[0, 1, 2], [0, 2, 3]]), len(corner))


def tiles(corner, u, v, nu: int, nv: int, gap: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Each rectangle of :func:`quads` split into ``nu`` x ``nv`` separate tiles, each shrunk by
    ``gap`` metres on every side (rectangle-major, then u, then v); normal ``u x v``."""
    corner, u, v = np.broadcast_arrays(*(np.atleast_2d(np.asarray(a, np.float64)) for a in (corner, u, v)))
    du, dv = u / nu, v / nv
    gu = gap * du / np.linalg.norm(du, axis=1, keepdims=True)
    gv = gap * dv / np.linalg.norm(dv, axis=1, keepdims=True)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    i, j = i.ravel()[None, :, None], j.ravel()[None, :, None]
    c0 = corner[:, None, :] + i * du[:, None, :] + j * dv[:, None, :] + (gu + gv)[:, None, :]
    a = np.broadcast_to((du - 2 * gu)[:, None, :], c0.shape)
    b = np.broadcast_to((dv - 2 * gv)[:, None, :], c0.shape)
    return quads(c0.reshape(-1, 3), a.reshape(-1, 3), b.reshape(-1, 3))


#: The octahedron's corners (+x, -x, +y, -y, +z, -z) and its 8 faces, wound outward.
_OCTA_VERTS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_OCTA_FACES = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]],
                       np.int64)


def octahedra(centre, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed octahedra of circumradius ``radius`` around ``centre`` (N, 3): 8 triangles each, every
    normal pointing away from the centre (a small bulb emitting on all sides)."""
    centre = np.atleast_2d(np.asarray(centre, np.float64))
    return _stack(centre[:, None, :] + radius * _OCTA_VERTS[None], _OCTA_FACES, len(centre))
