"""Materials as mesh files give them, per geometry (docs/math.md, "Materials from files").

- OBJ/MTL, per ``usemtl`` group: ``Kd`` -> albedo, ``Ks`` -> specular, ``Ns`` -> Phong exponent,
  ``Ke`` -> emitted radiance; ``illum 0`` or ``1`` (no highlights, by the MTL spec) -> specular 0;
  ``map_Kd`` -> albedo texture, multiplying ``Kd`` (options ``-o`` and ``-s`` move and scale its
  coordinates; the others are skipped, and it always repeats). trimesh groups the faces by
  ``usemtl`` and reads the ``vt`` coordinates; the values come from ``parse_mtl`` (full precision),
  not from trimesh's own MTL parser, which keeps Ks/Ns/Ke only as raw extras, quantises colours to 8
  bits and silently drops all of a file's materials on an entry it does not parse (see
  ``MtlResolver``). A material without ``Kd`` gets the default albedo. A missing material library
  is a warning (its materials get the default), a malformed entry or a missing texture an error.
- glTF/GLB, per primitive, the metallic-roughness model mapped onto Lambert + Phong (:func:`pbr_to_phong`):
  ``baseColorFactor`` and ``baseColorTexture`` -> the diffuse albedo and its texture,
  ``metallicFactor`` and ``roughnessFactor`` -> the specular reflectance and exponent,
  ``emissiveFactor`` times ``KHR_materials_emissive_strength`` times ``emissiveTexture`` (averaged
  over each triangle: emitters have one radiance per triangle) -> emission. Read and checked by
  lightcuts.scene.gltf (factors in the specification's ranges, textures and images present and
  decodable); ``TEXCOORD_0`` only; ``metallicRoughnessTexture``, normal and occlusion maps and
  other extensions are not read.
- Any geometry without a material: diffuse, albedo ``DEFAULT_ALBEDO`` (0.5 grey).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_RADIANCE
from lightcuts.scene.files import regular_file
from lightcuts.scene.textures import TexelBudget, read_image

DEFAULT_ALBEDO = 0.5
#: glTF's reflectance of a dielectric at normal incidence (the metallic-roughness model's 0.04).
DIELECTRIC_F0 = 0.04
#: Largest Phong exponent a glTF roughness maps to (roughness 0, a mirror).
MAX_PBR_EXPONENT = 1.0e4
#: MTL texture options (``map_Kd -o u v w file``) and how many arguments each takes (-o/-s/-t: 1 to 3).
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-mm": 2, "-texres": 1,
                "-bm": 1, "-imfchan": 1, "-type": 1, "-o": 3, "-s": 3, "-t": 3}


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
            if key == "ke" and current[key].max() > MAX_RADIANCE:
                raise LightcutsError(f"{here}: {tokens[0]} {' '.join(args)}: emitted radiance above {MAX_RADIANCE:g}")
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


class MtlResolver:
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
        self.missing: list[str] = []  # "<library>: <problem>" of each library not read

    def __getitem__(self, name: str) -> bytes:
        return self.get(name)

    def get(self, name: str) -> bytes:
        name = name.strip()
        # "mtllib a.mtl b.mtl" names several libraries (trimesh passes the whole line).
        names = [name] if (self.parent / name).is_file() else name.split()
        for n in names:
            path = self.parent / n
            try:  # a regular file: a pipe would block the read
                text = regular_file(path, str(path)).read_text(errors="replace")
            except (LightcutsError, OSError) as exc:
                self.missing.append(str(exc) if isinstance(exc, LightcutsError) else f"{path}: {exc.strerror}")
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


class FileMaterial(NamedTuple):
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


def default_material() -> FileMaterial:
    """Diffuse grey, for geometry without a material."""
    return FileMaterial(np.full(3, DEFAULT_ALBEDO), np.zeros(3), 0.0, np.zeros(3))


def obj_material(geometry, obj_materials: dict | None, where: str, images: dict,
                 budget: TexelBudget | None = None) -> FileMaterial:
    """The material of one trimesh geometry of an OBJ file (module docstring): the ``parse_mtl``
    values of its ``usemtl`` name in ``obj_materials`` (None: no library read). ``images``:
    texture file -> linear image, read once per file, its texels taken from ``budget``."""
    from trimesh.visual.material import SimpleMaterial

    mat = getattr(geometry.visual, "material", None)
    out = default_material()
    values = obj_materials.get(mat.name) if obj_materials is not None and isinstance(mat, SimpleMaterial) else None
    if values is None:
        return out
    out = out._replace(albedo=values.get("kd", out.albedo), specular=values.get("ks", out.specular),
                       exponent=values.get("ns", out.exponent), emission=values.get("ke", out.emission))
    if values.get("illum") in (0, 1):  # no highlights, by the MTL spec
        out = out._replace(specular=np.zeros(3))
    if "map_kd" in values:
        m = values["map_kd"]
        if m["file"] not in images:
            images[m["file"]] = read_image(m["file"], f"{where}: material {mat.name!r}: texture {m['file']}", budget)
        out = out._replace(texture=images[m["file"]], texture_name=m["file"], uv_offset=m["offset"],
                           uv_scale=m["scale"])
    return out
