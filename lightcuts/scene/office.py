"""An open-plan office floor lit by a large grid of ceiling panels, with ``emitters`` emitting
triangles (10^3 to 4 x 10^6).

Layout (metres, y up): the floor x in [0, W], z in [0, D], ceiling at ``H``; W and D are ``nx`` and
``nz`` panel pitches (``PANEL_PITCH``), so the floor grows with the panel grid (31 x 24 m at 10^3
emitters, 101 x 70 m from 10^5 on). Solid walls at both ends (x = 0, x = W), glazing with mullions
along both sides (z = 0, z = D), the night black outside. Columns every 7.2 m in lines either side
of a 2.4 m main aisle along x at z = D / 2. Desk pods on a 4.8 x 3.6 m grid, clear of the columns
and of the aisle: 4 desks facing in pairs across a partition, each desk with a monitor and a chair
(pulled out and turned at random); a seeded tenth of the pods are missing.

Emitters: a 0.6 x 0.6 m LED panel in a frame at the centre of a ceiling cell, its face 31 mm below
the ceiling, facing down (normal -y), split into ``ku`` x ``kv`` tiles (``ku`` = ``kv`` or ``kv +
1``); the few cells left over by the grid hold a vent. :func:`grid` chooses the panels (about 4
sqrt(emitters), at most ``MAX_PANELS``) and their tiles so that the 2 ku kv triangles of each make
``emitters`` to within one panel's. A panel's power does not depend on its tiles (the tiles'
radiance makes up for the gaps between them); panels vary by 5% and a seeded 2% are dimmed to 30%.

The camera stands at eye height at the x = 0 end of the main aisle, looking down it: the nearest
panel is a metre away, the farthest about 100 m. Non-emitting geometry stays below about 110,000
triangles.
"""

from __future__ import annotations

import math

import numpy as np

from lightcuts.scene.batches import boxes, quads, tiles
from lightcuts.scene.registry import SCENES, SEED, emitters as emitters_param
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.shapes import PartList, material as _m

H, PANEL_PITCH, PANEL, PANEL_DROP, TILE_GAP = 2.8, 2.4, 0.6, 0.031, 0.002
MIN_PANELS, MAX_PANELS, ASPECT = 64, 1200, 1.5
COLUMN_PITCH, COLUMN = 7.2, 0.5
POD_PITCH, POD, AISLE = (4.8, 3.6), (3.2, 1.6), 2.4
MULLION_PITCH = 1.5
RESOLUTION = (192, 128)


#: Surface name -> material (``scene.materials`` overrides any field by name); a panel's radiance
#: is ``panel``'s emission times its own factor.
PALETTE = {
    "floor": _m((0.32, 0.31, 0.30), (0.06, 0.06, 0.06), 30),
    "ceiling": _m((0.85, 0.85, 0.84)),
    "wall": _m((0.70, 0.69, 0.66)),
    "column": _m((0.75, 0.74, 0.72)),
    "glass": _m((0.02, 0.02, 0.025), (0.30, 0.30, 0.30), 500),
    "mullion": _m((0.30, 0.30, 0.32), (0.10, 0.10, 0.10), 40),
    "desk": _m((0.75, 0.73, 0.68), (0.05, 0.05, 0.05), 40),
    "partition": _m((0.22, 0.32, 0.42)),
    "monitor": _m((0.03, 0.03, 0.03), (0.30, 0.30, 0.30), 300),
    "chair": _m((0.08, 0.08, 0.10)),
    "frame": _m((0.90, 0.90, 0.90)),
    "vent": _m((0.45, 0.45, 0.47)),
    "panel": _m((0.8, 0.8, 0.8), emission=(5.0, 5.0, 4.7)),
}


def grid(emitters: int) -> tuple[int, int, int, int, int]:
    """(nx, nz, ku, kv, panels): the ceiling grid, each panel's tiles and how many cells hold a
    panel (the others a vent). ``panels`` = round(emitters / (2 ku kv)), so the emitting triangles
    2 panels ku kv are within a panel's of ``emitters``; ku kv is the closest of k^2, k (k + 1),
    (k + 1)^2 to emitters / (2 target), the target panel count 4 sqrt(emitters) (clipped to
    [MIN_PANELS, MAX_PANELS]); the grid about 3 : 2, fewer than nz cells spare."""
    target = float(np.clip(4.0 * math.sqrt(emitters), MIN_PANELS, MAX_PANELS))
    q = emitters / (2.0 * target)
    k = max(1, int(math.sqrt(q)))
    ku, kv = min(((k, k), (k + 1, k), (k + 1, k + 1)), key=lambda c: abs(c[0] * c[1] - q))
    panels = max(1, round(emitters / (2 * ku * kv)))
    nz = math.ceil(math.sqrt(panels / ASPECT))
    return math.ceil(panels / nz), nz, ku, kv, panels


def _cells(nx: int, nz: int) -> np.ndarray:
    """(nx nz, 2) centres (x, z) of the ceiling cells, x-major."""
    i, j = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    return np.stack([(i.ravel() + 0.5) * PANEL_PITCH, (j.ravel() + 0.5) * PANEL_PITCH], axis=1)


def _shell(parts: PartList, w: float, d: float) -> np.ndarray:
    """Floor, ceiling, end walls, glazing with mullions and columns; returns the columns' (C, 2)
    centres (x, z)."""
    parts.add(boxes([-0.3, -0.3, -0.3], [w + 0.3, 0.0, d + 0.3]), "floor")
    parts.add(boxes([-0.3, H, -0.3], [w + 0.3, H + 0.3, d + 0.3]), "ceiling")
    parts.add(boxes([[-0.3, 0, -0.3], [w, 0, -0.3]], [[0, H, d + 0.3], [w + 0.3, H, d + 0.3]]), "wall")
    parts.add(boxes([[0, 0, -0.06], [0, 0, d]], [[w, H, -0.04], [w, H, d + 0.02]]), "glass")
    xs = np.arange(MULLION_PITCH, w, MULLION_PITCH)
    lo = np.concatenate([np.stack([xs - 0.03, np.zeros_like(xs), np.full_like(xs, -0.04)], 1),
                         np.stack([xs - 0.03, np.zeros_like(xs), np.full_like(xs, d - 0.06)], 1)])
    parts.add(boxes(lo, lo + [0.06, H, 0.1]), "mullion")
    # columns in x every COLUMN_PITCH, in z in lines either side of the main aisle
    cx = np.arange(COLUMN_PITCH, w - 1.0, COLUMN_PITCH)
    half = np.arange(0.5 * (AISLE + COLUMN) + 0.3, 0.5 * d - 1.0, COLUMN_PITCH)
    cz = np.concatenate([0.5 * d - half[::-1], 0.5 * d + half])
    cols = np.stack([a.ravel() for a in np.meshgrid(cx, cz, indexing="ij")], axis=1).reshape(-1, 2)
    c3 = np.insert(cols, 1, 0.0, axis=1)
    parts.add(boxes(c3 - [COLUMN / 2, 0, COLUMN / 2], c3 + [COLUMN / 2, H, COLUMN / 2]), "column")
    return cols


def _pods(parts: PartList, rng: np.random.Generator, w: float, d: float, cols: np.ndarray) -> None:
    """Desk pods (module docstring): per pod a partition, per desk a top, a modesty panel, a monitor
    and a chair of seat, back and pedestal."""
    px = np.arange(0.5 * POD_PITCH[0], w - 0.5 * POD_PITCH[0] + 1e-9, POD_PITCH[0])
    pz = np.arange(0.5 * POD_PITCH[1], d - 0.5 * POD_PITCH[1] + 1e-9, POD_PITCH[1])
    centres = np.stack([a.ravel() for a in np.meshgrid(px, pz, indexing="ij")], axis=1)
    reach = np.array([0.5 * POD[0] + 0.4, 0.5 * POD[1] + 1.0])  # the pod with its chairs
    clear = np.abs(centres[:, 1] - 0.5 * d) > 0.5 * AISLE + reach[1]
    if len(cols):
        near = np.abs(centres[:, None, :] - cols[None, :, :]) < reach + 0.5 * COLUMN
        clear &= ~np.all(near, axis=2).any(axis=1)
    clear &= rng.random(len(centres)) >= 0.1
    c = centres[clear]
    if not len(c):
        return
    # partition along x through the pod's centre
    parts.add(boxes(np.stack([c[:, 0] - 0.5 * POD[0], np.zeros(len(c)), c[:, 1] - 0.02], 1),
                    np.stack([c[:, 0] + 0.5 * POD[0], np.full(len(c), 1.2), c[:, 1] + 0.02], 1)), "partition")
    sx, sz = (a.ravel() for a in np.meshgrid([-1.0, 1.0], [-1.0, 1.0], indexing="ij"))
    desk = np.repeat(c, 4, axis=0) + np.tile(np.stack([sx * 0.25 * POD[0], sz * 0.25 * POD[1]], 1), (len(c), 1))
    side = np.tile(sz, len(c))  # +1: the desk's user sits on the +z side
    dx, dz = 0.5 * POD[0] / 2 - 0.01, 0.5 * POD[1] / 2 - 0.01

    def box(x, z, half_x, y0, y1, half_z, rot=None):
        lo = np.stack([x - half_x, np.full_like(x, y0), z - half_z], 1)
        hi = np.stack([x + half_x, np.full_like(x, y1), z + half_z], 1)
        return boxes(lo, hi, rot)

    x, z = desk[:, 0], desk[:, 1]
    parts.add(box(x, z, dx, 0.72, 0.75, dz), "desk")
    parts.add(box(x, z - side * (dz - 0.05), dx - 0.02, 0.0, 0.72, 0.015), "desk")
    parts.add(box(x + rng.uniform(-0.3, 0.3, len(x)), z - side * (dz - 0.2), 0.28, 0.85, 1.18, 0.015), "monitor")
    # chairs: pulled out 0.2 to 0.7 m from the desk edge, turned up to 0.6 rad
    turn = rng.uniform(-0.6, 0.6, len(x))
    cx = x + rng.uniform(-0.25, 0.25, len(x))
    cz = z + side * (dz + rng.uniform(0.2, 0.7, len(x)))
    back_x, back_z = cx + side * 0.22 * np.sin(turn), cz + side * 0.22 * np.cos(turn)
    parts.add(box(cx, cz, 0.24, 0.42, 0.48, 0.24, turn), "chair")
    parts.add(box(back_x, back_z, 0.23, 0.5, 1.0, 0.025, turn), "chair")
    parts.add(box(cx, cz, 0.03, 0.0, 0.42, 0.03), "chair")


def office_parts(emitters: int, seed: int) -> PartList:
    """The office's parts (module docstring)."""
    nx, nz, ku, kv, panels = grid(emitters)
    w, d = nx * PANEL_PITCH, nz * PANEL_PITCH
    rng = np.random.default_rng(seed)
    parts = PartList()
    cols = _shell(parts, w, d)
    _pods(parts, rng, w, d, cols)
    cells = np.insert(_cells(nx, nz), 1, H, axis=1)
    rim = 0.5 * PANEL + 0.02
    parts.add(boxes(cells - [rim, 0.03, rim], cells + [rim, 0.0, rim]), "frame")
    lit = np.zeros(len(cells), bool)
    lit[np.sort(rng.permutation(len(cells))[:panels])] = True
    corner = cells - [0.5 * PANEL, PANEL_DROP, 0.5 * PANEL]
    # u along x, v along z: x cross z = -y, facing down
    if not lit.all():
        parts.add(quads(corner[~lit], [PANEL, 0, 0], [0, 0, PANEL]), "vent", closed=False)
    factor = rng.normal(1.0, 0.05, panels) * np.where(rng.random(panels) < 0.02, 0.3, 1.0)
    gap = min(TILE_GAP, 0.1 * PANEL / max(ku, kv))
    area = (PANEL / ku - 2 * gap) * (PANEL / kv - 2 * gap) * ku * kv
    parts.add(tiles(corner[lit], [PANEL, 0, 0], [0, 0, PANEL], ku, kv, gap), "panel", closed=False,
              scale=np.repeat(factor * PANEL ** 2 / area, 2 * ku * kv))
    return parts


def camera(emitters: int) -> Camera:
    """At eye height at the x = 0 end of the main aisle, looking down it."""
    nx, nz = grid(emitters)[:2]
    w, d = nx * PANEL_PITCH, nz * PANEL_PITCH
    return Camera((1.0, 1.6, 0.5 * d), (w, 1.2, 0.5 * d + 0.12 * w), (0, 1, 0), 55.0, *RESOLUTION)


@SCENES.register("office", params={"emitters": emitters_param(100_000), "seed": SEED}, resolution=RESOLUTION,
                 description="an open-plan office floor under a large grid of ceiling panels")
def office_scene(params: dict, materials=None, exhibits=(), offsets=(), name: str = "office") -> Scene:
    """The office (module docstring) with its camera; ``materials``: overrides by ``PALETTE`` name."""
    return office_parts(params["emitters"], params["seed"]).to_scene(PALETTE, materials, camera(params["emitters"]),
                                                                        name)
