"""Glue from a validated RunConfig to the stages: scene -> ray caster -> lights -> trees."""

from __future__ import annotations

from lightcuts.config import RunConfig


def make_scene(cfg: RunConfig):
    """The Scene the config describes (built-in and/or mesh files, camera applied)."""
    from lightcuts.scene.build import scene_from_config

    return scene_from_config(cfg)


def make_caster(cfg: RunConfig, scene):
    """The ray caster named by ``render.ray_caster`` over the scene's triangles."""
    from lightcuts.accel import make_caster as _make

    return _make(scene, cfg.render.ray_caster)


def make_lights(cfg: RunConfig, scene, caster=None) -> dict:
    """Light sets by type (``omni``/``oriented``/``directional``), seeded by ``cfg.seed``."""
    from lightcuts.lights.generate import lights_from_config

    if caster is None and cfg.lights.indirect.count > 0:
        caster = make_caster(cfg, scene)
    return lights_from_config(cfg, scene, caster)
