r"""A lightcuts Scene (camera, sun and environment map included) as a Mitsuba 3 scene dict.

:func:`scene_dict` returns the dict for ``mi.load_dict``; every quantity keeps its lightcuts meaning:

* Meshes: one ``mi.Mesh`` per material group (triangles with equal albedo, specular, exponent,
  emission and texture), built from the Scene's arrays (flat shading, face normals by the
  right-hand rule); a textured group's mesh has its corners' texture coordinates, v flipped to
  Mitsuba's convention (v = 0 at the image's top row).
* Textures: the diffuse reflectance of a textured group is a ``bitmap`` of the linear texels times
  the group's albedo (times the blend's diffuse scale below), ``raw`` (no further colour
  conversion), bilinear and repeating, as lightcuts filters it.
* Materials: lightcuts shades both sides of a surface, so every non-emitting group's BSDF is wrapped
  in ``twosided``. Diffuse (``rho_s = 0``) is Mitsuba's ``diffuse`` with reflectance ``rho_d``, exact.
  Phong (``f = rho_d / pi + rho_s (n + 2) / (2 pi) cos^n(alpha)``, alpha from the mirror direction;
  docs/math.md) has no Mitsuba plugin and is **approximated** (:func:`phong_bsdf`): a ``blendbsdf``
  of ``diffuse`` and a ``roughconductor`` without Fresnel (``material: none``, a perfect mirror
  whose microfacets follow a Beckmann distribution). A lobe ``cos^n`` about the mirror direction
  is ``exp(-2 n theta_h^2)`` in the half-vector angle theta_h near normal incidence, which is
  Beckmann with ``alpha = sqrt(1 / (2 n + 1))``; the blend weight ``w = max(rho_s) / (max(rho_s) +
  max(rho_d))`` gives the diffuse part ``rho_d / (1 - w)`` and the mirror ``rho_s / w``, so the two
  sum to the lightcuts reflectances (each clipped to 1, which Mitsuba requires, where ``rho_d +
  rho_s > 1``). The approximation differs in lobe shape away from normal incidence and loses the
  microfacet model's shadowing-masking energy.
* Emitters: an emissive group gets an ``area`` emitter with ``radiance`` = the Scene's emission;
  it emits and reflects on its front only (its BSDF is not two-sided), as in lightcuts, where the
  back of an emitter is black.
* Sun (``lights.sun``): a ``directional`` emitter, ``irradiance`` W/m^2 at normal incidence,
  travelling along minus the direction towards the sun.
* Environment map: Mitsuba's ``envmap`` uses lightcuts' direction <-> (u, v) convention (+y up,
  ``u = atan2(x, -z) / 2 pi``, ``v = acos(y) / pi``), but interpolates bilinearly between pixel
  values that it places at ``u = (j + 1/2) / W`` and ``v = i / (H - 1)``, whereas lightcuts' map is
  piecewise constant over cells ``v in [i / H, (i + 1) / H]``. :func:`envmap_for_mitsuba` resamples
  the cells onto Mitsuba's grid (k times finer, the cell value at every grid point, the mean of the
  two neighbours on a horizontal cell edge), so the two agree except within 1/k of a cell of an
  edge, where Mitsuba ramps linearly and the integral is kept. ``rotate`` becomes ``to_world`` (the
  same rotation about +y) and ``scale`` Mitsuba's ``scale``.
* Camera: ``perspective``, vertical ``fov`` (``fov_axis: y``), ``look_at`` with the same up (both
  give image right = forward x up), ``hdrfilm`` of the same size with a box pixel filter
  (``rfilter: box``), cropped to ``render.crop`` when one is given; clip planes enclose the scene;
  multi-jittered pixel samples. With a lens (``camera.aperture > 0``) ``thinlens`` instead, with
  ``aperture_radius`` = the aperture and ``focus_distance`` = ``camera.focus_distance`` (default
  ``|look_at - position|``): both place the plane in focus perpendicular to the view axis at that
  distance and sample the lens disk uniformly.
"""

from __future__ import annotations

import math

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.mitsuba import load_mitsuba

#: Integrators :func:`scene_dict` knows: lightcuts' direct light only, or full paths.
INTEGRATORS = ("direct", "path")
#: Largest width of the resampled environment map Mitsuba receives (see envmap_for_mitsuba).
MAX_ENVMAP_WIDTH = 2048
#: Mitsuba's sampler: multi-jittered samples converge on emitter edges far faster than independent
#: ones; it rounds a sample count it cannot factor up (``render.sample_count`` gives the one used).
SAMPLER = "multijitter"


def phong_alpha(exponent: float) -> float:
    """Beckmann roughness alpha matching a Phong lobe ``cos^n`` about the mirror direction."""
    return math.sqrt(1.0 / (2.0 * float(exponent) + 1.0))


def phong_bsdf(albedo, specular, exponent: float, texture: np.ndarray | None = None) -> dict:
    """Mitsuba BSDF dict (one-sided) for lightcuts' Lambert + Phong material (module docstring).

    albedo, specular : (3,) rho_d, rho_s; exponent : Phong n >= 0; texture : (H, W, 3) linear
    texels multiplying rho_d, or None.
    """
    rd = np.clip(np.asarray(albedo, np.float64), 0.0, None)
    rs = np.clip(np.asarray(specular, np.float64), 0.0, None)
    diffuse = {"type": "diffuse", "reflectance": _reflectance(np.minimum(rd, 1.0), texture)}
    if rs.max() <= 0.0:
        return diffuse
    md, ms = float(rd.max()), float(rs.max())
    glossy = {"type": "roughconductor", "material": "none", "distribution": "beckmann",
              "alpha": phong_alpha(exponent)}
    if md <= 0.0:
        return {**glossy, "specular_reflectance": _rgb(np.minimum(rs, 1.0))}
    w = ms / (ms + md)
    diffuse["reflectance"] = _reflectance(rd / (1.0 - w), texture)
    glossy["specular_reflectance"] = _rgb(np.minimum(rs / w, 1.0))
    return {"type": "blendbsdf", "weight": w, "bsdf_0": diffuse, "bsdf_1": glossy}


def _rgb(v) -> dict:
    return {"type": "rgb", "value": [float(x) for x in v]}


def _reflectance(rd, texture) -> dict:
    """``rd`` (3,) as an rgb value, or the texture times ``rd`` as a bitmap, each clipped to 1."""
    if texture is None:
        return _rgb(np.minimum(rd, 1.0))
    mi = load_mitsuba()
    texels = np.clip(np.asarray(texture, np.float64) * rd, 0.0, 1.0).astype(np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(texels)), "raw": True,
            "filter_type": "bilinear", "wrap_mode": "repeat"}


def material_groups(scene) -> list[np.ndarray]:
    """Triangle ids (int64 arrays) of each distinct (albedo, specular, exponent, emission, texture),
    in order of first appearance."""
    texture = scene.texture if scene.textured else np.full(scene.n_faces, -1)
    key = np.concatenate([scene.albedo, scene.specular, scene.exponent[:, None], scene.emission,
                          texture[:, None]], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first)
    return [np.flatnonzero(inverse == g) for g in order]


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, bsdf: dict, emission=None, uv=None):
    """One mi.Mesh over the vertices the faces use, with its BSDF and an area emitter if emissive;
    with ``uv`` (F, 3, 2) (lightcuts' convention) every corner gets its own vertex and texcoord."""
    if uv is None:
        used, local = np.unique(faces, return_inverse=True)
        positions = vertices[used]
    else:
        positions = vertices[faces].reshape(-1, 3)
        local = np.arange(positions.shape[0])
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    if emission is not None:
        props["emitter"] = mi.load_dict({"type": "area", "radiance": _rgb(emission)})
    mesh = mi.Mesh(name, vertex_count=len(positions), face_count=len(faces), props=props,
                   has_vertex_normals=False, has_vertex_texcoords=uv is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(positions, np.float32).ravel()
    params["faces"] = np.ascontiguousarray(local.reshape(-1, 3), np.uint32).ravel()
    if uv is not None:
        tc = np.asarray(uv, np.float64).reshape(-1, 2).copy()
        tc[:, 1] = 1.0 - tc[:, 1]
        params["vertex_texcoords"] = np.ascontiguousarray(tc, np.float32).ravel()
    params.update()
    return mesh


def envmap_for_mitsuba(pixels: np.ndarray, k: int | None = None) -> np.ndarray:
    """lightcuts' piecewise-constant lat-long map (H, W, 3) on Mitsuba's bilinear grid (module
    docstring): (k H + 1, k W, 3) float32. Column ``j'`` (at ``u = (j' + 1/2) / (k W)``) takes cell
    column ``j' // k``; row ``i'`` (at ``v = i' / (k H)``) takes cell row ``i' // k``, the mean of
    rows ``i' / k - 1`` and ``i' / k`` on an inner cell edge, the last row at the nadir.
    k : refinement, default the largest that keeps the width <= MAX_ENVMAP_WIDTH, and at least 2.
    """
    pixels = np.asarray(pixels, np.float32)
    h, w = pixels.shape[:2]
    if k is None:
        k = max(2, MAX_ENVMAP_WIDTH // w)
    rows = np.repeat(pixels, k, axis=0)
    out = np.concatenate([rows, pixels[-1:]], axis=0)
    if h > 1:
        out[k * np.arange(1, h)] = 0.5 * (pixels[:-1] + pixels[1:])
    return np.ascontiguousarray(np.repeat(out, k, axis=1), np.float32)


def camera_dict(mi, camera, spp: int, crop=None, scene_bounds=None, aperture: float = 0.0,
                focus_distance: float | None = None) -> dict:
    """The ``perspective`` sensor of a lightcuts Camera (module docstring), about ``spp`` samples
    per pixel (SAMPLER), film cropped to ``crop = (x0, y0, x1, y1)`` if given; ``thinlens`` with
    the lens radius ``aperture > 0`` focused at ``focus_distance`` (None: ``|look_at - position|``)."""
    far = 1e4
    if scene_bounds is not None:
        lo, hi = np.asarray(scene_bounds, np.float64)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        far = 2.0 * float(np.linalg.norm(corners - camera.position, axis=1).max()) + 1.0
    film = {"type": "hdrfilm", "width": int(camera.width), "height": int(camera.height),
            "rfilter": {"type": "box"}, "pixel_format": "rgb", "component_format": "float32"}
    if crop is not None:
        x0, y0, x1, y1 = (int(v) for v in crop)
        film.update(crop_offset_x=x0, crop_offset_y=y0, crop_width=x1 - x0, crop_height=y1 - y0)
    to_world = mi.ScalarTransform4f.look_at(origin=[float(v) for v in camera.position],
                                            target=[float(v) for v in camera.look_at],
                                            up=[float(v) for v in camera.up])
    sensor = {"type": "perspective", "fov": float(camera.fov), "fov_axis": "y", "near_clip": far * 1e-7,
              "far_clip": far, "to_world": to_world, "film": film,
              "sampler": {"type": SAMPLER, "sample_count": int(spp)}}
    if aperture > 0:
        if focus_distance is None:
            focus_distance = float(np.linalg.norm(np.subtract(camera.look_at, camera.position)))
        sensor.update(type="thinlens", aperture_radius=float(aperture), focus_distance=float(focus_distance))
    return sensor


def integrator_dict(integrator: str, max_depth: int = -1) -> dict:
    """``direct`` (one bounce: emitters, sun and environment, with MIS) or ``path`` (``max_depth``
    -1 = unbounded, Russian roulette)."""
    if integrator == "direct":
        return {"type": "direct"}
    if integrator == "path":
        return {"type": "path", "max_depth": int(max_depth)}
    raise LightcutsError(f"--integrator: {integrator!r} is not one of {', '.join(INTEGRATORS)}")


def scene_dict(scene, envmap=None, sun=None, *, spp: int = 16, integrator: str = "path", max_depth: int = -1,
               crop=None, aperture: float = 0.0, focus_distance: float | None = None) -> dict:
    """The Mitsuba scene dict (for ``mi.load_dict``) of ``scene`` and its camera.

    envmap : lightcuts.lights.environment.EnvironmentMap or None; sun : an object with ``direction``
    and ``irradiance`` (3,) (``cfg.lights.sun``) or None; spp : samples per pixel; integrator, max_depth
    : :func:`integrator_dict`; crop : (x0, y0, x1, y1) pixels or None; aperture, focus_distance : the
    camera's thin lens (``camera.aperture``, ``camera.focus_distance``; 0: a pinhole).
    """
    mi = load_mitsuba()
    if scene.camera is None:
        raise LightcutsError("camera: the scene has no camera")
    out = {"type": "scene", "integrator": integrator_dict(integrator, max_depth),
           "sensor": camera_dict(mi, scene.camera, spp, crop, scene.bounds, aperture, focus_distance)}
    for g, ids in enumerate(material_groups(scene)):
        f = ids[0]
        emission = scene.emission[f]
        k = int(scene.texture[f]) if scene.textured else -1
        bsdf = phong_bsdf(scene.albedo[f], scene.specular[f], scene.exponent[f],
                          scene.textures.image(k) if k >= 0 else None)
        emissive = bool(emission.max() > 0)
        if not emissive:
            bsdf = {"type": "twosided", "bsdf": bsdf}
        out[f"mesh_{g:04d}"] = _mesh(mi, f"mesh_{g:04d}", scene.vertices, scene.faces[ids], bsdf,
                                     emission if emissive else None, scene.uv[ids] if k >= 0 else None)
    if sun is not None:
        out["sun"] = sun_dict(sun)
    if envmap is not None:
        out["environment"] = envmap_dict(mi, envmap)
    return out


def sun_dict(sun) -> dict:
    """Mitsuba's ``directional`` emitter of a sun (``direction`` towards it, ``irradiance``)."""
    d = np.asarray(sun.direction, np.float64)
    d = d / np.linalg.norm(d)
    return {"type": "directional", "direction": [float(-x) for x in d], "irradiance": _rgb(sun.irradiance)}


def envmap_dict(mi, envmap) -> dict:
    """Mitsuba's ``envmap`` emitter of an EnvironmentMap: its pixels on Mitsuba's grid
    (:func:`envmap_for_mitsuba`), its scale, its rotation as ``to_world``."""
    m = np.eye(4)
    m[:3, :3] = envmap.rotation
    return {"type": "envmap", "bitmap": mi.Bitmap(envmap_for_mitsuba(envmap.pixels)),
            "scale": float(envmap.scale), "to_world": mi.ScalarTransform4f(m)}


def emitted_power(scene) -> np.ndarray:
    """(3,) RGB power of the Scene's emitters, ``sum pi L_e A`` (one-sided Lambertian emitters)."""
    return math.pi * (scene.emission * scene.face_areas[:, None]).sum(axis=0)


def mitsuba_emitted_power(mi_scene) -> np.ndarray:
    """(3,) RGB power of a loaded Mitsuba scene's area emitters, ``sum pi L_e A`` from Mitsuba's
    own shapes (their surface areas) and emitters (their radiance parameters)."""
    mi = load_mitsuba()
    total = np.zeros(3)
    for shape in mi_scene.shapes():
        e = shape.emitter()
        if e is None:
            continue
        radiance = np.array(mi.traverse(e)["radiance.value"], np.float64).reshape(3)
        total += math.pi * float(shape.surface_area()) * radiance
    return total
