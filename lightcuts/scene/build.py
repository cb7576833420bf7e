"""RunConfig -> Scene: the built-in scene, mesh files, material overrides and the camera.

Camera, in order of precedence, field by field (position, look_at, up, fov, resolution):

1. the fields ``cfg.camera`` gives;
2. the camera of the scene type ``scene.builtin`` or ``scene.procedural`` names
   (``lightcuts.scene.registry.SCENES``: the Cornell box's published one, the kitchen's, ...), or the
   sensor of the ``scene.mitsuba`` file, if set;
3. otherwise a default framing camera (``framing_camera``): up +y, vertical fov ``DEFAULT_FOV``,
   ``DEFAULT_RESOLUTION``, looking along -z at the centre of the scene's bounding box from the +z side,
   at the distance where the box's bounding sphere just fits in both the vertical and the horizontal
   field of view.
"""

from __future__ import annotations

import math
import numpy as np

from lightcuts.config.schema import CameraConfig, RunConfig
from lightcuts.errors import LightcutsError
from lightcuts.registry import Resolved
from lightcuts.scene.emitters import emitter_scene
from lightcuts.scene.loaders import concatenate_scenes, load_mesh
from lightcuts.scene.registry import make_scene, resolve_scene
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.textures import TexelBudget

DEFAULT_FOV = 40.0  # degrees, vertical
DEFAULT_RESOLUTION = (512, 512)


def image_size(cfg: RunConfig, scene_type: Resolved | None = None) -> tuple[int, int]:
    """The (width, height) of the image ``cfg`` renders, in pixels, from the config alone (the
    camera's precedence, see the module docstring; the scene type's ``resolution`` trait), for checks
    before any scene is built. ``scene_type``: the plan's resolved type (else resolved here)."""
    if cfg.camera.resolution is not None:
        return tuple(cfg.camera.resolution)
    if cfg.scene.mitsuba is not None:
        from lightcuts.scene.mitsuba_xml import xml_summary

        size = xml_summary(cfg.resolve(cfg.scene.mitsuba))[1]
        return size if size is not None else DEFAULT_RESOLUTION
    scene_type = resolve_scene(cfg.scene) if scene_type is None else scene_type
    if scene_type is not None:
        return tuple(scene_type.trait("resolution"))
    return DEFAULT_RESOLUTION


def framing_camera(bounds: np.ndarray, fov: float = DEFAULT_FOV, width: int = DEFAULT_RESOLUTION[0],
                   height: int = DEFAULT_RESOLUTION[1]) -> Camera:
    """A camera on the +z side of ``bounds`` ((2, 3) float, lo/hi) looking along -z at its centre.

    Distance from the centre: r / sin(half the smaller of the vertical and horizontal fov), with r
    half the box diagonal, so the bounding sphere (hence the box) is inside the view cone.
    """
    lo, hi = np.asarray(bounds, np.float64)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    half_v = math.radians(fov) / 2
    half_h = math.atan(math.tan(half_v) * width / height)
    distance = radius / math.sin(min(half_v, half_h))
    return Camera(centre + [0.0, 0.0, distance], centre, [0.0, 1.0, 0.0], fov, width, height)


def _apply_camera_config(cc: CameraConfig, base: Camera | None, bounds: np.ndarray) -> Camera:
    """``base`` (or the framing camera when None) with the fields ``cc`` gives replaced."""
    width, height = cc.resolution if cc.resolution is not None else (
        (base.width, base.height) if base is not None else DEFAULT_RESOLUTION)
    if base is None:
        base = framing_camera(bounds, cc.fov if cc.fov is not None else DEFAULT_FOV, width, height)
    cam = Camera(cc.position if cc.position is not None else base.position,
                 cc.look_at if cc.look_at is not None else base.look_at,
                 cc.up if cc.up is not None else base.up,
                 cc.fov if cc.fov is not None else base.fov, width, height)
    for name in ("position", "look_at", "up"):
        if not np.all(np.isfinite(getattr(cam, name))):
            raise LightcutsError(f"camera.{name}: values must be finite")
    view = cam.look_at - cam.position
    if np.linalg.norm(view) == 0:
        raise LightcutsError("camera.look_at: equals camera.position (no viewing direction)")
    cross = np.linalg.norm(np.cross(view / np.linalg.norm(view), cam.up))
    if np.linalg.norm(cam.up) == 0 or cross <= 1e-9 * np.linalg.norm(cam.up):
        raise LightcutsError("camera.up: zero or parallel to the viewing direction (look_at - position)")
    return cam


def scene_from_config(cfg: RunConfig, scene_type: Resolved | None = None) -> Scene:
    """The Scene ``cfg.scene`` describes, with its camera (module docstring) and ``cfg.name``.

    scene_type : the plan's resolved scene type (else resolved here, see
        :func:`~lightcuts.scene.registry.resolve_scene`)
    Triangle order: the ``scene.mitsuba`` file's or the scene type's first, then each of
    ``cfg.scene.meshes`` in order (a type with the ``exhibits`` trait, the gallery, takes them: its
    room, then the meshes on their plinths), then the area lights of ``cfg.scene.emitters`` (lightcuts.scene.emitters). Mesh paths are
    resolved with ``cfg.resolve``; errors name ``scene.meshes.<i>`` / ``scene.emitters.<i>``. The
    meshes' textures share one texel budget (lightcuts.limits.MAX_SCENE_TEXELS); the emission of
    each part, then of the whole scene, is checked against the light limits
    (:meth:`Scene.check_emission`).
    """
    sc = cfg.scene
    scene_type = resolve_scene(sc) if scene_type is None else scene_type
    if sc.materials and scene_type is None:
        raise LightcutsError(f"scene.materials.{next(iter(sc.materials))}: overrides built-in surfaces, "
                             "but neither scene.builtin nor scene.procedural is set")
    if sc.mitsuba is not None and scene_type is not None:
        raise LightcutsError("scene.mitsuba: goes alone, without scene.builtin or scene.procedural")
    budget = TexelBudget()
    meshes = [load_mesh(cfg.resolve(m.file), m.scale, m.rotate, m.translate, m.material, key=f"scene.meshes.{i}",
                        budget=budget) for i, m in enumerate(sc.meshes)]
    parts = []
    if sc.mitsuba is not None:
        from lightcuts.scene.mitsuba_xml import load_mitsuba_xml

        parts.append(load_mitsuba_xml(cfg.resolve(sc.mitsuba), name=cfg.name, budget=budget)[0])
        parts[0].check_emission(f"scene.mitsuba: {sc.mitsuba}")
    if scene_type is not None:
        if scene_type.trait("exhibits"):
            exhibits, offsets, meshes = meshes, [m.translate for m in sc.meshes], []
        else:
            exhibits, offsets = [], []
        parts.append(make_scene(scene_type, sc.materials, exhibits, offsets, name=cfg.name))
        parts[0].check_emission("scene.materials" if sc.materials else f"scene: the {scene_type.name} scene")
    parts += meshes
    parts += [emitter_scene(e, key=f"scene.emitters.{i}") for i, e in enumerate(sc.emitters)]
    if not parts:
        raise LightcutsError("scene: needs builtin, procedural, mitsuba, meshes or emitters")
    base_camera = parts[0].camera if scene_type is not None or sc.mitsuba is not None else None
    scene = concatenate_scenes(parts, name=cfg.name)
    scene.check_emission("scene: all its parts together")
    scene.camera = _apply_camera_config(cfg.camera, base_camera, scene.bounds)
    return scene
