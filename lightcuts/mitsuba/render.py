"""Rendering a run config with Mitsuba 3 (variant ``scalar_rgb``, all CPU cores).

Library functions (what the ``reference`` and ``compare`` commands call):

* ``render_mitsuba(cfg, scene, envmap, *, spp, integrator="path", seed=0, max_depth=-1)
  -> (image, seconds)``: the config's scene (its camera and thin lens, ``lights.sun``, the environment map
  ``envmap`` as loaded by ``lightcuts.lights.generate.load_environment``, ``render.crop``) rendered
  with ``spp`` samples per pixel (multi-jittered; a count that the sampler cannot factor is
  rounded up); ``image`` (H, W, 3) float32 linear RGB radiance, the same pixels
  as lightcuts' image of the config (the crop window where ``render.crop`` is set); ``seconds`` the
  wall time of ``mi.render`` alone (building and loading the Mitsuba scene excluded, as lightcuts'
  ``render_seconds`` excludes its preprocessing).
* ``spp_for_seconds(cfg, scene, envmap, seconds, integrator="path", *, max_depth=-1) -> int``: a
  timing run at :data:`PROBE_SPP` samples per pixel, then the spp (>= 1) whose render takes about
  ``seconds`` of wall time at the measured rate (a rough figure: the machine's load changes it).

``integrator``: ``direct`` computes direct light only (emitters, sun and environment, each sampled
with MIS, plus what the camera sees directly) - the quantity lightcuts computes without indirect
VPLs; ``path`` is a unidirectional path tracer with ``max_depth`` (-1 = unbounded, Russian
roulette), the full light transport. Mitsuba's emitters, materials and camera follow lightcuts'
definitions (lightcuts.mitsuba.export); Phong materials are approximated there. A config whose scene
is a ``scene.mitsuba`` file alone renders that file's own shapes, BSDFs and emitters instead, with
lightcuts' camera (:func:`_load_xml_scene`).
"""

from __future__ import annotations

import time

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.mitsuba import VARIANT, load_mitsuba
from lightcuts.mitsuba.export import INTEGRATORS, camera_dict, envmap_dict, integrator_dict, scene_dict, sun_dict

#: Samples per pixel of the timing run of :func:`spp_for_seconds`.
PROBE_SPP = 4


def load_scene(cfg, scene, envmap, *, spp: int, integrator: str = "path", max_depth: int = -1):
    """The loaded Mitsuba scene of the config (see :func:`render_mitsuba`); LightcutsError on bad
    arguments or if Mitsuba rejects the scene."""
    if int(spp) != spp or spp < 1:
        raise LightcutsError(f"--spp: {spp} must be a positive integer")
    if integrator not in INTEGRATORS:
        raise LightcutsError(f"--integrator: {integrator!r} is not one of {', '.join(INTEGRATORS)}")
    if int(max_depth) != max_depth or not (max_depth == -1 or max_depth >= 1):
        raise LightcutsError(f"--max-depth: {max_depth} must be -1 (unbounded) or >= 1")
    mi = load_mitsuba()
    sun = cfg.lights.sun
    if cfg.scene.mitsuba is not None:
        if not (cfg.scene.meshes or cfg.scene.emitters):
            return _load_xml_scene(mi, cfg, scene, envmap, spp=int(spp), integrator=integrator,
                                   max_depth=int(max_depth))
        from lightcuts.scene.mitsuba_xml import xml_settings

        sun = xml_settings(cfg).lights.sun  # the file's directional emitter, if it has one
    d = scene_dict(scene, envmap, sun, spp=int(spp), integrator=integrator, max_depth=int(max_depth),
                   crop=cfg.render.crop, aperture=cfg.camera.aperture, focus_distance=cfg.camera.focus_distance)
    try:
        return mi.load_dict(d)
    except Exception as exc:
        why = " ".join(str(exc).split())
        raise LightcutsError(f"mitsuba: cannot load the exported scene ({why[:300]})") from None


def _load_xml_scene(mi, cfg, scene, envmap, *, spp: int, integrator: str, max_depth: int):
    """The config's ``scene.mitsuba`` file as Mitsuba loads it (its shapes, BSDFs and emitters, the
    directional, constant and envmap ones included), with lightcuts' camera (the file's sensor with
    the config's camera fields applied, box filter, multi-jittered sampler, ``render.crop``), the
    config's own ``lights.sun`` and ``lights.environment`` file or sky if it gives them (exported as
    lightcuts.mitsuba.export does), and the integrator asked for; so the only difference from
    lightcuts' image is the file's mapping (lightcuts.scene.mitsuba_xml).

    Each mesh's bounding box is computed again: Mitsuba (3.9.1) merges meshes that share a BSDF into
    one whose box is left empty, so the scene's bounding sphere collapses to a point, and the shadow
    rays of its infinite emitters (constant, envmap, directional), which end at twice that sphere's
    radius or the point's distance from its centre, miss what lies further away."""
    from lightcuts.scene.mitsuba_xml import load_xml

    _, xml = load_xml(cfg.resolve(cfg.scene.mitsuba))
    d = {"type": "scene", "integrator": integrator_dict(integrator, max_depth),
         "sensor": camera_dict(mi, scene.camera, spp, cfg.render.crop, scene.bounds, cfg.camera.aperture,
                               cfg.camera.focus_distance)}
    for i, shape in enumerate(xml.shapes()):
        if hasattr(shape, "recompute_bbox"):
            shape.recompute_bbox()  # see the docstring
        d[f"shape_{i:05d}"] = shape
    for i, emitter in enumerate(e for e in xml.emitters() if e.class_name() != "AreaLight"):
        d[f"emitter_{i:03d}"] = emitter
    env = cfg.lights.environment
    if cfg.lights.sun is not None and not any(e.class_name() == "DirectionalEmitter" for e in xml.emitters()):
        d["sun"] = sun_dict(cfg.lights.sun)  # the config's own (a plan's cfg holds the file's)
    if env is not None and (env.file is not None or env.procedural is not None):
        d["environment"] = envmap_dict(mi, envmap)
    try:
        return mi.load_dict(d)
    except Exception as exc:
        why = " ".join(str(exc).split())
        raise LightcutsError(f"mitsuba: cannot load {cfg.scene.mitsuba} with lightcuts' camera ({why[:300]})") from None


def sample_count(mi_scene) -> int:
    """Samples per pixel the loaded scene's sampler takes (the requested spp, or the next count the
    multi-jittered sampler can factor)."""
    return int(mi_scene.sensors()[0].sampler().sample_count())


def render_loaded(mi_scene, seed: int = 0) -> tuple[np.ndarray, float]:
    """Render a loaded scene at its sampler's spp (:func:`sample_count`): ((H, W, 3) float32 linear
    RGB, wall seconds of ``mi.render``)."""
    mi = load_mitsuba()
    t0 = time.perf_counter()
    image = mi.render(mi_scene, seed=int(seed) % 2**32)
    seconds = time.perf_counter() - t0
    return np.ascontiguousarray(np.array(image, np.float32)[..., :3]), seconds


def render_mitsuba(cfg, scene, envmap, *, spp: int, integrator: str = "path", seed: int = 0,
                   max_depth: int = -1) -> tuple[np.ndarray, float]:
    """(image (H, W, 3) float32, seconds): see the module docstring."""
    mi_scene = load_scene(cfg, scene, envmap, spp=spp, integrator=integrator, max_depth=max_depth)
    return render_loaded(mi_scene, seed)


def spp_for_seconds(cfg, scene, envmap, seconds: float, integrator: str = "path", *,
                    max_depth: int = -1) -> int:
    """Samples per pixel that fill about ``seconds`` of render time: see the module docstring."""
    if not (seconds > 0 and np.isfinite(seconds)):
        raise LightcutsError(f"seconds: {seconds} must be a positive number")
    mi_scene = load_scene(cfg, scene, envmap, spp=PROBE_SPP, integrator=integrator, max_depth=max_depth)
    _, t = render_loaded(mi_scene, seed=0)
    return max(1, int(seconds / max(t / sample_count(mi_scene), 1e-9)))


def mitsuba_version() -> dict:
    """{"version": Mitsuba's version, "variant": the variant used}."""
    mi = load_mitsuba()
    return {"version": str(mi.__version__), "variant": VARIANT}
