"""RunConfig -> Scene: the built-in scene, mesh files, material overrides and the camera.

Camera, in order of precedence, field by field (position, look_at, up, fov, resolution):

1. the fields ``cfg.camera`` gives;
2. the built-in scene's camera (the Cornell box's published one), if ``scene.builtin`` is set, or the
   procedural scene's (``lightcuts.scene.procedural``), if ``scene.procedural`` is;
3. otherwise a default framing camera (``framing_camera``): up +y, vertical fov ``DEFAULT_FOV``,
   ``DEFAULT_RESOLUTION``, looking along -z at the centre of the scene's bounding box from the +z side,
   at the distance where the box's bounding sphere just fits in both the vertical and the horizontal
   field of view.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from lightcuts.config.schema import CameraConfig, RunConfig
from lightcuts.errors import LightcutsError
from lightcuts.scene.cornell import RESOLUTION as CORNELL_RESOLUTION
from lightcuts.scene.cornell import cornell_box
from lightcuts.scene.loaders import concatenate_scenes, load_mesh
from lightcuts.scene.procedural import RESOLUTIONS as PROCEDURAL_RESOLUTIONS
from lightcuts.scene.procedural import procedural_scene
from lightcuts.scene.scene import Camera, Scene

DEFAULT_FOV = 40.0  # degrees, vertical
DEFAULT_RESOLUTION = (512, 512)

#: Built-in scenes by ``scene.builtin`` name: factory(materials overrides) -> Scene with a camera.
BUILTINS: dict[str, Callable[..., Scene]] = {"cornell": cornell_box}
#: Their cameras' (width, height), pixels, known without building them.
BUILTIN_RESOLUTIONS = {"cornell": tuple(CORNELL_RESOLUTION)}


def image_size(cfg: RunConfig) -> tuple[int, int]:
    """The (width, height) of the image ``cfg`` renders, in pixels, from the config alone (the
    camera's precedence, see the module docstring), for checks before any scene is built."""
    if cfg.camera.resolution is not None:
        return tuple(cfg.camera.resolution)
    if cfg.scene.builtin is not None:
        return BUILTIN_RESOLUTIONS[cfg.scene.builtin]
    if cfg.scene.procedural is not None:
        return tuple(PROCEDURAL_RESOLUTIONS[cfg.scene.procedural.type])
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


def scene_from_config(cfg: RunConfig) -> Scene:
    """The Scene ``cfg.scene`` describes, with its camera (module docstring) and ``cfg.name``.

    Triangle order: the built-in or procedural scene's first, then each of ``cfg.scene.meshes`` in
    order (a gallery's meshes after its room, placed on its plinths). Mesh paths are resolved with
    ``cfg.resolve``; errors name ``scene.meshes.<i>``.
    """
    sc = cfg.scene
    parts = []
    if sc.builtin is not None:
        if sc.builtin not in BUILTINS:
            raise LightcutsError(f"scene.builtin: unknown built-in {sc.builtin!r}; valid: {', '.join(BUILTINS)}")
        parts.append(BUILTINS[sc.builtin](sc.materials))
    elif sc.materials and sc.procedural is None:
        raise LightcutsError(f"scene.materials.{next(iter(sc.materials))}: overrides built-in surfaces, "
                             "but neither scene.builtin nor scene.procedural is set")
    meshes = [load_mesh(cfg.resolve(m.file), m.scale, m.rotate, m.translate, m.material, key=f"scene.meshes.{i}")
              for i, m in enumerate(sc.meshes)]
    if sc.procedural is not None:
        if sc.procedural.type == "gallery":
            parts.append(procedural_scene(sc.procedural, sc.materials, meshes, [m.translate for m in sc.meshes],
                                          name=cfg.name))
            meshes = []
        else:
            parts.append(procedural_scene(sc.procedural, sc.materials, name=cfg.name))
    parts += meshes
    if not parts:
        raise LightcutsError("scene: needs builtin, procedural or meshes")
    base_camera = parts[0].camera if (sc.builtin is not None or sc.procedural is not None) else None
    scene = concatenate_scenes(parts, name=cfg.name)
    scene.camera = _apply_camera_config(cfg.camera, base_camera, scene.bounds)
    return scene
