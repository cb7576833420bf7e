"""A Mitsuba 3 XML scene (``scene.mitsuba: FILE.xml``) read through Mitsuba's own parser.

The file is loaded with ``mi.load_file`` (variant ``scalar_rgb``; the optional ``mitsuba`` extra) and
read back with ``mi.traverse``, so every XML feature Mitsuba knows (``<ref>``, ``<default>``,
``<include>``, transforms, ``$param`` substitution) means what it means in Mitsuba. What lightcuts
takes from it (docs/math.md's Lambert + Phong material; ``MAPPED_BSDFS`` lists the BSDFs):

* Shapes: meshes (``obj``, ``ply``, ``serialized``, ``cube``) as Mitsuba holds them (world-space
  vertices, its faces and texture coordinates); ``rectangle`` (two triangles), ``sphere``, ``disk``
  and ``cylinder`` (``SEGMENTS`` around) are built here from Mitsuba's unit shape and ``to_world``.
* BSDFs (:func:`map_bsdf`): ``diffuse`` exact (reflectance, or a ``bitmap`` texture as the albedo
  texture); ``plastic`` / ``roughplastic``: diffuse albedo = Mitsuba's diffuse lobe at normal
  incidence, ``rho (1 - F0)^2 / (eta^2 (1 - Fdr_int))``, specular = ``F0`` (Fresnel at normal
  incidence from ``int_ior``/``ext_ior``) times ``specular_reflectance``; ``conductor`` /
  ``roughconductor``: albedo 0, specular = the conductor's Fresnel at normal incidence from its
  ``eta``, ``k``, times ``specular_reflectance``; the lobe width ``alpha`` -> Phong ``n = 2 / alpha^2
  - 2`` (Walter et al. 2007, as for glTF), a smooth BSDF the largest exponent ``MAX_PBR_EXPONENT``;
  ``twosided``: its inner BSDF (lightcuts shades both sides anyway). Any other BSDF (``dielectric``,
  ``thindielectric``, ``blendbsdf``, ``principled``, ...) is an error naming it and the shape.
* Area emitters: the shape's triangles emit ``radiance``; a textured radiance emits the mean of its
  bitmap (a documented stand-in: lightcuts' emitters have one radiance per triangle).
* The sensor (``perspective``): position, look-at and up from its ``to_world``, the vertical fov from
  Mitsuba's horizontal ``x_fov`` (whatever ``fov_axis`` the file gave) and the film's size.
* Other emitters (lightcuts.scene.mitsuba_emitters): ``directional`` -> ``lights.sun``
  (:func:`xml_settings`); ``point`` -> an ``omni`` light of its ``intensity``
  (``lightcuts.lights.generate.point_lights``; direct light only); ``constant`` and ``envmap`` ->
  ``lights.environment`` (:func:`xml_settings`, ``lightcuts.lights.generate.load_environment``);
  ``spot`` is an error naming the emitter and what to use instead.

Mitsuba is imported here itself (:func:`mitsuba_module`), not through ``lightcuts.mitsuba``, a later
layer.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.scene.files import regular_file
from lightcuts.scene.materials import MAX_PBR_EXPONENT
from lightcuts.scene.mitsuba_emitters import XmlEmitters, param, param_rgb, read_emitters
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.textures import TexelBudget, TextureSet, srgb_to_linear

#: Segments around a tessellated sphere, disk or cylinder (and half as many rings of a sphere).
SEGMENTS = 64
#: The Mitsuba BSDF plugins :func:`map_bsdf` maps (their class names in Mitsuba 3).
MAPPED_BSDFS = {"SmoothDiffuse": "diffuse", "SmoothPlastic": "plastic", "RoughPlastic": "roughplastic",
                "SmoothConductor": "conductor", "RoughConductor": "roughconductor"}
INSTALL_HINT = "pip install 'lightcuts[mitsuba]'"


def mitsuba_module(where: str):
    """The ``mitsuba`` module with variant ``scalar_rgb``; LightcutsError naming the extra if absent."""
    try:
        import mitsuba as mi
        if mi.variant() != "scalar_rgb":
            mi.set_variant("scalar_rgb")
    except Exception as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise LightcutsError(f"{where}: needs Mitsuba 3 ({why}); install it with: {INSTALL_HINT}") from None
    mi.set_log_level(mi.LogLevel.Error)
    return mi


def load_xml(path, where: str = "scene.mitsuba"):
    """(mi, the loaded Mitsuba scene) of the XML file; LightcutsError ``<where>: <path>: <Mitsuba's
    reason>`` (one line) for a missing file or one Mitsuba rejects."""
    path = regular_file(path, f"{where}: {path}")
    mi = mitsuba_module(where)
    try:
        return mi, mi.load_file(str(path))
    except Exception as exc:
        why = " ".join(str(exc).split())
        why = why.split("Error while loading")[-1] if len(why) > 300 else why
        raise LightcutsError(f"{where}: {path}: Mitsuba cannot load it ({why[:300]})") from None


def _phong_exponent(alpha: float) -> float:
    """Beckmann/GGX width -> Phong exponent ``2 / alpha^2 - 2`` (MAX_PBR_EXPONENT when smooth)."""
    if alpha ** 2 <= 2.0 / (MAX_PBR_EXPONENT + 2.0):
        return MAX_PBR_EXPONENT
    return max(0.0, 2.0 / alpha ** 2 - 2.0)


def _dielectric_f0(eta: float) -> float:
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def map_bsdf(mi, bsdf, where: str) -> tuple[np.ndarray, np.ndarray, float, np.ndarray | None, str]:
    """A Mitsuba BSDF -> (rho_d (3,), rho_s (3,), Phong n, albedo texture or None, the plugin's
    name) by the mapping of the module docstring; the texture is ((H, W, 3) float32 linear RGB,
    its (3, 3) ``to_uv`` transform). LightcutsError naming ``where`` for a BSDF it does not map."""
    cls, params = bsdf.class_name(), dict(mi.traverse(bsdf).items())
    raw = re.search(r"raw = 1", str(bsdf)) is not None  # a bitmap's flag, in its printed form only
    if cls.startswith("TwoSided"):
        # Mitsuba 3 has no accessor for the wrapped BSDF: its printed form names the plugin, and
        # its parameters are the wrapper's under ``brdf_0.``.
        match = re.search(r"brdf\[0\] = (\w+)\[", str(bsdf))
        cls = match.group(1) if match else "TwoSided"
        params = {k[len("brdf_0."):]: v for k, v in params.items() if k.startswith("brdf_0.")}
        return _map(mi, cls, params, raw, where)[:4] + ("twosided",)
    return _map(mi, cls, params, raw, where)


def _map(mi, cls: str, p: dict, raw: bool, where: str):
    if cls not in MAPPED_BSDFS:
        raise LightcutsError(f"{where}: BSDF {cls!r} has no Lambert + Phong mapping (mapped: "
                             f"{', '.join(sorted(set(MAPPED_BSDFS.values())))})")
    name = MAPPED_BSDFS[cls]
    zero = np.zeros(3)
    if name == "diffuse":
        if "reflectance.data" in p:
            return np.ones(3), zero, 0.0, _texture(p, "reflectance", raw), name
        return np.clip(param_rgb(p, "reflectance.value", 0.5), 0, 1), zero, 0.0, None, name
    alpha = float(param(p, "alpha.value", param(p, "alpha", 0.0))[0]) if cls.startswith("Rough") else 0.0
    n = _phong_exponent(alpha)
    rho_s_scale = param_rgb(p, "specular_reflectance.value", 1.0)
    if name in ("plastic", "roughplastic"):
        eta = float(param(p, "eta", 1.49)[0])
        f0 = _dielectric_f0(eta)
        fdr_int = float(mi.fresnel_diffuse_reflectance(1.0 / eta))
        scale = (1.0 - f0) ** 2 / (eta ** 2 * (1.0 - fdr_int))
        texture = None
        if "diffuse_reflectance.data" in p:
            texture, rho_d = _texture(p, "diffuse_reflectance", raw), np.full(3, scale)
        else:
            rho_d = param_rgb(p, "diffuse_reflectance.value", 0.5) * scale
        return np.clip(rho_d, 0, 1), np.clip(f0 * rho_s_scale, 0, 1), n, texture, name
    if "eta.value" not in p:  # material "none": a perfect mirror
        f0 = np.ones(3)
    else:
        eta, k = param_rgb(p, "eta.value", 0.0), param_rgb(p, "k.value", 0.0)
        f0 = ((eta - 1) ** 2 + k ** 2) / ((eta + 1) ** 2 + k ** 2)
    return zero, np.clip(f0 * rho_s_scale, 0, 1), n, None, name


def _texture(p: dict, key: str, raw: bool) -> tuple[np.ndarray, np.ndarray]:
    """A bitmap texture's (H, W, 3) float32 linear RGB (grey broadcast; 8-bit data decoded from
    sRGB unless the bitmap is ``raw``) and its (3, 3) ``to_uv`` transform."""
    data = p[f"{key}.data"]
    a = np.array(data, np.float32)
    if np.array(data).dtype == np.uint8:
        a = a / 255.0
        if not raw:
            a = srgb_to_linear(a).astype(np.float32)
    if a.ndim == 2:
        a = a[..., None]
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    to_uv = np.array(p[f"{key}.to_uv"].matrix, np.float64).reshape(3, 3) if f"{key}.to_uv" in p else np.eye(3)
    return np.ascontiguousarray(a[..., :3]), to_uv


def _tessellate(kind, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) world, faces (F, 3)) of Mitsuba's unit ``Rectangle``, ``Sphere``, ``Disk``
    or ``Cylinder`` through the 4x4 ``to_world`` m; faces wound so their normals point outwards
    (sphere, cylinder) or along local +z (rectangle, disk), as Mitsuba's own normals."""
    s = SEGMENTS
    phi = 2 * np.pi * np.arange(s) / s
    ring = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    j = np.arange(s)
    jn = (j + 1) % s
    if kind == "Rectangle":
        local = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
        faces = np.array([[0, 1, 2], [0, 2, 3]])
    elif kind == "Disk":
        local = np.concatenate([[[0, 0, 0]], np.column_stack([ring, np.zeros(s)])])
        faces = np.column_stack([np.zeros(s, int), 1 + j, 1 + jn])
    elif kind == "Cylinder":
        local = np.concatenate([np.column_stack([ring, np.zeros(s)]), np.column_stack([ring, np.ones(s)])])
        faces = np.concatenate([np.column_stack([j, jn, s + jn]), np.column_stack([j, s + jn, s + j])])
    else:  # Sphere: rings of latitude between the poles
        rings = s // 2
        theta = np.pi * np.arange(1, rings) / rings
        body = np.concatenate([np.column_stack([np.sin(t) * ring, np.full(s, np.cos(t))]) for t in theta])
        local = np.concatenate([[[0, 0, 1]], body, [[0, 0, -1]]])
        south = len(local) - 1
        faces = [np.column_stack([np.zeros(s, int), 1 + j, 1 + jn])]
        for r in range(rings - 2):
            a, b = 1 + r * s, 1 + (r + 1) * s
            faces += [np.column_stack([a + j, b + j, b + jn]), np.column_stack([a + j, b + jn, a + jn])]
        last = 1 + (rings - 2) * s
        faces.append(np.column_stack([np.full(s, south), last + jn, last + j]))
        faces = np.concatenate(faces)
    v = local @ m[:3, :3].T + m[:3, 3]
    return v, np.asarray(faces, np.int64)


def _shape_triangles(mi, shape, where: str):
    """(vertices, faces, uv (F, 3, 2) Mitsuba's texture coordinates or None) of one Mitsuba shape."""
    p = mi.traverse(shape)
    if "vertex_positions" in p:
        v = np.array(p["vertex_positions"], np.float64).reshape(-1, 3)
        f = np.array(p["faces"], np.int64).reshape(-1, 3)
        uv = None
        if "vertex_texcoords" in p and np.size(p["vertex_texcoords"]) == 2 * len(v):
            uv = np.array(p["vertex_texcoords"], np.float64).reshape(-1, 2)[f]
        return v, f, uv
    analytic = ("Sphere", "Disk", "Cylinder", "Rectangle")
    kind = next((k for k in analytic if shape.shape_type() == int(getattr(mi.ShapeType, k))), shape.class_name())
    if kind not in analytic:
        raise LightcutsError(f"{where}: shape type {kind!r} is not read (meshes, rectangle, cube, sphere, "
                             "disk, cylinder are)")
    m = np.array(p["to_world"].matrix, np.float64).reshape(4, 4)
    v, f = _tessellate(kind, m)
    if kind == "Rectangle":  # Mitsuba's uv: the local (x, y) from [-1, 1]^2 onto [0, 1]^2
        local = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
        return v, f, local[f]
    return v, f, None


def xml_camera(mi, mi_scene, where: str) -> Camera | None:
    """The first sensor as a pinhole Camera (None without a sensor); vertical fov from ``x_fov``."""
    sensors = mi_scene.sensors()
    if not sensors:
        return None
    sensor = sensors[0]
    p = mi.traverse(sensor)
    if "x_fov" not in p:
        raise LightcutsError(f"{where}: sensor {sensor.class_name()!r} is not read (a perspective one is)")
    m = np.array(p["to_world"].matrix, np.float64).reshape(4, 4)
    width, height = (int(x) for x in sensor.film().size())
    x_fov = float(np.array(p["x_fov"]).reshape(-1)[0])
    fov = math.degrees(2 * math.atan(math.tan(math.radians(x_fov) / 2) * height / width))
    position = m[:3, 3]
    return Camera(position, position + m[:3, 2], m[:3, 1], fov, width, height)


_SUMMARIES: dict = {}


def xml_summary(path, where: str = "scene.mitsuba") -> tuple[XmlEmitters, tuple | None]:
    """(the file's emitters other than area lights (lightcuts.scene.mitsuba_emitters), its film's
    (width, height) or None), read once per file version (path, size, modification time) in a
    process; LightcutsError for an emitter that is not read."""
    p = regular_file(path, f"{where}: {path}")
    st = p.stat()
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _SUMMARIES:
        mi, mi_scene = load_xml(p, where)
        sensors = mi_scene.sensors()
        size = tuple(int(x) for x in sensors[0].film().size()) if sensors else None
        _SUMMARIES.clear()
        _SUMMARIES[key] = (read_emitters(mi, mi_scene, where), size)
    return _SUMMARIES[key]


def xml_settings(cfg):
    """``cfg`` with what its ``scene.mitsuba`` file sets and the config does not: ``lights.sun``
    from a directional emitter, ``lights.environment`` (neither ``file`` nor ``procedural``: the
    file's, :func:`lightcuts.lights.generate.load_environment`) from a constant or envmap emitter,
    ``camera.resolution`` from the film. A config's ``lights.environment`` that names neither takes the
    file's with its own ``count``. LightcutsError naming the ``lights`` key when the config and the
    file both give a sun or an environment, when the config scales or rotates the file's
    environment (the file's ``scale`` and ``to_world`` do that), or when the config asks for the
    file's environment and the file has none."""
    from lightcuts.config.schema import Environment, Sun

    emitters, size = xml_summary(cfg.resolve(cfg.scene.mitsuba))
    lights, camera = cfg.lights, cfg.camera
    sun, env, own = emitters.sun, emitters.environment, lights.environment
    if sun is not None:
        if lights.sun is not None:
            raise LightcutsError("lights.sun: the scene.mitsuba file has a directional emitter, its sun; "
                                 "remove one of the two")
        lights = lights.model_copy(update={"sun": Sun(direction=sun[0].tolist(), irradiance=sun[1].tolist())})
    from_file = own is not None and own.file is None and own.procedural is None
    if env is not None and own is not None and not from_file:
        raise LightcutsError("lights.environment: the scene.mitsuba file has a constant or envmap emitter, its "
                             "environment; remove one of the two")
    if env is not None and own is not None and (own.scale != 1.0 or own.rotate != 0.0):
        raise LightcutsError("lights.environment: scale and rotate do not apply to the scene.mitsuba file's "
                             "environment (its emitter's scale and to_world give them)")
    if env is None and from_file:
        raise LightcutsError("lights.environment: gives neither file nor procedural, and the scene.mitsuba file "
                             "has no constant or envmap emitter")
    if env is not None and own is None:
        lights = lights.model_copy(update={"environment": Environment()})
    if size is not None and camera.resolution is None:
        camera = camera.model_copy(update={"resolution": list(size)})
    return cfg.model_copy(update={"lights": lights, "camera": camera})


#: How each mapped BSDF's lightcuts material relates to Mitsuba's (for reports).
MAPPING_NOTES = {
    "diffuse": "exact (Lambert)",
    "plastic": "Lambert + Phong stand-in: albedo = the diffuse lobe at normal incidence, a Phong mirror of F0",
    "roughplastic": "Lambert + Phong stand-in: albedo = the diffuse lobe at normal incidence, Phong lobe "
                    "n = 2 / alpha^2 - 2 of F0",
    "conductor": "Phong stand-in: a mirror of the Fresnel reflectance at normal incidence",
    "roughconductor": "Phong stand-in: lobe n = 2 / alpha^2 - 2 of the Fresnel reflectance at normal incidence",
}


def bsdf_mapping(path, where: str = "scene.mitsuba") -> dict:
    """Per Mitsuba BSDF plugin of the file's shapes (as Mitsuba holds them: it merges meshes that
    share a BSDF): ``{"shapes": count, "mapping": note}`` (``twosided`` counted under the BSDF it
    wraps), for reports."""
    mi, mi_scene = load_xml(path, where)
    out: dict = {}
    for i, shape in enumerate(mi_scene.shapes()):
        bsdf = shape.bsdf()
        name = map_bsdf(mi, bsdf, f"{where}: shape {shape.id() or i}")[4] if bsdf is not None else "diffuse"
        if name == "twosided":
            match = re.search(r"brdf\[0\] = (\w+)\[", str(bsdf))
            name = MAPPED_BSDFS.get(match.group(1), name) if match else name
        entry = out.setdefault(name, {"shapes": 0, "mapping": MAPPING_NOTES.get(name, "")})
        entry["shapes"] += 1
    return out


def load_mitsuba_xml(path, name: str = "scene", where: str = "scene.mitsuba",
                     budget: TexelBudget | None = None) -> tuple[Scene, tuple | None]:
    """(the Scene of the XML file with its sensor's camera, its sun or None); see the module
    docstring. LightcutsError ``<where>: ...`` for a file Mitsuba rejects or a feature not read.
    ``budget``: the scene's texel budget (lightcuts.limits.MAX_SCENE_TEXELS), which the file's
    textures take from."""
    budget = TexelBudget() if budget is None else budget
    mi, mi_scene = load_xml(path, where)
    sun = read_emitters(mi, mi_scene, where).sun
    parts, images = [], []
    for i, shape in enumerate(mi_scene.shapes()):
        label = f"{where}: shape {shape.id() or i}"
        v, f, uv = _shape_triangles(mi, shape, label)
        bsdf = shape.bsdf()
        rho_d, rho_s, n, texture, _ = map_bsdf(mi, bsdf, label) if bsdf is not None else (
            np.full(3, 0.5), np.zeros(3), 0.0, None, "")
        emission = np.zeros(3)
        if shape.emitter() is not None:
            ep = mi.traverse(shape.emitter())
            raw = re.search(r"raw = 1", str(shape.emitter())) is not None
            emission = _texture(ep, "radiance", raw)[0].reshape(-1, 3).mean(axis=0).astype(np.float64) \
                if "radiance.data" in ep else param_rgb(ep, "radiance.value", 0.0)
        tex_id = -1
        if texture is not None and uv is not None:
            image, to_uv = texture
            budget.take(image.shape[0] * image.shape[1], label)
            tex_id = len(images)
            images.append((image, f"{Path(path).name}: {shape.id() or i}"))
            uv = uv @ to_uv[:2, :2].T + to_uv[:2, 2]
            uv = np.stack([uv[..., 0], 1.0 - uv[..., 1]], axis=-1)  # Mitsuba's v = 0 is the image's top row
        elif texture is not None:
            rho_d = rho_d * texture[0].reshape(-1, 3).mean(axis=0)  # no uv: the texture's mean
        parts.append((v, f, rho_d, rho_s, n, emission, tex_id, uv))
    if not parts:
        raise LightcutsError(f"{where}: {path}: no shapes")
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    counts = [len(p[1]) for p in parts]
    rep = lambda k: np.concatenate([np.repeat(np.asarray(p[k], np.float64)[None], c, axis=0)  # noqa: E731
                                    for p, c in zip(parts, counts)])
    tex = {}
    if images:
        tex = dict(texture=np.concatenate([np.full(c, p[6], np.int32) for p, c in zip(parts, counts)]),
                   uv=np.concatenate([p[7] if p[7] is not None else np.zeros((c, 3, 2))
                                      for p, c in zip(parts, counts)]),
                   textures=TextureSet.of([im for im, _ in images], [nm for _, nm in images]))
    scene = Scene(np.concatenate([p[0] for p in parts]),
                  np.concatenate([p[1] + o for p, o in zip(parts, offsets)]),
                  rep(2), rep(3), np.concatenate([np.full(c, p[4]) for p, c in zip(parts, counts)]), rep(5),
                  xml_camera(mi, mi_scene, where), name, **tex)
    return scene, sun
