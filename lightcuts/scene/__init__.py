"""Scenes: triangle meshes with per-triangle materials and a pinhole camera."""

from lightcuts.scene.scene import Camera, Scene

__all__ = ["Camera", "Scene"]
