"""Area lights placed by a config (``scene.emitters``): quads and discs, one or a grid of them, as
emitting triangles that join the scene like any emissive mesh (lights.direct samples them, particle
paths start on them, the Mitsuba export sees them).

A quad of size [w, h] is two triangles, a disc a fan of ``segments`` triangles (its area is the
polygon's, slightly less than pi r^2); both are wound so that their normal (right-hand rule) is
the entry's ``normal``, the side they emit on. The in-plane frame: ``e_u = normalize(normal x up)``
(w runs along it), ``e_v = normal x e_u``.
"""

from __future__ import annotations

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.scene.scene import Scene


def _frame(normal, up, key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    if up is None:
        up = [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [0.0, 0.0, 1.0]
    u = np.cross(n, np.asarray(up, np.float64))
    if np.linalg.norm(u) <= 1e-9 * max(np.linalg.norm(up), 1e-300):
        raise LightcutsError(f"{key}.up: zero or parallel to the normal")
    u /= np.linalg.norm(u)
    return n, u, np.cross(n, u)


def _centres(entry) -> np.ndarray:
    """(K, 3) centres: the position, or the grid's cell centres (x fastest)."""
    if entry.grid is None:
        return np.asarray([entry.position], np.float64)
    g = entry.grid
    lo, hi = np.asarray(g.lo, np.float64), np.asarray(g.hi, np.float64)
    axes = [lo[a] + (np.arange(g.count[a]) + 0.5) * (hi[a] - lo[a]) / g.count[a] for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def emitter_scene(entry, key: str = "scene.emitters.0") -> Scene:
    """The triangles of one ``scene.emitters`` entry (lightcuts.config.schema.AreaLight) as a Scene."""
    _, u, v = _frame(entry.normal, entry.up, key)
    if entry.shape == "quad":
        a, b = 0.5 * entry.size[0] * u, 0.5 * entry.size[1] * v
        shape = np.stack([-a - b, a - b, a + b, -a + b])
        tris = np.array([[0, 1, 2], [0, 2, 3]])
    else:
        theta = 2.0 * np.pi * np.arange(entry.segments) / entry.segments
        ring = entry.radius * (np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v)
        shape = np.concatenate([np.zeros((1, 3)), ring])
        k = np.arange(entry.segments)
        tris = np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % entry.segments], axis=1)
    centres = _centres(entry)
    vertices = (centres[:, None, :] + shape[None, :, :]).reshape(-1, 3)
    faces = (tris[None, :, :] + len(shape) * np.arange(len(centres))[:, None, None]).reshape(-1, 3)
    if not np.all(np.isfinite(vertices)):
        raise LightcutsError(f"{key}: its vertices are not finite")
    scene = Scene(vertices, faces, albedo=entry.albedo, specular=0.0, exponent=0.0, emission=entry.radiance,
                  name=key)
    scene.check_emission(key)
    return scene
