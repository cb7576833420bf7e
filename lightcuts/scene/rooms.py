"""A building of procedural kitchens: the 1995 HUG paper's growing scene, ``rooms`` copies of the
interior (each with its own seed) joined by doorways so that light passes between them.

Layout: row 0 holds ceil(rooms / 2) rooms side by side along +x (0.2 m walls between them); row 1
holds the rest, each turned 180 degrees about y so that its front wall meets the front wall of the
row-0 room opposite. Neighbours in a row share a side-wall doorway; rooms facing each other share a
front-wall doorway. Only walls on the outside of the building carry a window, so every room has its
4 x 3 ceiling panels of 3 x 3 tiles (108 emitters) and its 40-segment LED strip, and the outer rooms
a 12-pane window: 8 rooms hold over 1,000 emitting quads. Triangles grow linearly with ``rooms``.
"""

from __future__ import annotations

import math

import numpy as np

from lightcuts.registry import Param
from lightcuts.scene.kitchen import PALETTE, D, RESOLUTION, SIDE_DOOR, T, W, camera as kitchen_camera, kitchen_parts
from lightcuts.scene.registry import MAX_ROOMS, SCENES, SEED, triangles as triangles_param
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.shapes import PartList, pose

PITCH = W + 2 * T  # x distance between neighbouring rooms


def layout(rooms: int) -> list[dict]:
    """Per room: its (4, 4) placement, doorway sides and whether it has a window (module docstring)."""
    n0 = math.ceil(rooms / 2) if rooms > 1 else 1
    n1 = rooms - n0
    out = []
    for c in range(n0):
        doors = {"left"} if c > 0 else set()
        if c < n0 - 1:
            doors.add("right")
        if c < n1:
            doors.add("front")
        out.append(dict(matrix=pose((c * PITCH, 0, 0)), doors=doors, window=c == 0))
    for c in range(n1):
        # turned: local left (x = 0) faces global +x, i.e. column c + 1 of row 1
        doors = {"front"}
        if c + 1 < n1:
            doors.add("left")
        if c > 0:
            doors.add("right")
        out.append(dict(matrix=pose((c * PITCH + W, 0, 2 * D + 2 * T), np.pi), doors=doors, window=c + 1 >= n1))
    return out


def building_parts(rooms: int, triangles: int, seed: int) -> PartList:
    """All rooms' parts, about ``triangles`` per room; room i is generated from seed (seed, i)."""
    parts = PartList()
    for i, room in enumerate(layout(rooms)):
        parts.extend(kitchen_parts(triangles, (seed, i), tuple(sorted(room["doors"])), room["window"]),
                     room["matrix"])
    return parts


def camera(rooms: int) -> Camera:
    """In the first room, looking through its side doorway into the next room of its row (or, with
    2 rooms, through its front doorway into the room facing it); the kitchen's camera for 1 room."""
    doors = layout(rooms)[0]["doors"]
    if "right" in doors:
        z = 0.5 * sum(SIDE_DOOR)
        return Camera((1.0, 1.6, D - 0.3), (W + 1.8, 1.0, z - 0.6), (0, 1, 0), 70.0, *RESOLUTION)
    if "front" in doors:
        return Camera((0.9, 1.6, 1.0), (0.5 * W + 0.6, 1.0, D + 1.5), (0, 1, 0), 70.0, *RESOLUTION)
    return kitchen_camera()


@SCENES.register("rooms", params={
    "triangles": triangles_param(100_000, "the triangle count per room, hit within a few percent"),
    "rooms": Param(int, 4, lo=1, hi=MAX_ROOMS, doc="copies of the kitchen in the building"),
    "seed": SEED}, resolution=RESOLUTION, description="a building of seeded kitchens joined by doorways")
def rooms_scene(params: dict, materials=None, exhibits=(), offsets=(), name: str = "rooms") -> Scene:
    """The building (module docstring) with its camera; ``materials``: overrides by the kitchen's
    ``PALETTE`` names."""
    parts = building_parts(params["rooms"], params["triangles"], params["seed"])
    return parts.to_scene(PALETTE, materials, camera(params["rooms"]), name)
