"""The lights a run config asks for: direct + indirect oriented lights, sun + environment directional lights.

Each source draws its randomness from its own sub-seed of ``cfg.seed`` (numpy ``SeedSequence`` with
a fixed spawn key per source), so adding or removing one source leaves the others' lights unchanged.
"""

from __future__ import annotations

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.lights.direct import direct_lights
from lightcuts.lights.environment import EnvironmentMap, environment_lights, procedural_sky, sun_light
from lightcuts.lights.indirect import indirect_lights
from lightcuts.lights.lightset import LightSet
from lightcuts.lights.triangles import TRIANGLES_META, triangle_lights

# Spawn keys of the sources' sub-seeds: never renumber (it would change every saved run's lights).
_SOURCE_KEYS = {"direct": 1, "indirect": 2, "environment": 3}


def sub_seed(seed: int, source: str) -> int:
    """A 63-bit seed for ``source`` ("direct", "indirect", "environment") derived from the run's seed."""
    state = np.random.SeedSequence(int(seed), spawn_key=(_SOURCE_KEYS[source],)).generate_state(2, np.uint32)
    return (int(state[0]) << 31) ^ int(state[1])


def load_environment(cfg) -> EnvironmentMap | None:
    """The config's environment map (file or procedural sky, ``rotate`` and ``scale`` applied; with
    neither, the ``constant`` or ``envmap`` emitter of its ``scene.mitsuba`` file, held in memory as
    lightcuts.scene.mitsuba_emitters reads it), or None."""
    env = cfg.lights.environment
    if env is None:
        return None
    if env.file is not None:
        return EnvironmentMap.load(cfg.resolve(env.file), env.rotate, env.scale)
    if env.procedural is None:
        xml = None
        if cfg.scene.mitsuba is not None:
            from lightcuts.scene.mitsuba_xml import xml_summary

            xml = xml_summary(cfg.resolve(cfg.scene.mitsuba))[0].environment
        if xml is None:
            raise LightcutsError("lights.environment: give file or procedural (or a scene.mitsuba file with a "
                                 "constant or envmap emitter)")
        return EnvironmentMap(xml.pixels, env.rotate, env.scale * xml.scale, xml.name, frame=xml.frame)
    p = env.procedural
    return procedural_sky(p.sun_direction, p.resolution, p.zenith, p.horizon, p.ground,
                          sun_irradiance=p.sun_irradiance, sun_radius=p.sun_radius, rotate=env.rotate,
                          scale=env.scale)


def point_lights(cfg) -> LightSet | None:
    """The ``omni`` LightSet of the config's ``scene.mitsuba`` point emitters (direct light only:
    lightcuts' indirect VPLs are traced from emitting triangles), or None without any."""
    if cfg.scene.mitsuba is None:
        return None
    from lightcuts.scene.mitsuba_xml import xml_summary

    points = xml_summary(cfg.resolve(cfg.scene.mitsuba))[0].points
    if not len(points):
        return None
    return LightSet(points[:, 0], np.zeros((len(points), 3)), points[:, 1], "omni")


def lights_from_config(cfg, scene, caster=None, envmap: EnvironmentMap | None = None) -> dict[str, LightSet]:
    """Light sets keyed by type (``omni``, ``oriented``, ``directional``), empty types omitted.

    cfg : RunConfig; scene : Scene; caster : RayCaster for particle tracing (required when indirect
    lights are asked for); envmap : the config's environment map (:func:`load_environment`, loaded
    once per run by the caller), None without one.

    ``omni`` = the point emitters of a ``scene.mitsuba`` file; ``oriented`` = direct lights then
    indirect VPLs; ``directional`` = the sun then the environment samples. Each set's ``meta``: scene
    name, scene bbox min/max and diagonal, the run seed, and ``count_direct``, ``count_indirect``,
    ``count_sun``, ``count_environment``, ``count_point`` (0 when absent) plus
    ``indirect_paths`` (the particle paths that normalise the VPLs). With
    ``lights.direct.source: triangles`` the direct lights are the scene's emitting triangles
    (lightcuts.lights.triangles.triangle_lights, one light each, ``count_direct`` of them, first in
    the ``oriented`` set) and every set's meta has ``direct_source: triangles``
    (:data:`~lightcuts.lights.triangles.TRIANGLES_META`).

    LightcutsError: emission the scene may not have (:meth:`Scene.check_emission`), an indirect
    count > 0, or a direct count the config sets, in a scene without emitters (the default direct
    count then makes no lights), a zero sun direction, an unreadable environment map, or no
    lights at all.
    """
    lc = cfg.lights
    scene.check_emission(f"scene {scene.name!r}")  # NaN would count as no emission below
    have_emitters = len(scene.emitters) > 0 and float((scene.emission.max(axis=1) * scene.face_areas).max()) > 0
    triangles = lc.direct.source == "triangles"
    n_direct = lc.direct.count
    if not have_emitters and "count" not in lc.direct.model_fields_set:
        n_direct = 0  # the default count samples the emitters there are, none here
    if triangles and not have_emitters:
        raise LightcutsError("lights.direct.source: triangles, but the scene has no emissive triangles "
                             "(place area lights with scene.emitters, or use source: samples)")
    for key, n in (("direct", n_direct), ("indirect", lc.indirect.count)):
        if n > 0 and not have_emitters:
            raise LightcutsError(f"lights.{key}: the scene has no emissive triangles "
                                 f"(set lights.{key}.count: 0, or place area lights with scene.emitters)")
    oriented, directional = [], []
    counts = {"count_direct": 0, "count_indirect": 0, "count_sun": 0, "count_environment": 0, "indirect_paths": 0}
    if triangles:
        d = triangle_lights(scene).lights
        oriented.append(d)
        counts["count_direct"] = len(d)
    elif n_direct > 0:
        d = direct_lights(scene, n_direct, sub_seed(cfg.seed, "direct"))
        oriented.append(d)
        counts["count_direct"] = len(d)
    if lc.indirect.count > 0:
        if caster is None:
            raise TypeError("lights_from_config: indirect lights need a ray caster")
        ind = indirect_lights(scene, caster, lc.indirect.count, sub_seed(cfg.seed, "indirect"),
                              lc.indirect.max_bounces, lc.indirect.rr_start, glossy=cfg.render.compensation)
        oriented.append(ind)
        counts["count_indirect"] = len(ind)
        counts["indirect_paths"] = int(ind.meta.get("indirect_paths", 0))
    if lc.sun is not None:
        directional.append(sun_light(lc.sun.direction, lc.sun.irradiance))
        counts["count_sun"] = 1
    if (envmap is None) != (lc.environment is None):
        raise TypeError("lights_from_config: pass the config's environment map (load_environment)")
    if envmap is not None:
        e = environment_lights(envmap, lc.environment.count, sub_seed(cfg.seed, "environment"))
        directional.append(e)
        counts["count_environment"] = len(e)
    omni = [ls for ls in [point_lights(cfg)] if ls is not None]
    counts["count_point"] = len(omni[0]) if omni else 0
    lo, hi = scene.bounds
    meta = {"scene": scene.name, "bbox_min": lo, "bbox_max": hi, "diagonal": scene.diagonal, "seed": cfg.seed,
            **counts}
    if triangles:
        meta[TRIANGLES_META] = "triangles"
    out = {}
    for typ, sets in (("omni", omni), ("oriented", oriented), ("directional", directional)):
        sets = [s for s in sets if len(s)]
        if sets:
            ls = LightSet.concatenate(sets)
            ls.meta = dict(meta)
            out[typ] = ls
    if not out:
        raise LightcutsError("lights: the config yields no lights (all counts 0, no sun, or a black environment)")
    return out
