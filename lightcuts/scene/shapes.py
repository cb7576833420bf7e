"""Primitives for the procedural scenes: boxes, tessellated curved solids and emitter quads.

A ``PartList`` collects parts (one mesh and one named material each) and turns them into a
``Scene`` with a palette (material name -> Material). Closed solids come from ``trimesh.creation``
(watertight, outward normals); emitters are open quads whose normal is ``u x v``.

Curved solids are first described (``Curved``: kind, dimensions, pose, material, weight) and only
tessellated once the triangle budget is known: ``resolutions`` picks every solid's resolution
``k = clip(s * weight)`` with one scale ``s`` found by bisection, then +-1 section on cylinders, so
that the total hits the budget (to a few triangles, unless every solid is at its coarsest).
Units: metres, y up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Mapping, NamedTuple

import numpy as np
import trimesh

from lightcuts.config.schema import Material
from lightcuts.errors import LightcutsError
from lightcuts.scene.loaders import as_material
from lightcuts.scene.scene import Camera, Scene

#: Resolution bounds per curved kind: (smallest, largest) k.
K_RANGE = {"cylinder": (6, 512), "annulus": (6, 512), "torus": (6, 256), "sphere": (6, 256)}
#: z-up trimesh solids -> y-up.
Z_TO_Y = trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0])


def material(albedo, specular=(0, 0, 0), exponent=0.0, emission=(0, 0, 0)) -> Material:
    """A palette entry: diffuse albedo, Phong specular reflectance and exponent, emitted radiance
    (RGB each)."""
    return Material(albedo=list(albedo), specular=list(specular), exponent=exponent, emission=list(emission))


def pose(translate=(0.0, 0.0, 0.0), rot_y: float = 0.0, rot_x: float = 0.0) -> np.ndarray:
    """(4, 4) float64: rotate about x, then about y (radians), then translate (metres)."""
    m = trimesh.transformations.rotation_matrix(rot_y, [0, 1, 0]) @ \
        trimesh.transformations.rotation_matrix(rot_x, [1, 0, 0])
    m[:3, 3] = translate
    return m


def faces_of(kind: str, k: int) -> int:
    """Triangle count of one curved solid of ``kind`` at resolution ``k`` (what trimesh builds)."""
    if kind == "cylinder":
        return 4 * k
    if kind == "annulus":
        return 8 * k
    if kind == "torus":
        return 2 * k * max(3, k // 2)
    if kind == "sphere":
        k = k + (k % 2)
        return 4 * k * (k - 2)
    raise ValueError(kind)


def _faces_vec(kind: str, k: np.ndarray) -> np.ndarray:
    if kind == "cylinder":
        return 4 * k
    if kind == "annulus":
        return 8 * k
    if kind == "torus":
        return 2 * k * np.maximum(3, k // 2)
    k = k + (k % 2)
    return 4 * k * (k - 2)


class Curved(NamedTuple):
    """A curved solid before tessellation.

    kind : cylinder (dims radius, height), annulus (r_min, r_max, height), torus (major, minor
        radius; in the xz plane unless posed) or sphere (radius)
    matrix : (4, 4) pose; cylinders and annuli stand on y = 0 of their frame, axis +y; spheres and
        tori are centred on the origin of their frame
    weight : relative resolution (larger objects get finer tessellation)
    """

    kind: str
    dims: tuple
    matrix: np.ndarray
    material: str
    weight: float


@lru_cache(maxsize=1024)
def _unit(kind: str, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the unit cylinder (radius 1, height 1, standing on y = 0, axis +y) or
    the unit sphere at resolution ``k``: scaled per solid, so equal resolutions share one build."""
    if kind == "cylinder":
        m = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=k)
        m.apply_transform(pose((0, 0.5, 0)) @ Z_TO_Y)
    else:
        m = trimesh.creation.uv_sphere(radius=1.0, count=[k + (k % 2)] * 2)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    v.flags.writeable = False
    f.flags.writeable = False
    return v, f


def curved_mesh(c: Curved, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of ``c`` at resolution ``k``, posed: a watertight solid (trimesh.creation)."""
    if c.kind in ("cylinder", "sphere"):
        v, f = _unit(c.kind, k)
        scale = (c.dims[0], c.dims[1], c.dims[0]) if c.kind == "cylinder" else (c.dims[0],) * 3
        v = (v * scale) @ c.matrix[:3, :3].T + c.matrix[:3, 3]
        return v, f
    if c.kind == "annulus":
        r0, r1, h = c.dims
        m = trimesh.creation.annulus(r_min=r0, r_max=r1, height=h, sections=k)
        m.apply_transform(pose((0, h / 2, 0)) @ Z_TO_Y)
    elif c.kind == "torus":
        big, small = c.dims
        m = trimesh.creation.torus(big, small, major_sections=k, minor_sections=max(3, k // 2))
        m.apply_transform(Z_TO_Y)
    else:
        raise ValueError(c.kind)
    m.apply_transform(c.matrix)
    return np.asarray(m.vertices), np.asarray(m.faces)


def resolutions(items: list[Curved], budget: int) -> np.ndarray:
    """(len(items),) int64 resolutions whose total triangle count is closest to ``budget`` under the
    rule k_i = clip(round(s * weight_i), K_RANGE) (one scale s, found by bisection on log s)."""
    if not items:
        return np.zeros(0, np.int64)
    kinds = np.array([c.kind for c in items])
    w = np.array([c.weight for c in items], np.float64)
    lo_k = np.array([K_RANGE[k][0] for k in kinds])
    hi_k = np.array([K_RANGE[k][1] for k in kinds])
    groups = {kind: np.flatnonzero(kinds == kind) for kind in K_RANGE}

    def ks(s):
        return np.clip(np.round(s * w), lo_k, hi_k).astype(np.int64)

    def total(k):
        return int(sum(_faces_vec(kind, k[i]).sum() for kind, i in groups.items() if len(i)))

    lo, hi = -10.0, 10.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if total(ks(np.exp(mid))) < budget:
            lo = mid
        else:
            hi = mid
    a, b = ks(np.exp(lo)), ks(np.exp(hi))
    k = a if abs(total(a) - budget) <= abs(total(b) - budget) else b
    # the rest of the gap in steps of 4 triangles: +-1 section on the finest cylinders first
    cyl = groups["cylinder"][np.argsort(-w[groups["cylinder"]], kind="stable")]
    steps = int((budget - total(k)) / 4)
    if len(cyl) and steps:
        q, r = divmod(abs(steps), len(cyl))
        k[cyl] += int(np.sign(steps)) * (q + (np.arange(len(cyl)) < r))
        k[cyl] = np.clip(k[cyl], lo_k[cyl], hi_k[cyl])
    return k


@dataclass
class PartList:
    """Parts of a scene: per part (V, 3) vertices, (F, 3) faces, a material name, whether the
    part is a closed solid (watertight) or an open surface (emitter quads), and its per-face
    emission scale ((F,) float64 multiplying the material's emission, or None: 1)."""

    vertices: list = field(default_factory=list)
    faces: list = field(default_factory=list)
    materials: list = field(default_factory=list)
    closed: list = field(default_factory=list)
    scales: list = field(default_factory=list)

    def add(self, mesh, material: str, closed: bool = True, scale=None) -> None:
        """Append a trimesh (or a (vertices, faces) pair); ``scale`` (F,): per-face emission factors."""
        v, f = (mesh.vertices, mesh.faces) if isinstance(mesh, trimesh.Trimesh) else mesh
        self.vertices.append(np.asarray(v, np.float64))
        self.faces.append(np.asarray(f, np.int64))
        self.materials.append(material)
        self.closed.append(closed)
        self.scales.append(None if scale is None else np.broadcast_to(np.asarray(scale, np.float64), len(f)))

    def extend(self, other: "PartList", matrix: np.ndarray | None = None) -> None:
        """Append ``other``'s parts, moved by the rigid (4, 4) ``matrix`` (rotation keeps windings)."""
        for v, f, m, c, s in zip(other.vertices, other.faces, other.materials, other.closed, other.scales):
            if matrix is not None:
                v = v @ matrix[:3, :3].T + matrix[:3, 3]
            self.add((v, f), m, c, s)

    def box(self, lo, hi, material: str, rot_y: float = 0.0) -> None:
        """An axis-aligned box [lo, hi] (metres), optionally turned by ``rot_y`` about its centre."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        self.add(trimesh.creation.box(extents=hi - lo, transform=pose(0.5 * (lo + hi), rot_y)), material)

    def quads(self, corner, u, v, nu: int, nv: int, material: str, gap: float = 0.0) -> None:
        """An open rectangle ``corner + [0,1] u + [0,1] v`` split into nu x nv separate quads (each
        shrunk by ``gap`` metres per side); normal ``u x v`` (the emitting side)."""
        corner, u, v = (np.asarray(a, float) for a in (corner, u, v))
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        i, j = i.ravel(), j.ravel()
        du, dv = u / nu, v / nv
        gu = gap * du / np.linalg.norm(du)
        gv = gap * dv / np.linalg.norm(dv)
        c0 = corner + i[:, None] * du + j[:, None] * dv + gu + gv
        a, b = du - 2 * gu, dv - 2 * gv
        verts = np.stack([c0, c0 + a, c0 + a + b, c0 + b], axis=1).reshape(-1, 3)
        base = 4 * np.arange(len(c0))[:, None]
        faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
        self.add((verts, faces), material, closed=False)

    def curved(self, items: list[Curved], budget: int) -> None:
        """Tessellate ``items`` to about ``budget`` triangles in all (see ``resolutions``)."""
        for c, k in zip(items, resolutions(items, budget)):
            self.add(curved_mesh(c, int(k)), c.material)

    @property
    def n_faces(self) -> int:
        return int(sum(len(f) for f in self.faces))

    def extents(self) -> np.ndarray:
        """(P,) float64 largest bounding-box side of each part, metres."""
        return np.array([float(np.ptp(v, axis=0).max()) for v in self.vertices])

    def to_scene(self, palette: Mapping[str, Material], overrides: Mapping | None = None,
                 camera: Camera | None = None, name: str = "scene") -> Scene:
        """One Scene, parts in order; ``overrides`` (name -> Material or dict, the fields given
        replace the palette's) errors as ``scene.materials.<name>`` when the name is unknown."""
        mats = dict(palette)
        for key, value in (overrides or {}).items():
            if key not in mats:
                raise LightcutsError(f"scene.materials.{key}: unknown surface; valid: {', '.join(sorted(mats))}")
            given = as_material(value, f"scene.materials.{key}")
            mats[key] = mats[key].model_copy(update={f: getattr(given, f) for f in given.model_fields_set})
        counts = np.array([len(f) for f in self.faces], np.int64)
        starts = np.cumsum([0] + [len(v) for v in self.vertices[:-1]])
        faces = np.concatenate([f + s for f, s in zip(self.faces, starts)])
        names = sorted(mats)
        index = {n: i for i, n in enumerate(names)}
        table = {a: np.array([getattr(mats[n], a) for n in names], np.float64)
                 for a in ("albedo", "specular", "exponent", "emission")}
        which = np.repeat([index[m] for m in self.materials], counts)
        emission = table["emission"][which]
        if any(s is not None for s in self.scales):
            emission *= np.concatenate([np.ones(n) if s is None else s for s, n in zip(self.scales, counts)])[:, None]
        return Scene(np.concatenate(self.vertices), faces, table["albedo"][which], table["specular"][which],
                     table["exponent"][which], emission, camera=camera, name=name)
