"""A seeded procedural kitchen: a 5 x 4 x 2.7 m room down to 4 mm beads and bolts, lit by small
area lights.

Room interior x in [0, W], y in [0, H], z in [0, D] (metres); walls, floor and ceiling are 0.1 m thick
boxes outside it. Along the back wall (z = 0): base cabinets with a glossy worktop and wall cabinets
whose undersides carry an LED strip of ``LED_SEGMENTS`` quads. Left wall (x = 0): a window, an
emissive quad of sky radiance split into panes (only where the wall is exterior). Right wall (x = W):
shelves with books and small items. Centre: a table with plates and four chairs. Ceiling: a 4 x 3 grid
of LED panels, each 3 x 3 emitting tiles. Small items (cups, bowls, stacks of saucers, jars,
bottles, fruit, utensils, bolts, beads) sit in 12 cm cells on the worktop, table, shelves and
wall-cabinet tops; their number grows with the triangle budget, and the curved solids' tessellation
takes up the rest of it (``shapes.resolutions``), so the scene hits the requested triangle count to
a few triangles.

Emitters are one-sided quads 1 mm off the surface they are mounted on, facing into the room. All
other parts are closed solids (watertight). Doorways (0.9 x 2.1 m) open the side walls near the
front (z in [D - 1.3, D - 0.4]) and the front wall at its centre, for ``rooms.py``'s building.
"""

from __future__ import annotations

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.scene.registry import SCENES, SEED, triangles as triangles_param
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.shapes import K_RANGE, Curved, PartList, faces_of, pose, material as _m

W, D, H, T = 5.0, 4.0, 2.7, 0.1
DOOR_W, DOOR_H = 0.9, 2.1
SIDE_DOOR = (D - 1.3, D - 0.4)  # z range of the side-wall doorways
CELL = 0.12  # m, the grid small items are placed on
LED_SEGMENTS = 40
PANEL_TILES = 3  # per side of a ceiling panel
RESOLUTION = (512, 384)
MIN_TRIANGLES = 10_000
TRIANGLES_PER_CLUSTER = 3000


#: Surface name -> material (``scene.materials`` overrides any field by name).
PALETTE = {
    "floor": _m((0.42, 0.38, 0.33), (0.12, 0.12, 0.12), 40),
    "wall": _m((0.74, 0.72, 0.67)),
    "ceiling": _m((0.80, 0.80, 0.78)),
    "cabinet": _m((0.40, 0.27, 0.16), (0.05, 0.05, 0.05), 20),
    "cabinet_door": _m((0.45, 0.55, 0.50), (0.10, 0.10, 0.10), 60),
    "worktop": _m((0.16, 0.16, 0.17), (0.30, 0.30, 0.30), 300),
    "metal": _m((0.08, 0.08, 0.08), (0.60, 0.60, 0.60), 400),
    "wood": _m((0.50, 0.32, 0.17), (0.08, 0.08, 0.08), 30),
    "shelf": _m((0.62, 0.52, 0.40)),
    "frame": _m((0.85, 0.85, 0.83)),
    "ceramic": _m((0.80, 0.79, 0.76), (0.15, 0.15, 0.15), 150),
    "ceramic_blue": _m((0.15, 0.25, 0.55), (0.15, 0.15, 0.15), 150),
    "ceramic_red": _m((0.60, 0.12, 0.08), (0.15, 0.15, 0.15), 150),
    "glass": _m((0.25, 0.30, 0.27), (0.40, 0.40, 0.40), 600),
    "bottle": _m((0.06, 0.20, 0.08), (0.40, 0.40, 0.40), 600),
    "fruit_red": _m((0.55, 0.06, 0.04), (0.10, 0.10, 0.10), 40),
    "fruit_orange": _m((0.80, 0.40, 0.05), (0.05, 0.05, 0.05), 20),
    "fruit_green": _m((0.30, 0.55, 0.10), (0.10, 0.10, 0.10), 40),
    "book_red": _m((0.50, 0.10, 0.08)),
    "book_blue": _m((0.10, 0.18, 0.45)),
    "book_green": _m((0.12, 0.35, 0.15)),
    "book_cream": _m((0.80, 0.75, 0.60)),
    "book_black": _m((0.05, 0.05, 0.05), (0.05, 0.05, 0.05), 30),
    "bead": _m((0.70, 0.55, 0.20), (0.30, 0.30, 0.30), 200),
    "ceiling_light": _m((0.8, 0.8, 0.8), emission=(4.0, 3.8, 3.4)),
    "led_strip": _m((0.8, 0.8, 0.8), emission=(14.0, 12.0, 9.0)),
    "window": _m((0.8, 0.8, 0.8), emission=(2.4, 2.8, 3.4)),
}
BOOKS = ("book_red", "book_blue", "book_green", "book_cream", "book_black")
CERAMICS = ("ceramic", "ceramic_blue", "ceramic_red")
FRUITS = ("fruit_red", "fruit_orange", "fruit_green")
#: Small-item kinds and their probabilities.
CLUSTERS = {"cup": 0.14, "bowl": 0.08, "saucers": 0.08, "jar": 0.12, "bottle": 0.08, "fruit": 0.12, "utensils": 0.12,
            "bolts": 0.13, "beads": 0.13}

TABLE_CENTRE = (0.5 * W, 2.0)
TABLE_SIZE = (1.6, 0.9)
TABLE_H = 0.76
SHELF_Z = (0.9, 2.5)
SHELF_DEPTH = 0.32
SHELF_LEVELS = (0.35, 0.75, 1.15, 1.55, 1.95)
BOOK_LEVELS = (1, 3)
BASE_H, WORKTOP_H, BASE_D = 0.86, 0.04, 0.6
WALL_CAB_Y, WALL_CAB_D = (1.45, 2.2), 0.35
RUN_X = (0.0, 4.4)


def camera() -> Camera:
    """Near the front wall, eye height, looking at the worktop past the table."""
    return Camera((0.42 * W, 1.65, D - 0.2), (0.58 * W, 0.95, 0.6), (0, 1, 0), 62.0, *RESOLUTION)


def _wall(parts: PartList, lo, hi, axis: int, door) -> None:
    """A wall box [lo, hi]; ``door`` = (a0, a1) along ``axis`` cuts a DOOR_H doorway into it."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if door is None:
        parts.box(lo, hi, "wall")
        return
    a0, a1 = door
    for x0, x1 in ((lo[axis], a0), (a1, hi[axis])):
        l, h = lo.copy(), hi.copy()
        l[axis], h[axis] = x0, x1
        parts.box(l, h, "wall")
    l, h = lo.copy(), hi.copy()
    l[axis], h[axis], l[1] = a0, a1, DOOR_H
    parts.box(l, h, "wall")


def shell(parts: PartList, doors=(), window: bool = True) -> None:
    """Floor, ceiling, walls (doorways in the sides named in ``doors``: left, right, front), window."""
    parts.box((-T, -T, -T), (W + T, 0, D + T), "floor")
    parts.box((-T, H, -T), (W + T, H + T, D + T), "ceiling")
    parts.box((0, 0, -T), (W, H, 0), "wall")
    _wall(parts, (0, 0, D), (W, H, D + T), 0, (0.5 * (W - DOOR_W), 0.5 * (W + DOOR_W)) if "front" in doors else None)
    _wall(parts, (-T, 0, -T), (0, H, D + T), 2, SIDE_DOOR if "left" in doors else None)
    _wall(parts, (W, 0, -T), (W + T, H, D + T), 2, SIDE_DOOR if "right" in doors else None)
    if window:
        z0, z1, y0, y1 = 0.9, 2.5, 0.9, 2.1
        parts.quads((0.001, y0, z0), (0, y1 - y0, 0), (0, 0, z1 - z0), 3, 4, "window", gap=0.02)
        parts.box((0, y0 - 0.04, z0 - 0.05), (0.16, y0, z1 + 0.05), "frame")
        parts.box((0, y1, z0 - 0.05), (0.04, y1 + 0.05, z1 + 0.05), "frame")
        for z in (z0 - 0.05, z1):
            parts.box((0, y0, z), (0.04, y1, z + 0.05), "frame")
    for i in range(4):
        for j in range(3):
            cx, cz, s = W * (i + 0.5) / 4, D * (j + 0.5) / 3, 0.6
            rim = s / 2 + 0.02
            parts.box((cx - rim, H - 0.03, cz - rim), (cx + rim, H, cz + rim), "frame")
            parts.quads((cx - s / 2, H - 0.031, cz - s / 2), (s, 0, 0), (0, 0, s), PANEL_TILES, PANEL_TILES,
                        "ceiling_light", gap=0.008)


def cabinets(parts: PartList) -> list:
    """Base and wall cabinets along the back wall, worktop, LED strip; returns item surfaces."""
    x0, x1 = RUN_X
    n = 6
    xs = np.linspace(x0, x1, n + 1)
    for a, b in zip(xs[:-1], xs[1:]):
        parts.box((a + 0.002, 0, 0), (b - 0.002, BASE_H, BASE_D - 0.02), "cabinet")
        parts.box((a + 0.004, 0.1, BASE_D - 0.02), (b - 0.004, BASE_H - 0.02, BASE_D), "cabinet_door")
        parts.box((a + 0.08, BASE_H - 0.1, BASE_D), (a + 0.22, BASE_H - 0.088, BASE_D + 0.02), "metal")
        y0, y1 = WALL_CAB_Y
        parts.box((a + 0.002, y0, 0), (b - 0.002, y1, WALL_CAB_D - 0.02), "cabinet")
        parts.box((a + 0.004, y0 + 0.004, WALL_CAB_D - 0.02), (b - 0.004, y1 - 0.004, WALL_CAB_D), "cabinet_door")
        parts.box((b - 0.05, y0 + 0.04, WALL_CAB_D), (b - 0.038, y0 + 0.18, WALL_CAB_D + 0.02), "metal")
    top = BASE_H + WORKTOP_H
    parts.box((x0, BASE_H, 0), (x1 + 0.02, top, BASE_D + 0.03), "worktop")
    parts.quads((x0 + 0.05, WALL_CAB_Y[0] - 0.001, 0.24), (x1 - x0 - 0.1, 0, 0), (0, 0, 0.05), LED_SEGMENTS, 1,
                "led_strip", gap=0.004)
    return [((x0 + 0.05, 0.05), (x1 - 0.05, BASE_D - 0.03), top),
            ((x0 + 0.05, 0.03), (x1 - 0.05, WALL_CAB_D - 0.05), WALL_CAB_Y[1])]


def table(parts: PartList, curved: list) -> list:
    """Table, plates and four chairs; returns the table top as an item surface (minus the plates)."""
    cx, cz = TABLE_CENTRE
    sx, sz = TABLE_SIZE
    parts.box((cx - sx / 2, TABLE_H - 0.04, cz - sz / 2), (cx + sx / 2, TABLE_H, cz + sz / 2), "wood")
    for dx in (-1, 1):
        for dz in (-1, 1):
            p = (cx + dx * (sx / 2 - 0.08), 0.0, cz + dz * (sz / 2 - 0.08))
            curved.append(Curved("cylinder", (0.03, TABLE_H - 0.04), pose(p), "wood", _w(TABLE_H)))
            # chair on this side, facing the table
            chx, chz = cx + dx * 0.4, cz + dz * (sz / 2 + 0.3)
            parts.box((chx - 0.21, 0.43, chz - 0.21), (chx + 0.21, 0.46, chz + 0.21), "wood")
            for ex in (-1, 1):
                for ez in (-1, 1):
                    lx, lz = chx + ex * 0.18, chz + ez * 0.18
                    parts.box((lx - 0.018, 0, lz - 0.018), (lx + 0.018, 0.43, lz + 0.018), "wood")
            bz = chz + dz * 0.19
            parts.box((chx - 0.21, 0.46, bz - 0.015), (chx + 0.21, 0.9, bz + 0.015), "wood")
            plate = (cx + dx * 0.4, TABLE_H, cz + dz * 0.22)
            curved.append(Curved("cylinder", (0.12, 0.015), pose(plate), "ceramic", _w(0.24)))
    return [((cx - sx / 2 + 0.04, cz - 0.08), (cx + sx / 2 - 0.04, cz + 0.08), TABLE_H),
            ((cx - sx / 2 + 0.04, cz - sz / 2 + 0.04), (cx - 0.55, cz + sz / 2 - 0.04), TABLE_H),
            ((cx + 0.55, cz - sz / 2 + 0.04), (cx + sx / 2 - 0.04, cz + sz / 2 - 0.04), TABLE_H)]


def shelves(parts: PartList, rng: np.random.Generator) -> list:
    """Shelf unit on the right wall with rows of books; returns the free boards as item surfaces."""
    z0, z1 = SHELF_Z
    x0 = W - SHELF_DEPTH
    for z in (z0, z1 - 0.02):
        parts.box((x0, 0, z), (W, SHELF_LEVELS[-1] + 0.025, z + 0.02), "shelf")
    free = []
    for level, y in enumerate(SHELF_LEVELS):
        parts.box((x0, y, z0 + 0.02), (W, y + 0.025, z1 - 0.02), "shelf")
        top = y + 0.025
        if level in BOOK_LEVELS:
            z = z0 + 0.03
            while True:
                width = rng.uniform(0.015, 0.05)
                if z + width > z1 - 0.03:
                    break
                height, depth = rng.uniform(0.15, 0.3), rng.uniform(0.13, 0.24)
                parts.box((W - 0.01 - depth, top, z), (W - 0.01, top + height, z + width),
                          BOOKS[rng.integers(len(BOOKS))])
                z += width + (rng.uniform(0.002, 0.08) if rng.random() < 0.1 else 0.002)
        else:
            free.append(((x0 + 0.02, z0 + 0.04), (W - 0.02, z1 - 0.04), top))
    return free


def _w(extent: float) -> float:
    """Tessellation weight of a solid of this extent (metres): finer for larger objects."""
    return float(np.sqrt(extent / 0.1))


def _cells(surfaces) -> np.ndarray:
    """(C, 3) cell centres (x, y_top, z) of CELL squares inside each surface ((x0, z0), (x1, z1), y)."""
    out = []
    for (x0, z0), (x1, z1), y in surfaces:
        nx, nz = int((x1 - x0) // CELL), int((z1 - z0) // CELL)
        if nx < 1 or nz < 1:
            continue
        i, j = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
        out.append(np.stack([x0 + (i.ravel() + 0.5) * CELL, np.full(i.size, y), z0 + (j.ravel() + 0.5) * CELL], 1))
    return np.concatenate(out)


def _cluster(kind: str, p, rng: np.random.Generator, parts: PartList, curved: list) -> None:
    """One cell's items, standing on the surface at p = (x, y, z)."""
    x, y, z = p
    r = lambda a, b: float(rng.uniform(a, b))  # noqa: E731
    turn = r(0, 2 * np.pi)
    if kind == "cup":
        rad, h = r(0.03, 0.04), r(0.07, 0.1)
        mat = CERAMICS[rng.integers(3)]
        curved.append(Curved("annulus", (rad - 0.004, rad, h), pose((x, y, z)), mat, _w(h)))
        curved.append(Curved("cylinder", (rad - 0.0041, 0.006), pose((x, y, z)), mat, _w(2 * rad)))
        hx, hz = x + (rad + 0.012) * np.cos(turn), z - (rad + 0.012) * np.sin(turn)
        curved.append(Curved("torus", (0.02, 0.005), pose((hx, y + 0.55 * h, hz), turn, np.pi / 2), mat, _w(0.05)))
    elif kind == "bowl":
        rad, h = r(0.045, 0.058), r(0.04, 0.06)
        mat = CERAMICS[rng.integers(3)]
        curved.append(Curved("annulus", (rad - 0.005, rad, h), pose((x, y, z)), mat, _w(2 * rad)))
        curved.append(Curved("cylinder", (rad - 0.0051, 0.008), pose((x, y, z)), mat, _w(2 * rad)))
    elif kind == "saucers":
        rad, mat = r(0.045, 0.058), CERAMICS[rng.integers(3)]
        for i in range(rng.integers(2, 9)):
            curved.append(Curved("cylinder", (rad, 0.009), pose((x, y + 0.0092 * i, z)), mat, _w(2 * rad)))
    elif kind == "jar":
        rad, h = r(0.025, 0.045), r(0.07, 0.16)
        curved.append(Curved("cylinder", (rad, h), pose((x, y, z)), "glass", _w(h)))
        curved.append(Curved("cylinder", (rad + 0.002, 0.014), pose((x, y + h, z)), "metal", _w(2 * rad)))
    elif kind == "bottle":
        rad, h = r(0.025, 0.035), r(0.17, 0.22)
        curved.append(Curved("cylinder", (rad, h), pose((x, y, z)), "bottle", _w(h)))
        curved.append(Curved("cylinder", (0.011, 0.08), pose((x, y + h, z)), "bottle", _w(0.08)))
        curved.append(Curved("cylinder", (0.013, 0.015), pose((x, y + h + 0.08, z)), "metal", _w(0.026)))
    elif kind == "fruit":
        rad = r(0.028, 0.045)
        curved.append(Curved("sphere", (rad,), pose((x, y + rad, z)), FRUITS[rng.integers(3)], _w(2 * rad)))
    elif kind == "utensils":
        for k in range(rng.integers(1, 4)):
            a = turn + r(-0.3, 0.3)
            dx, dz = 0.03 * (k - 1) * np.sin(a), 0.03 * (k - 1) * np.cos(a)
            centre = np.array([x + dx, y + 0.0015, z + dz])
            m = pose(centre, a)
            length = r(0.1, 0.16)
            half = np.array([length / 2, 0.0015, 0.006])
            parts.box(centre - half, centre + half, "metal", rot_y=a)
            bowl = m @ pose((length / 2 + 0.015, 0.003, 0)) @ np.diag([1.3, 0.35, 0.9, 1.0])
            curved.append(Curved("sphere", (0.016,), bowl, "metal", _w(0.04)))
    elif kind == "bolts":
        for _ in range(rng.integers(3, 8)):
            bx, bz, a = x + r(-0.04, 0.04), z + r(-0.04, 0.04), r(0, 2 * np.pi)
            head, length = r(0.0025, 0.004), r(0.01, 0.03)
            base = pose((bx, y + head, bz), a, np.pi / 2)
            curved.append(Curved("cylinder", (head, 0.003), base, "metal", _w(2 * head)))
            curved.append(Curved("cylinder", (0.45 * head, length), base @ pose((0, 0.003, 0)), "metal", _w(length)))
    elif kind == "beads":
        for _ in range(rng.integers(4, 10)):
            rad = r(0.002, 0.004)
            curved.append(Curved("sphere", (rad,), pose((x + r(-0.04, 0.04), y + rad, z + r(-0.04, 0.04))),
                                 "bead", _w(2 * rad)))
    else:
        raise ValueError(kind)


def kitchen_parts(triangles: int, seed, doors=(), window: bool = True) -> PartList:
    """The kitchen's parts (module docstring) with about ``triangles`` triangles in all.

    seed : anything ``np.random.default_rng`` takes (int, or a sequence for a room of a building)
    doors : subset of ("left", "right", "front"): walls with a doorway
    """
    rng = np.random.default_rng(seed)
    parts, curved = PartList(), []
    shell(parts, doors, window)
    surfaces = cabinets(parts) + table(parts, curved) + shelves(parts, rng)
    cells = _cells(surfaces)
    n = int(np.clip(triangles // TRIANGLES_PER_CLUSTER, len(CLUSTERS), len(cells)))
    chosen = cells[np.sort(rng.permutation(len(cells))[:n])]
    kinds = list(CLUSTERS)
    # every kind at least once (the size range needs the smallest items), the rest drawn by weight
    which = np.concatenate([np.arange(len(kinds)),
                            rng.choice(len(kinds), n - len(kinds), p=list(CLUSTERS.values()))])
    for p, k in zip(chosen, rng.permutation(which)):
        _cluster(kinds[k], p, rng, parts, curved)
    budget = triangles - parts.n_faces
    minimum = sum(_min_faces(c) for c in curved)
    if budget < minimum:
        raise LightcutsError(f"scene.procedural.triangles: {triangles} is below this scene's minimum "
                             f"({parts.n_faces + minimum} at the coarsest tessellation)")
    parts.curved(curved, budget)
    return parts


def _min_faces(c: Curved) -> int:
    return faces_of(c.kind, K_RANGE[c.kind][0])


@SCENES.register("kitchen", params={"triangles": triangles_param(200_000), "seed": SEED}, resolution=RESOLUTION,
                 description="a seeded kitchen down to 4 mm beads, lit by 160 small area lights")
def kitchen_scene(params: dict, materials=None, exhibits=(), offsets=(), name: str = "kitchen") -> Scene:
    """The kitchen (module docstring) with its camera; ``materials``: overrides by ``PALETTE`` name."""
    return kitchen_parts(params["triangles"], params["seed"]).to_scene(PALETTE, materials, camera(), name)
