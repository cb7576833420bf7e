"""Glue from a validated RunConfig to the stages: scene -> ray caster -> lights -> trees."""

from __future__ import annotations

from lightcuts.config import RunConfig


def check_names(cfg: RunConfig) -> None:
    """Resolve every registry name the config uses (builder, metric, ray caster): an unknown name fails
    with one line listing the valid ones, before any work starts."""
    import lightcuts.accel.embree  # noqa: F401  (registers the built-in casters)
    from lightcuts.accel.base import RAY_CASTERS
    from lightcuts.errors import LightcutsError
    from lightcuts.trees.registry import get_builder, get_metric

    for key, lookup, name in (("tree.builder", get_builder, cfg.tree.builder),
                              ("tree.metric", get_metric, cfg.tree.metric)):
        try:
            lookup(name)
        except LightcutsError as exc:
            raise LightcutsError(f"{key}: {exc}") from None
    try:
        RAY_CASTERS.get(cfg.render.ray_caster)
    except LightcutsError as exc:
        raise LightcutsError(f"render.ray_caster: {exc}") from None


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
