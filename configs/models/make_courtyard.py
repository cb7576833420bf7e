"""Writes courtyard.obj/.mtl: a ground, two walls, boxes and a sphere for sun-and-sky renders.

Run from this folder: ``python make_courtyard.py``. Units: metres, y up.
"""

import numpy as np
import trimesh


def main():
    parts = []  # (mesh, material name)
    ground = trimesh.creation.box(extents=[12.0, 0.1, 12.0])
    ground.apply_translation([0, -0.05, 0])
    parts.append((ground, "ground"))
    wall = trimesh.creation.box(extents=[6.0, 3.0, 0.2])
    wall.apply_translation([0, 1.5, -3.0])
    parts.append((wall, "wall"))
    wall2 = trimesh.creation.box(extents=[0.2, 2.0, 4.0])
    wall2.apply_translation([-3.0, 1.0, -1.0])
    parts.append((wall2, "wall"))
    for (x, z, s, h) in [(-1.2, 0.2, 0.8, 0.8), (1.4, -0.8, 0.9, 1.6), (0.3, 1.6, 0.5, 0.5)]:
        b = trimesh.creation.box(extents=[s, h, s])
        b.apply_translation([x, h / 2, z])
        parts.append((b, "block"))
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.6)
    sphere.apply_translation([0.0, 0.6, -0.6])
    parts.append((sphere, "sphere"))

    mtl = {
        "ground": ("0.45 0.42 0.38", "0 0 0", 0),
        "wall": ("0.7 0.68 0.64", "0 0 0", 0),
        "block": ("0.6 0.25 0.15", "0 0 0", 0),
        "sphere": ("0.3 0.35 0.5", "0.3 0.3 0.3", 80),
    }
    lines = ["# courtyard: written by make_courtyard.py", "mtllib courtyard.mtl"]
    offset = 1
    for mesh, mat in parts:
        lines.append(f"o {mat}")
        lines.append(f"usemtl {mat}")
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in np.asarray(mesh.vertices)]
        lines += [f"f {a + offset} {b + offset} {c + offset}" for a, b, c in np.asarray(mesh.faces)]
        offset += len(mesh.vertices)
    with open("courtyard.obj", "w") as f:
        f.write("\n".join(lines) + "\n")
    with open("courtyard.mtl", "w") as f:
        for name, (kd, ks, ns) in mtl.items():
            f.write(f"newmtl {name}\nKd {kd}\nKs {ks}\nNs {ns}\n\n")


if __name__ == "__main__":
    main()
