"""Mesh files -> Scene, through trimesh: OBJ (+MTL), PLY, glTF/GLB.

Materials read from the files:

- OBJ/MTL, per ``usemtl`` group: ``Kd`` -> albedo, ``Ks`` -> specular, ``Ns`` -> Phong exponent,
  ``Ke`` -> emitted radiance; ``illum 0`` or ``1`` (no highlights, by the MTL spec) -> specular 0.
  trimesh groups the faces by ``usemtl``; the values come from ``parse_mtl`` (full precision), not
  from trimesh's own MTL parser, which keeps Ks/Ns/Ke only as raw extras, quantises colours to 8 bits
  and silently drops all of a file's materials on an entry it does not parse (see ``_MtlResolver``).
  A material without ``Kd`` gets the default albedo; textures (``map_Kd``...) are ignored. A missing
  material library is a warning (its materials get the default), a malformed entry an error.
- glTF/GLB, per primitive: ``baseColorFactor`` -> albedo (trimesh stores it as 8-bit RGBA, so it is
  exact to 1/255), ``emissiveFactor`` -> emission; no specular (metallic-roughness has no Phong
  equivalent). Node transforms are baked into the vertices.
- PLY, or any geometry without a material: diffuse, albedo ``DEFAULT_ALBEDO`` (0.5 grey).

A ``material`` argument replaces whatever the file had, on every triangle.

Lengths are kept in the file's units; place meshes with ``scale``/``rotate``/``translate``.
"""

from __future__ import annotations

import io
import math
import os
import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from pydantic import ValidationError

from lightcuts.config.schema import Material
from lightcuts.errors import LightcutsError
from lightcuts.scene.scene import Camera, Scene

SUPPORTED = (".obj", ".ply", ".gltf", ".glb")
DEFAULT_ALBEDO = 0.5

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
    ``ns`` (float), ``illum`` (int). Other statements (textures, ``Ka``, ``Ni``, ``d``...) are ignored.

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
        if current is None or key not in ("kd", "ks", "ke", "ns", "illum"):
            continue
        here = f"{where}:{lineno}: material {name!r}"
        if key in ("kd", "ks", "ke"):
            if args and args[0].lower() in ("spectral", "xyz"):
                raise LightcutsError(f"{here}: {tokens[0]} {args[0]} is not supported; give r g b")
            current[key] = np.broadcast_to(_numbers(args, (1, 3), tokens[0], here), 3).copy()
        elif key == "ns":
            current[key] = float(_numbers(args, (1,), tokens[0], here)[0])
        else:
            current[key] = int(_numbers(args, (1,), tokens[0], here)[0])
    return materials


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
                self.materials.update(parse_mtl(text, f"{self.where}: {path}"))
            except LightcutsError as exc:
                self.error = self.error or exc
        return "".join(f"newmtl {m}\n" for m in self.materials).encode()


def _file_material(geometry, obj_materials: dict | None) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """(albedo (3,), specular (3,), exponent, emission (3,)) of one trimesh geometry.

    ``obj_materials``: for OBJ files, the ``parse_mtl`` values by material name; None otherwise.
    """
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    mat = getattr(geometry.visual, "material", None)
    albedo = np.full(3, DEFAULT_ALBEDO)
    specular = np.zeros(3)
    exponent = 0.0
    emission = np.zeros(3)
    if obj_materials is not None:
        values = obj_materials.get(mat.name) if isinstance(mat, SimpleMaterial) else None
        if values is not None:
            albedo = values.get("kd", albedo)
            specular = values.get("ks", specular)
            exponent = values.get("ns", exponent)
            emission = values.get("ke", emission)
            if values.get("illum") in (0, 1):  # no highlights, by the MTL spec
                specular = np.zeros(3)
    elif isinstance(mat, PBRMaterial):
        if mat.baseColorFactor is not None:
            albedo = np.asarray(mat.baseColorFactor[:3], np.float64) / 255.0
        if mat.emissiveFactor is not None:
            emission = np.asarray(mat.emissiveFactor, np.float64).reshape(3)
    return albedo, specular, exponent, emission


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

    parts = []  # (vertices, faces, (albedo, specular, exponent, emission)) per geometry instance
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
        mat = ((override.albedo, override.specular, override.exponent, override.emission)
               if override is not None else _file_material(geom, mtl.materials if mtl is not None else None))
        parts.append((v, f, mat))
    if not parts:
        raise LightcutsError(f"{where}: no triangles in the file")

    counts = [len(f) for _, f, _ in parts]
    starts = np.cumsum([0] + [len(v) for v, _, _ in parts[:-1]])
    vertices = np.concatenate([v for v, _, _ in parts])
    faces = np.concatenate([f + s for (_, f, _), s in zip(parts, starts)])
    albedo = np.repeat([p[2][0] for p in parts], counts, axis=0)
    specular = np.repeat([p[2][1] for p in parts], counts, axis=0)
    exponent = np.repeat([p[2][2] for p in parts], counts)
    emission = np.repeat([p[2][3] for p in parts], counts, axis=0)

    vertices = (vertices * scale_v) @ rotation.T + offset
    if np.prod(np.sign(scale_v)) < 0:
        faces = faces[:, ::-1]
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

    return Scene(vertices, faces, albedo, specular, exponent, emission, camera=None, name=path.stem)


def concatenate_scenes(scenes: Sequence[Scene], camera: Camera | None = None, name: str | None = None) -> Scene:
    """One Scene holding the triangles of ``scenes`` in order (triangle ids offset accordingly).

    ``camera`` defaults to the first scene's camera that is not None; ``name`` to the first scene's.
    """
    if not scenes:
        raise ValueError("no scenes to concatenate")
    starts = np.cumsum([0] + [len(s.vertices) for s in scenes[:-1]])
    if camera is None:
        camera = next((s.camera for s in scenes if s.camera is not None), None)
    return Scene(
        np.concatenate([s.vertices for s in scenes]),
        np.concatenate([s.faces.astype(np.int64) + o for s, o in zip(scenes, starts)]),
        np.concatenate([s.albedo for s in scenes]),
        np.concatenate([s.specular for s in scenes]),
        np.concatenate([s.exponent for s in scenes]),
        np.concatenate([s.emission for s in scenes]),
        camera=camera,
        name=name if name is not None else scenes[0].name,
    )
