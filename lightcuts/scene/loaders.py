"""Mesh files -> Scene, through trimesh: OBJ (+MTL), PLY, glTF/GLB.

Materials read from the files (docs/math.md, "Materials from files"):

- OBJ/MTL, per ``usemtl`` group: ``Kd`` -> albedo, ``Ks`` -> specular, ``Ns`` -> Phong exponent,
  ``Ke`` -> emitted radiance; ``illum 0`` or ``1`` (no highlights, by the MTL spec) -> specular 0;
  ``map_Kd`` -> albedo texture, multiplying ``Kd`` (options ``-o`` and ``-s`` move and scale its
  coordinates; the others are skipped, and it always repeats). trimesh groups the faces by
  ``usemtl`` and reads the ``vt`` coordinates; the values come from ``parse_mtl`` (full precision),
  not from trimesh's own MTL parser, which keeps Ks/Ns/Ke only as raw extras, quantises colours to 8
  bits and silently drops all of a file's materials on an entry it does not parse (see
  ``_MtlResolver``). A material without ``Kd`` gets the default albedo. A missing material library
  is a warning (its materials get the default), a malformed entry or a missing texture an error.
- glTF/GLB, per primitive, the metallic-roughness model mapped onto Lambert + Phong (:func:`pbr_to_phong`):
  ``baseColorFactor`` (trimesh stores it as 8-bit RGBA, so it is exact to 1/255) and
  ``baseColorTexture`` -> the diffuse albedo and its texture, ``metallicFactor`` and
  ``roughnessFactor`` -> the specular reflectance and exponent, ``emissiveFactor`` times
  ``emissiveTexture`` (averaged over each triangle: emitters have one radiance per triangle) ->
  emission. ``TEXCOORD_0`` only; ``metallicRoughnessTexture``, normal and occlusion maps and
  extensions are not read. Node transforms are baked into the vertices.
- PLY, or any geometry without a material: diffuse, albedo ``DEFAULT_ALBEDO`` (0.5 grey).

A ``material`` argument replaces whatever the file had, on every triangle (textures included).

Lengths are kept in the file's units; place meshes with ``scale``/``rotate``/``translate``.
"""

from __future__ import annotations

import io
import math
import os
import warnings
from pathlib import Path
from typing import Mapping, NamedTuple, Sequence

import numpy as np
from pydantic import ValidationError

from lightcuts.config.schema import Material
from lightcuts.errors import LightcutsError
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.textures import TextureSet, face_texture_means, image_to_linear, read_image

SUPPORTED = (".obj", ".ply", ".gltf", ".glb")
DEFAULT_ALBEDO = 0.5

#: glTF's reflectance of a dielectric at normal incidence (the metallic-roughness model's 0.04).
DIELECTRIC_F0 = 0.04
#: Largest Phong exponent a glTF roughness maps to (roughness 0, a mirror).
MAX_PBR_EXPONENT = 1.0e4
#: MTL texture options (``map_Kd -o u v w file``) and how many arguments each takes (-o/-s/-t: 1 to 3).
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-mm": 2, "-texres": 1,
                "-bm": 1, "-imfchan": 1, "-type": 1, "-o": 3, "-s": 3, "-t": 3}

# A triangle is degenerate when |e1 x e2| (twice its area) is below this fraction of the squared
# bounding-box diagonal: far below any triangle a renderer can resolve, far above float64 round-off
# of an exactly collinear triple.
DEGENERATE_RELATIVE_AREA = 1e-12


def euler_xyz(rotate_deg: Sequence[float]) -> np.ndarray:
    """(3, 3) rotation: about x by rx, then y by ry, then z by rz (degrees, fixed world axes),
    i.e. ``Rz @ Ry @ Rx`` acting on column vectors."""
    rx, ry, rz = np.radians(np.asarray(rotate_deg, np.float64))
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rot_z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rot_z @ rot_y @ rot_x


def as_material(value, key: str) -> Material:
    """A Material from a Material or a mapping; LightcutsError naming ``key.<field>`` if invalid.

    Also rejects NaN and infinite values, which the schema's float fields let through.
    """
    if isinstance(value, Material):
        mat = value
    elif isinstance(value, Mapping):
        try:
            mat = Material.model_validate(dict(value))
        except ValidationError as exc:
            e = exc.errors()[0]
            field = ".".join(str(p) for p in e["loc"])
            msg = "unknown key" if e["type"] == "extra_forbidden" else e["msg"]
            raise LightcutsError(f"{key}.{field}: {msg}") from None
    else:
        raise LightcutsError(f"{key}: expected a material mapping, got {type(value).__name__}")
    for field in ("albedo", "specular", "exponent", "emission"):
        if not np.all(np.isfinite(getattr(mat, field))):
            raise LightcutsError(f"{key}.{field}: values must be finite, got {getattr(mat, field)!r}")
    return mat


def _vector(value, name: str, key: str, allow_scalar: bool) -> np.ndarray:
    a = np.asarray(value, np.float64)
    if allow_scalar and a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,):
        raise LightcutsError(f"{key}.{name}: expected {'a number or ' if allow_scalar else ''}3 numbers, "
                             f"got {value!r}")
    if not np.all(np.isfinite(a)):
        raise LightcutsError(f"{key}.{name}: values must be finite, got {value!r}")
    return a


def _numbers(args: list[str], n_allowed: tuple[int, ...], what: str, where: str) -> np.ndarray:
    """MTL arguments -> float64 array of one of the allowed lengths, finite and non-negative."""
    try:
        a = np.array([float(x) for x in args], np.float64)
    except ValueError:
        a = np.empty(0)
        args = args or ["(nothing)"]
    if a.size not in n_allowed or not np.all(np.isfinite(a)) or np.any(a < 0):
        n = " or ".join(str(k) for k in n_allowed)
        raise LightcutsError(f"{where}: {what} expects {n} finite non-negative numbers, got {' '.join(args)!r}")
    return a


def parse_mtl(text: str, where: str) -> dict[str, dict]:
    """An MTL file's materials: name -> dict with any of ``kd``, ``ks``, ``ke`` ((3,) float64),
    ``ns`` (float), ``illum`` (int), ``map_kd`` (:func:`parse_map`). Other statements (other maps,
    ``Ka``, ``Ni``, ``d``...) are ignored.

    A colour with one value is grey (MTL spec); ``spectral``/``xyz`` colour forms are rejected.
    ``where`` prefixes error messages, which add the line number.
    """
    materials: dict[str, dict] = {}
    current = None
    for lineno, line in enumerate(text.splitlines(), 1):
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        key, args = tokens[0].lower(), tokens[1:]
        if key == "newmtl":
            name = " ".join(args)
            current = materials.setdefault(name, {})
            continue
        if current is None or key not in ("kd", "ks", "ke", "ns", "illum", "map_kd"):
            continue
        here = f"{where}:{lineno}: material {name!r}"
        if key == "map_kd":
            current[key] = parse_map(args, here)
            continue
        if key in ("kd", "ks", "ke"):
            if args and args[0].lower() in ("spectral", "xyz"):
                raise LightcutsError(f"{here}: {tokens[0]} {args[0]} is not supported; give r g b")
            current[key] = np.broadcast_to(_numbers(args, (1, 3), tokens[0], here), 3).copy()
        elif key == "ns":
            current[key] = float(_numbers(args, (1,), tokens[0], here)[0])
        else:
            current[key] = int(_numbers(args, (1,), tokens[0], here)[0])
    return materials


def parse_map(args: list[str], where: str) -> dict:
    """``map_Kd`` arguments -> ``{"file": str, "offset": (2,), "scale": (2,)}``: the options ``-o``
    and ``-s`` (u, v; w is ignored) are kept, the others skipped; the rest is the file name."""
    offset, scale = np.zeros(2), np.ones(2)
    i = 0
    while i < len(args) and args[i].lower() in _MAP_OPTIONS:
        opt, n = args[i].lower(), _MAP_OPTIONS[args[i].lower()]
        values = []
        i += 1
        while i < len(args) and len(values) < n:
            try:
                values.append(float(args[i]))
            except ValueError:
                if opt in ("-o", "-s", "-t", "-mm"):
                    break
                values.append(args[i])
            i += 1
        if not values or (opt in ("-o", "-s", "-t") and not all(np.isfinite(values))):
            raise LightcutsError(f"{where}: map_Kd {opt} needs a value")
        if opt == "-o":
            offset[:min(2, len(values))] = values[:2]
        elif opt == "-s":
            scale[:min(2, len(values))] = values[:2]
    name = " ".join(args[i:])
    if not name:
        raise LightcutsError(f"{where}: map_Kd names no file")
    return {"file": name, "offset": offset, "scale": scale}


class _MtlResolver:
    """Gives trimesh's OBJ loader its material library reduced to the ``newmtl`` names, and keeps
    the values parsed by ``parse_mtl``.

    trimesh parses MTL colours itself, but quantises them to 8 bits, and when one entry has a form
    it does not take (a one-value ``Kd``, which the MTL spec allows) it drops every material of the
    file without an error. Handing it the names alone keeps its per-``usemtl`` grouping of faces
    (each group's ``visual.material.name``) and leaves the values to ``parse_mtl``. trimesh swallows
    exceptions raised here, so problems are recorded and raised by ``load_mesh`` afterwards.
    """

    def __init__(self, obj_path: Path, where: str):
        self.parent = obj_path.parent
        self.where = where
        self.materials: dict[str, dict] = {}
        self.error: LightcutsError | None = None
        self.missing: list[str] = []

    def __getitem__(self, name: str) -> bytes:
        return self.get(name)

    def get(self, name: str) -> bytes:
        name = name.strip()
        # "mtllib a.mtl b.mtl" names several libraries (trimesh passes the whole line).
        names = [name] if (self.parent / name).is_file() else name.split()
        for n in names:
            path = self.parent / n
            try:
                text = path.read_text(errors="replace")
            except OSError:
                self.missing.append(str(path))
                continue
            try:
                mats = parse_mtl(text, f"{self.where}: {path}")
            except LightcutsError as exc:
                self.error = self.error or exc
                continue
            for values in mats.values():
                if "map_kd" in values:  # texture paths are relative to the library
                    values["map_kd"]["file"] = str(path.parent / values["map_kd"]["file"].replace("\\", "/"))
            self.materials.update(mats)
        return "".join(f"newmtl {m}\n" for m in self.materials).encode()


def pbr_to_phong(base, metallic: float, roughness: float) -> tuple[np.ndarray, np.ndarray, float]:
    """glTF metallic-roughness -> (rho_d (3,), rho_s (3,), Phong exponent n).

    The specular reflectance is the model's reflectance at normal incidence, F0 = 0.04 for a
    dielectric blended to the base colour for a metal: ``rho_s = 0.04 (1 - m) + base m``; the
    diffuse part is what a dielectric does not reflect specularly: ``rho_d = base (1 - m)(1 - 0.04)``,
    so rho_d + rho_s <= 1. The lobe: glTF's alpha = roughness^2 is a GGX / Beckmann width, and a
    Beckmann lobe of width alpha is close to Phong's with ``n = 2 / alpha^2 - 2`` (Walter et al.
    2007), capped at ``MAX_PBR_EXPONENT`` (roughness 0).
    """
    base = np.clip(np.asarray(base, np.float64).reshape(3), 0.0, 1.0)
    m = float(np.clip(metallic, 0.0, 1.0))
    alpha = float(np.clip(roughness, 0.0, 1.0)) ** 2
    n = MAX_PBR_EXPONENT if alpha ** 2 <= 2.0 / (MAX_PBR_EXPONENT + 2.0) else 2.0 / alpha ** 2 - 2.0
    return base * (1.0 - m) * (1.0 - DIELECTRIC_F0), DIELECTRIC_F0 * (1.0 - m) + base * m, max(0.0, n)


class _FileMaterial(NamedTuple):
    """One geometry's material as its file gives it: the per-triangle values, and the albedo
    texture (linear image, a name to share it by, the uv offset and scale) and emissive texture."""

    albedo: np.ndarray
    specular: np.ndarray
    exponent: float
    emission: np.ndarray
    texture: np.ndarray | None = None
    texture_name: str = ""
    uv_offset: np.ndarray = np.zeros(2)
    uv_scale: np.ndarray = np.ones(2)
    emissive: np.ndarray | None = None


def _pil_linear(image) -> np.ndarray:
    """A texture trimesh hands over (PIL image or array) -> (H, W, 3) float32 linear RGB."""
    a = np.asarray(image.convert("RGB") if hasattr(image, "convert") else image)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.dtype != np.uint8:
        a = np.clip(np.round(np.asarray(a, np.float64) * (255.0 if a.max() <= 1.0 else 1.0)), 0, 255)
    return image_to_linear(a[:, :, :3].astype(np.uint8))


def _file_material(geometry, obj_materials: dict | None, where: str, images: dict) -> _FileMaterial:
    """The material of one trimesh geometry (module docstring). ``obj_materials``: for OBJ files,
    the ``parse_mtl`` values by material name; None otherwise. ``images``: texture file -> linear
    image, read once per file."""
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    mat = getattr(geometry.visual, "material", None)
    out = _FileMaterial(np.full(3, DEFAULT_ALBEDO), np.zeros(3), 0.0, np.zeros(3))
    if obj_materials is not None:
        values = obj_materials.get(mat.name) if isinstance(mat, SimpleMaterial) else None
        if values is not None:
            out = out._replace(albedo=values.get("kd", out.albedo), specular=values.get("ks", out.specular),
                               exponent=values.get("ns", out.exponent), emission=values.get("ke", out.emission))
            if values.get("illum") in (0, 1):  # no highlights, by the MTL spec
                out = out._replace(specular=np.zeros(3))
            if "map_kd" in values:
                m = values["map_kd"]
                if m["file"] not in images:
                    images[m["file"]] = read_image(m["file"], f"{where}: material {mat.name!r}")
                out = out._replace(texture=images[m["file"]], texture_name=m["file"], uv_offset=m["offset"],
                                   uv_scale=m["scale"])
    elif isinstance(mat, PBRMaterial):
        # glTF defaults: base colour 1, metallic 1, roughness 1, emissive 0
        base = np.ones(3) if mat.baseColorFactor is None else np.asarray(mat.baseColorFactor[:3], np.float64) / 255.0
        metallic = 1.0 if mat.metallicFactor is None else float(mat.metallicFactor)
        roughness = 1.0 if mat.roughnessFactor is None else float(mat.roughnessFactor)
        rd, rs, n = pbr_to_phong(base, metallic, roughness)
        emission = np.zeros(3) if mat.emissiveFactor is None else np.asarray(mat.emissiveFactor, np.float64)
        out = out._replace(albedo=rd, specular=rs, exponent=n, emission=emission.reshape(3))
        for attr, slot in (("baseColorTexture", "texture"), ("emissiveTexture", "emissive")):
            image = getattr(mat, attr)
            if image is not None:
                key = f"glTF {mat.name or 'material'} {attr} {id(image)}"
                if key not in images:
                    images[key] = _pil_linear(image)
                out = out._replace(**{slot: images[key]}, **({"texture_name": key} if slot == "texture" else {}))
    return out


def _obj_text(path: Path) -> str:
    """An OBJ file's text: UTF-8 if it decodes so, else Latin-1, which maps every byte to a character.

    OBJ keywords and numbers are ASCII, so any 8-bit encoding only differs in comments and names.
    trimesh would otherwise guess the encoding of non-UTF-8 bytes with ``charset_normalizer``, an
    optional dependency; decoding here keeps the loader to the installed packages.
    """
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def load_mesh(path, scale: float | Sequence[float] = 1.0, rotate: Sequence[float] = (0.0, 0.0, 0.0),
              translate: Sequence[float] = (0.0, 0.0, 0.0), material: Material | Mapping | None = None,
              key: str = "scene.meshes.0") -> Scene:
    """Read a triangle mesh file (OBJ with MTL, PLY, glTF/GLB) into a Scene.

    Parameters
    ----------
    path : str or Path
    scale : float or (3,) float
        Per-axis scale; a negative product mirrors the mesh, and the winding is flipped so that
        normals keep pointing the same way relative to the surface.
    rotate : (3,) float
        Euler angles in degrees about the fixed x, then y, then z axes (``euler_xyz``).
    translate : (3,) float
        Applied last: ``v_world = R @ (scale * v_file) + translate`` (file node transforms first).
    material : Material or mapping, optional
        Replaces the file's materials on every triangle.
    key : str
        The config key named in error messages.

    Returns
    -------
    Scene
        Per-triangle materials, no camera, named after the file's stem.

    Raises
    ------
    LightcutsError
        One line ``<key>: <path>: <problem>`` for a missing or unreadable file, an unsupported
        extension, no triangles, or non-finite vertices. Degenerate (zero-area) triangles are
        dropped with a warning naming the file and the count.
    """
    path = Path(path)
    where = f"{key}: {path}"
    ext = path.suffix.lower()
    if ext not in SUPPORTED:
        raise LightcutsError(f"{where}: unsupported mesh format {path.suffix or '(no extension)'!r}; "
                             f"supported: {', '.join(SUPPORTED)}")
    if not path.is_file():
        raise LightcutsError(f"{where}: no such file")
    if not os.access(path, os.R_OK):
        raise LightcutsError(f"{where}: cannot read file (permission denied)")
    scale_v = _vector(scale, "scale", key, allow_scalar=True)
    if np.any(scale_v == 0):
        raise LightcutsError(f"{key}.scale: must be non-zero on every axis, got {scale!r}")
    rotation = euler_xyz(_vector(rotate, "rotate", key, allow_scalar=False))
    offset = _vector(translate, "translate", key, allow_scalar=False)
    override = as_material(material, f"{key}.material") if material is not None else None

    import trimesh

    mtl = _MtlResolver(path, where) if ext == ".obj" and override is None else None
    options = {}
    if ext == ".obj":
        options = {"resolver": mtl} if mtl is not None else {"skip_materials": True}
    try:
        if ext == ".obj":
            loaded = trimesh.load(io.BytesIO(_obj_text(path).encode("utf-8")), file_type="obj", force="scene",
                                  process=False, **options)
        else:
            loaded = trimesh.load(str(path), force="scene", process=False, **options)
    except Exception as exc:  # trimesh raises many types on malformed files
        raise LightcutsError(f"{where}: cannot read mesh ({type(exc).__name__}: {exc})".splitlines()[0]) from None
    if mtl is not None:
        if mtl.error is not None:
            raise mtl.error
        for missing in mtl.missing:
            warnings.warn(f"{where}: material library {missing} not found; its materials get the default",
                          stacklevel=2)

    parts = []  # (vertices, faces, _FileMaterial, corner uv (F, 3, 2) or None) per geometry instance
    images: dict = {}
    for node in sorted(loaded.graph.nodes_geometry):
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        v = np.asarray(geom.vertices, np.float64)
        f = np.asarray(geom.faces, np.int64)
        if f.min() < 0 or f.max() >= len(v):
            raise LightcutsError(f"{where}: face indices out of range (mesh has {len(v)} vertices)")
        bad = ~np.all(np.isfinite(v), axis=1)
        if bad.any():
            raise LightcutsError(f"{where}: {int(bad.sum())} vertices have NaN or infinite coordinates")
        m = np.asarray(transform, np.float64)
        v = v @ m[:3, :3].T + m[:3, 3]
        if np.linalg.det(m[:3, :3]) < 0:
            f = f[:, ::-1]
        mat = (_FileMaterial(override.albedo, override.specular, override.exponent, override.emission)
               if override is not None else
               _file_material(geom, mtl.materials if mtl is not None else None, where, images))
        uv = None
        if mat.texture is not None or mat.emissive is not None:
            vuv = getattr(geom.visual, "uv", None)
            if vuv is None or len(vuv) != len(v) or not np.all(np.isfinite(vuv)):
                raise LightcutsError(f"{where}: a textured material ({mat.texture_name or 'emissive texture'}) "
                                     f"on triangles without texture coordinates")
            uv = np.asarray(vuv, np.float64)[f] * mat.uv_scale + mat.uv_offset
            if mat.emissive is not None:
                one = TextureSet.of([mat.emissive], ["emissive"])
                emission = mat.emission * face_texture_means(one, np.zeros(len(f), np.int32), uv)
                mat = mat._replace(emission=emission, emissive=None)
                if mat.texture is None:
                    uv = None
        parts.append((v, f, mat, uv))
    if not parts:
        raise LightcutsError(f"{where}: no triangles in the file")

    counts = [len(f) for _, f, _, _ in parts]
    starts = np.cumsum([0] + [len(v) for v, _, _, _ in parts[:-1]])
    vertices = np.concatenate([v for v, _, _, _ in parts])
    faces = np.concatenate([f + s for (_, f, _, _), s in zip(parts, starts)])

    def per_face(values, width):
        return np.concatenate([np.broadcast_to(np.asarray(x, np.float64).reshape(-1, width), (n, width))
                               for x, n in zip(values, counts)])

    albedo = per_face([p[2].albedo for p in parts], 3)
    specular = per_face([p[2].specular for p in parts], 3)
    exponent = per_face([p[2].exponent for p in parts], 1)[:, 0]
    emission = per_face([p[2].emission for p in parts], 3)
    face_tex = np.full(len(faces), -1, np.int32)
    face_uv = np.zeros((len(faces), 3, 2))
    ids: dict[str, int] = {}  # texture name -> index
    used_images = []
    for (_, _, mat, uv), s0, n in zip(parts, np.cumsum([0] + counts[:-1]), counts):
        if mat.texture is None:
            continue
        if mat.texture_name not in ids:
            ids[mat.texture_name] = len(used_images)
            used_images.append(mat.texture)
        face_tex[s0:s0 + n] = ids[mat.texture_name]
        face_uv[s0:s0 + n] = uv
    textures = TextureSet.of(used_images, list(ids))

    vertices = (vertices * scale_v) @ rotation.T + offset
    if np.prod(np.sign(scale_v)) < 0:
        faces = faces[:, ::-1]
        face_uv = face_uv[:, ::-1]
    if not np.all(np.isfinite(vertices)):
        raise LightcutsError(f"{where}: vertex coordinates overflow to infinity after the transforms")

    t = vertices[faces]
    twice_area = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    used = vertices[np.unique(faces)]
    diag2 = float(np.sum((used.max(axis=0) - used.min(axis=0)) ** 2))
    keep = twice_area > DEGENERATE_RELATIVE_AREA * diag2
    if not keep.all():
        n_bad = int((~keep).sum())
        if n_bad == len(faces):
            raise LightcutsError(f"{where}: no triangles with non-zero area (all {n_bad} are degenerate)")
        warnings.warn(f"{where}: dropped {n_bad} degenerate (zero-area) triangles of {len(faces)}",
                      stacklevel=2)
        faces, albedo, specular = faces[keep], albedo[keep], specular[keep]
        exponent, emission = exponent[keep], emission[keep]
        face_tex, face_uv = face_tex[keep], face_uv[keep]

    return Scene(vertices, faces, albedo, specular, exponent, emission, camera=None, name=path.stem,
                 uv=face_uv, texture=face_tex, textures=textures)


def concatenate_scenes(scenes: Sequence[Scene], camera: Camera | None = None, name: str | None = None) -> Scene:
    """One Scene holding the triangles of ``scenes`` in order (triangle ids offset accordingly,
    their textures gathered into one set).

    ``camera`` defaults to the first scene's camera that is not None; ``name`` to the first scene's.
    """
    if not scenes:
        raise ValueError("no scenes to concatenate")
    starts = np.cumsum([0] + [len(s.vertices) for s in scenes[:-1]])
    if camera is None:
        camera = next((s.camera for s in scenes if s.camera is not None), None)
    tex = {}
    if any(s.textured for s in scenes):
        textures = TextureSet()
        ids, uvs = [], []
        for s in scenes:
            if s.textured:
                base = textures.extend(s.textures)
                ids.append(np.where(s.texture >= 0, s.texture + base, -1))
                uvs.append(s.uv)
            else:
                ids.append(np.full(s.n_faces, -1, np.int32))
                uvs.append(np.zeros((s.n_faces, 3, 2)))
        tex = dict(uv=np.concatenate(uvs), texture=np.concatenate(ids), textures=textures)
    return Scene(
        np.concatenate([s.vertices for s in scenes]),
        np.concatenate([s.faces.astype(np.int64) + o for s, o in zip(scenes, starts)]),
        np.concatenate([s.albedo for s in scenes]),
        np.concatenate([s.specular for s in scenes]),
        np.concatenate([s.exponent for s in scenes]),
        np.concatenate([s.emission for s in scenes]),
        camera=camera,
        name=name if name is not None else scenes[0].name,
        **tex,
    )
