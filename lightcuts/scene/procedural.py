"""``scene.procedural`` -> Scene: the generated kitchen, building of rooms and gallery.

Defaults for what the config leaves out: ``DEFAULTS`` per type. Every choice is seeded by the
procedural seed (not the run's), so a config gives the same bytes of ``Scene.save`` every time.
"""

from __future__ import annotations

from lightcuts.config.schema import PROCEDURAL_READS, ProceduralScene
from lightcuts.scene import gallery, kitchen, rooms
from lightcuts.scene.scene import Scene

DEFAULTS = {"triangles": 200_000, "rooms": 4, "seed": 0}
ROOMS_DEFAULT_TRIANGLES = 100_000
#: (width, height) of each type's default camera, pixels.
RESOLUTIONS = {"kitchen": kitchen.RESOLUTION, "rooms": kitchen.RESOLUTION, "gallery": gallery.RESOLUTION}


def parameters(proc: ProceduralScene) -> dict:
    """The parameters ``proc.type`` reads, with defaults filled in."""
    defaults = dict(DEFAULTS, triangles=ROOMS_DEFAULT_TRIANGLES) if proc.type == "rooms" else DEFAULTS
    return {k: getattr(proc, k) if getattr(proc, k) is not None else defaults[k] for k in PROCEDURAL_READS[proc.type]}


def procedural_scene(proc: ProceduralScene, materials=None, exhibits=(), offsets=(), name: str = "scene") -> Scene:
    """The scene ``proc`` describes, with its default camera. ``materials``: overrides by surface
    name (the type's PALETTE); ``exhibits``/``offsets``: the gallery's meshes and their translates."""
    p = parameters(proc)
    if proc.type == "kitchen":
        parts = kitchen.kitchen_parts(p["triangles"], p["seed"])
        return parts.to_scene(kitchen.PALETTE, materials, kitchen.camera(), name)
    if proc.type == "rooms":
        parts = rooms.building_parts(p["rooms"], p["triangles"], p["seed"])
        return parts.to_scene(kitchen.PALETTE, materials, rooms.camera(p["rooms"]), name)
    return gallery.gallery_scene(list(exhibits), list(offsets), materials, name)
