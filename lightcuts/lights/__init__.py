"""Virtual point lights: omni, oriented and directional light sets."""

from lightcuts.lights.lightset import LIGHT_TYPES, LightSet

__all__ = ["LIGHT_TYPES", "LightSet"]
