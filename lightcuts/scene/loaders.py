"""Mesh files -> Scene, through trimesh: OBJ (+MTL), PLY, glTF/GLB.

The materials, per triangle, are the files' (lightcuts.scene.materials: MTL values and ``map_Kd``,
glTF metallic-roughness mapped onto Lambert + Phong, textures); PLY, or any geometry without a
material, is diffuse grey. A ``material`` argument replaces whatever the file had, on every
triangle (textures included).

Lengths are kept in the file's units; place meshes with ``scale``/``rotate``/``translate``.
"""

from __future__ import annotations

import io
import math
import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from pydantic import ValidationError

from lightcuts.config.schema import Material
from lightcuts.errors import LightcutsError
from lightcuts.scene.files import regular_file
from lightcuts.scene.gltf import GltfFile
from lightcuts.scene.materials import FileMaterial, MtlResolver, obj_material
from lightcuts.scene.scene import Camera, Scene
from lightcuts.scene.textures import TexelBudget, TextureSet, check_uv, face_texture_means

SUPPORTED = (".obj", ".ply", ".gltf", ".glb")

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
              key: str = "scene.meshes.0", budget: TexelBudget | None = None) -> Scene:
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
    budget : TexelBudget, optional
        The texels the scene's textures may still take (lightcuts.limits.MAX_SCENE_TEXELS); shared
        by the meshes of one scene.

    Returns
    -------
    Scene
        Per-triangle materials, no camera, named after the file's stem.

    Raises
    ------
    LightcutsError
        One line ``<key>: <path>: <problem>`` for a missing or unreadable file, an unsupported
        extension, a malformed file or material (glTF: lightcuts.scene.gltf), a texture missing,
        unreadable or beyond the texel limits, no triangles, non-finite vertices or texture
        coordinates, or emission beyond the limits (:meth:`Scene.check_emission`). Degenerate
        (zero-area) triangles are dropped with a warning naming the file and the count.
    """
    path = Path(path)
    where = f"{key}: {path}"
    ext = path.suffix.lower()
    if ext not in SUPPORTED:
        raise LightcutsError(f"{where}: unsupported mesh format {path.suffix or '(no extension)'!r}; "
                             f"supported: {', '.join(SUPPORTED)}")
    regular_file(path, where)
    scale_v = _vector(scale, "scale", key, allow_scalar=True)
    if np.any(scale_v == 0):
        raise LightcutsError(f"{key}.scale: must be non-zero on every axis, got {scale!r}")
    rotation = euler_xyz(_vector(rotate, "rotate", key, allow_scalar=False))
    offset = _vector(translate, "translate", key, allow_scalar=False)
    override = as_material(material, f"{key}.material") if material is not None else None

    import trimesh

    budget = TexelBudget() if budget is None else budget
    mtl = MtlResolver(path, where) if ext == ".obj" and override is None else None
    gltf = GltfFile(path, where, budget, materials=override is None) if ext in (".gltf", ".glb") else None
    try:
        if ext == ".obj":
            options = {"resolver": mtl} if mtl is not None else {"skip_materials": True}
            loaded = trimesh.load(io.BytesIO(_obj_text(path).encode("utf-8")), file_type="obj", force="scene",
                                  process=False, **options)
        elif gltf is not None:
            loaded = trimesh.load(io.BytesIO(gltf.glb), file_type="glb", force="scene", process=False)
        else:
            loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types on malformed OBJ and PLY files
        reason = str(exc).strip().splitlines()
        raise LightcutsError(f"{where}: cannot read mesh: trimesh's {ext[1:].upper()} reader failed "
                             f"({type(exc).__name__}{': ' + reason[0] if reason else ''})") from None
    if mtl is not None:
        if mtl.error is not None:
            raise mtl.error
        for missing in mtl.missing:
            warnings.warn(f"{where}: material library {missing}; its materials get the default",
                          stacklevel=2)

    parts = []  # (vertices, faces, FileMaterial, corner uv (F, 3, 2) or None) per geometry instance
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
        if override is not None:
            mat = FileMaterial(override.albedo, override.specular, override.exponent, override.emission)
        elif gltf is not None:
            mat = gltf.material_of(geom)
        else:
            mat = obj_material(geom, mtl.materials if mtl is not None else None, where, images, budget)
        uv = None
        if mat.texture is not None or mat.emissive is not None:
            vuv = getattr(geom.visual, "uv", None)
            textured = f"{where}: a textured material ({mat.texture_name or 'emissive texture'})"
            if vuv is None or len(vuv) != len(v):
                raise LightcutsError(f"{textured} on triangles without texture coordinates")
            check_uv(np.asarray(vuv, np.float64)[f], textured)
            with np.errstate(over="ignore", invalid="ignore"):
                uv = np.asarray(vuv, np.float64)[f] * mat.uv_scale + mat.uv_offset
            check_uv(uv, f"{textured}, its coordinates moved and scaled by map_Kd -o and -s")
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

    textured = face_tex >= 0
    if textured.any():
        check_uv(face_uv[textured], where, vertices, faces[textured])
    scene = Scene(vertices, faces, albedo, specular, exponent, emission, camera=None, name=path.stem,
                  uv=face_uv, texture=face_tex, textures=textures)
    scene.check_emission(where)
    return scene


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
        textures, bases = TextureSet.concatenate([s.textures for s in scenes if s.textured])
        bases = iter(bases)
        ids, uvs = [], []
        for s in scenes:
            if s.textured:
                ids.append(np.where(s.texture >= 0, s.texture + next(bases), -1))
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
