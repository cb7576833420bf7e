"""Writes knot.obj (a trefoil-knot tube) and vase.obj (a fluted vase of revolution): the gallery's
default exhibits. Run from this folder: ``python make_gallery_models.py``. Units: metres, y up;
each model stands on y = 0, about 0.5 m tall; no materials (the config assigns them).
"""

import numpy as np
import trimesh


def trefoil(n_along=180, n_around=12, tube=0.045):
    """A closed tube around the trefoil knot ((sin t + 2 sin 2t), (cos t - 2 cos 2t), -sin 3t)."""
    t = np.linspace(0, 2 * np.pi, n_along, endpoint=False)
    c = np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], 1) * 0.08
    d = np.stack([np.cos(t) + 4 * np.cos(2 * t), -np.sin(t) + 4 * np.sin(2 * t), -3 * np.cos(3 * t)], 1)
    tangent = d / np.linalg.norm(d, axis=1, keepdims=True)
    normal = np.cross(tangent, [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    binormal = np.cross(tangent, normal)
    a = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    ring = np.cos(a)[None, :, None] * normal[:, None] + np.sin(a)[None, :, None] * binormal[:, None]
    vertices = (c[:, None] + tube * ring).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_along), np.arange(n_around), indexing="ij")
    p = i * n_around + j
    q = ((i + 1) % n_along) * n_around + j
    p1 = i * n_around + (j + 1) % n_around
    q1 = ((i + 1) % n_along) * n_around + (j + 1) % n_around
    faces = np.concatenate([np.stack([p, q, q1], -1).reshape(-1, 3), np.stack([p, q1, p1], -1).reshape(-1, 3)])
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    if mesh.volume < 0:
        mesh.invert()
    mesh.apply_translation([0, -mesh.bounds[0, 1], 0])
    return mesh


def vase(n_profile=40, sections=48):
    """A fluted vase: a revolved profile, its radius rippled with 12 flutes."""
    y = np.linspace(0, 0.5, n_profile)
    r = 0.09 + 0.06 * np.sin(np.pi * y / 0.5 * 1.3) ** 2 - 0.04 * (y / 0.5) ** 3
    linestring = np.column_stack([np.concatenate([[0], r, [0]]), np.concatenate([[0], y, [0.5]])])
    mesh = trimesh.creation.revolve(linestring, sections=sections)
    theta = np.arctan2(mesh.vertices[:, 1], mesh.vertices[:, 0])
    mesh.vertices[:, :2] *= (1 + 0.04 * np.cos(12 * theta))[:, None]
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def write(mesh, path, comment):
    lines = [f"# {comment}: written by make_gallery_models.py"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in np.asarray(mesh.vertices)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(mesh.faces)]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def main():
    write(trefoil(), "knot.obj", "trefoil knot tube")
    write(vase(), "vase.obj", "fluted vase")


if __name__ == "__main__":
    main()
