"""A lit gallery room with one plinth per exhibit mesh.

Room interior x in [0, GW], y in [0, GH], z in [0, GD] (metres), glossy floor, white walls. Lights:
a 5 x 3 grid of ceiling panels (2 x 2 tiles each), a spotlight tile group above every plinth, and a
wall-washer strip of ``WASHER_SEGMENTS`` quads along the top of the back wall. Exhibits stand in rows
of up to ``PER_ROW`` plinths: each mesh (already scaled, rotated and translated by its
``scene.meshes`` entry) is moved so that its bounding box's bottom centre sits on its plinth's top
centre, then shifted by its entry's ``translate`` (an offset from that spot). A plinth is a white box
0.15 m wider than its exhibit's footprint, as high as brings the exhibit's top near eye height.
"""

from __future__ import annotations

import numpy as np

from lightcuts.scene.loaders import concatenate_scenes
from lightcuts.scene.registry import SCENES
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.shapes import PartList, material as _m

GW, GH, GD, T = 10.0, 3.6, 7.0, 0.1
PER_ROW = 5
SPACING = 1.5  # m between plinth centres in a row
ROW_Z = (2.2, 4.2)
WASHER_SEGMENTS = 24
RESOLUTION = (512, 384)


PALETTE = {
    "floor": _m((0.25, 0.24, 0.23), (0.25, 0.25, 0.25), 120),
    "wall": _m((0.78, 0.77, 0.74)),
    "ceiling": _m((0.80, 0.80, 0.80)),
    "plinth": _m((0.82, 0.81, 0.78), (0.04, 0.04, 0.04), 20),
    "frame": _m((0.15, 0.15, 0.15)),
    "ceiling_light": _m((0.8, 0.8, 0.8), emission=(3.0, 3.0, 2.9)),
    "spot": _m((0.8, 0.8, 0.8), emission=(40.0, 36.0, 30.0)),
    "washer": _m((0.8, 0.8, 0.8), emission=(12.0, 11.0, 10.0)),
}


def plinth_spots(n: int) -> np.ndarray:
    """(n, 2) (x, z) centres of the plinths: rows of up to PER_ROW, back row first."""
    out = []
    for i in range(n):
        row, col = divmod(i, PER_ROW)
        in_row = min(PER_ROW, n - row * PER_ROW)
        x = 0.5 * GW + (col - 0.5 * (in_row - 1)) * SPACING
        z = ROW_Z[0] + row * (ROW_Z[1] - ROW_Z[0])
        out.append((x + (0.4 if row % 2 else 0.0), z))
    return np.array(out, np.float64).reshape(-1, 2)


def gallery_parts(footprints: np.ndarray) -> PartList:
    """The room, its lights and one plinth per exhibit; ``footprints`` (E, 3) the exhibits' bounding
    box sizes (metres)."""
    parts = PartList()
    parts.box((-T, -T, -T), (GW + T, 0, GD + T), "floor")
    parts.box((-T, GH, -T), (GW + T, GH + T, GD + T), "ceiling")
    parts.box((0, 0, -T), (GW, GH, 0), "wall")
    parts.box((0, 0, GD), (GW, GH, GD + T), "wall")
    parts.box((-T, 0, -T), (0, GH, GD + T), "wall")
    parts.box((GW, 0, -T), (GW + T, GH, GD + T), "wall")
    for i in range(5):
        for j in range(3):
            cx, cz, s = GW * (i + 0.5) / 5, GD * (j + 0.5) / 3, 0.8
            parts.box((cx - s / 2 - 0.03, GH - 0.04, cz - s / 2 - 0.03), (cx + s / 2 + 0.03, GH, cz + s / 2 + 0.03),
                      "frame")
            parts.quads((cx - s / 2, GH - 0.041, cz - s / 2), (s, 0, 0), (0, 0, s), 2, 2, "ceiling_light", gap=0.01)
    parts.box((0.3, GH - 0.35, 0), (GW - 0.3, GH - 0.3, 0.12), "frame")
    parts.quads((0.35, GH - 0.351, 0.02), (GW - 0.7, 0, 0), (0, 0, 0.08), WASHER_SEGMENTS, 1, "washer", gap=0.01)
    for (x, z), size in zip(plinth_spots(len(footprints)), np.asarray(footprints, float).reshape(-1, 3)):
        width, height = plinth_size(size)
        parts.box((x - width / 2, 0, z - width / 2), (x + width / 2, height, z + width / 2), "plinth")
        s = 0.3
        parts.box((x - s / 2 - 0.02, GH - 0.03, z - s / 2 - 0.02), (x + s / 2 + 0.02, GH, z + s / 2 + 0.02), "frame")
        parts.quads((x - s / 2, GH - 0.031, z - s / 2), (s, 0, 0), (0, 0, s), 2, 2, "spot", gap=0.005)
    return parts


def plinth_size(size) -> tuple[float, float]:
    """(width, height) metres of the plinth under an exhibit of bounding-box ``size`` (3,)."""
    return max(0.4, float(max(size[0], size[2])) + 0.15), float(np.clip(1.5 - size[1], 0.3, 1.0))


def gallery_scene(exhibits: list[Scene], offsets: list, overrides=None, name: str = "gallery") -> Scene:
    """The room (``gallery_parts``) with ``exhibits`` after its triangles, each placed as the module
    docstring says (``offsets`` (E, 3): the entries' ``translate``)."""
    bounds = [m.bounds for m in exhibits]
    sizes = np.array([hi - lo for lo, hi in bounds]).reshape(-1, 3)
    room = gallery_parts(sizes).to_scene(PALETTE, overrides, name=name)
    placed = []
    for (x, z), mesh, (lo, hi), offset in zip(plinth_spots(len(exhibits)), exhibits, bounds, offsets):
        top = np.array([x, plinth_size(hi - lo)[1], z])
        shift = top - [0.5 * (lo[0] + hi[0]), lo[1], 0.5 * (lo[2] + hi[2])] + np.asarray(offset)
        placed.append(mesh.translated(shift))
    return concatenate_scenes([room, *placed], camera=camera(len(exhibits)), name=name)


def camera(n: int) -> Camera:
    """From the front of the room at eye height, looking at the plinths."""
    rows = max(1, -(-n // PER_ROW))
    z = ROW_Z[0] + 0.5 * (rows - 1) * (ROW_Z[1] - ROW_Z[0])
    return Camera((0.5 * GW, 1.7, GD - 0.3), (0.5 * GW, 1.0, z), (0, 1, 0), 60.0, *RESOLUTION)


@SCENES.register("gallery", exhibits=True, resolution=RESOLUTION)
def _gallery(params: dict, materials=None, exhibits=(), offsets=(), name: str = "gallery") -> Scene:
    """A lit gallery room with the config's meshes on plinths (``gallery_scene``)."""
    return gallery_scene(list(exhibits), list(offsets), materials, name)
