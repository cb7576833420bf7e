"""Scenes: triangle meshes with per-triangle materials and a pinhole camera; the built-in Cornell
box (``cornell``) and the procedural kitchen, building of rooms, gallery, city and office
(``procedural``)."""

from lightcuts.scene.scene import Camera, Scene

__all__ = ["Camera", "Scene"]
