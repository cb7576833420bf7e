"""The Scene: a triangle soup with one material per triangle (an albedo texture optional), and a
pinhole camera.

Structure of arrays, like trimesh's ``Trimesh``: every per-triangle quantity is a flat numpy array
indexed by triangle id (the ``primID`` Embree returns).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.io import save_npz
from lightcuts.limits import MAX_EMITTED_POWER, MAX_RADIANCE
from lightcuts.scene.textures import TextureSet, empty_kernel_data, uv_maps


@dataclass
class Camera:
    """Pinhole camera.

    position, look_at, up : (3,) float64, world units
    fov : vertical field of view, degrees
    width, height : image resolution, pixels
    """

    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float
    width: int
    height: int

    def __post_init__(self):
        self.position = np.asarray(self.position, np.float64).reshape(3)
        self.look_at = np.asarray(self.look_at, np.float64).reshape(3)
        self.up = np.asarray(self.up, np.float64).reshape(3)
        self.fov = float(self.fov)
        self.width = int(self.width)
        self.height = int(self.height)

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal (right, up, forward) of the camera, each (3,)."""
        fwd = self.look_at - self.position
        fwd = fwd / np.linalg.norm(fwd)
        right = np.cross(fwd, self.up)
        right = right / np.linalg.norm(right)
        up = np.cross(right, fwd)
        return right, up, fwd

    def as_array(self) -> np.ndarray:
        """(12,) float64: position, look_at, up, fov, width, height (for .npz)."""
        return np.concatenate([self.position, self.look_at, self.up, [self.fov, self.width, self.height]])

    @classmethod
    def from_array(cls, a: np.ndarray) -> "Camera":
        a = np.asarray(a, np.float64)
        return cls(a[0:3], a[3:6], a[6:9], a[9], int(a[10]), int(a[11]))


def kernel_array(a, dtype) -> np.ndarray:
    """``a`` as a C-contiguous, writeable ``dtype`` array, copied when it is a read-only view (a
    broadcast material, a cached mesh): numba compiles a kernel again for a read-only array, so the
    arrays kernels receive (a scene's, an environment map's) are all writeable."""
    a = np.ascontiguousarray(a, dtype)
    return a if a.flags.writeable else a.copy()


@dataclass
class Scene:
    """Triangle meshes with per-triangle material.

    vertices : (V, 3) float64, world units
    faces : (F, 3) int32, vertex indices, counter-clockwise = front (normal by the right-hand rule)
    albedo : (F, 3) float64, diffuse reflectance rho_d in [0, 1] (RGB)
    specular : (F, 3) float64, Phong specular reflectance rho_s (RGB); 0 = purely diffuse
    exponent : (F,) float64, Phong exponent n (>= 0)
    emission : (F, 3) float64, emitted radiance, W/(m^2 sr) per RGB channel, one-sided along the
        triangle's normal; 0 = not an emitter
    camera : Camera or None
    name : str
    uv : (F, 3, 2) float64, the corners' texture coordinates, or None without textures
    texture : (F,) int32, the triangle's albedo texture in ``textures`` (-1: none), or None
    textures : lightcuts.scene.textures.TextureSet or None; a textured triangle's albedo is
        ``albedo[f]`` times the texture at the point (lightcuts.scene.textures)
    """

    vertices: np.ndarray
    faces: np.ndarray
    albedo: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    emission: np.ndarray
    camera: Camera | None = None
    name: str = "scene"
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    textures: TextureSet | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        self.vertices = kernel_array(np.reshape(self.vertices, (-1, 3)), np.float64)
        self.faces = kernel_array(np.reshape(self.faces, (-1, 3)), np.int32)
        nf = len(self.faces)
        self.albedo = kernel_array(np.broadcast_to(self.albedo, (nf, 3)), np.float64)
        self.specular = kernel_array(np.broadcast_to(self.specular, (nf, 3)), np.float64)
        self.exponent = kernel_array(np.broadcast_to(self.exponent, (nf,)), np.float64)
        self.emission = kernel_array(np.broadcast_to(self.emission, (nf, 3)), np.float64)
        if self.texture is None or self.textures is None or len(self.textures) == 0 \
                or not np.any(np.asarray(self.texture) >= 0):
            self.uv, self.texture, self.textures = None, None, None
        else:
            self.texture = kernel_array(np.reshape(self.texture, nf), np.int32)
            self.uv = kernel_array(np.reshape(self.uv, (nf, 3, 2)), np.float64)
            if self.texture.max() >= len(self.textures):
                raise ValueError(f"texture ids up to {self.texture.max()}, but {len(self.textures)} textures")

    @property
    def textured(self) -> bool:
        """Whether some triangle has an albedo texture."""
        return self.textures is not None

    def texture_data(self):
        """The texture tuple kernels take (lightcuts.scene.textures.albedo_at): the per-triangle
        texture ids, uv maps, texels and image table; all empty without textures."""
        if "texture_data" not in self._cache:
            if not self.textured:
                self._cache["texture_data"] = empty_kernel_data()
            else:
                self._cache["texture_data"] = (self.texture, uv_maps(self.vertices, self.faces, self.uv),
                                               self.textures.texels, self.textures.table)
        return self._cache["texture_data"]

    def translated(self, shift) -> "Scene":
        """The same scene moved by ``shift`` (3,) world units (materials and textures kept)."""
        return Scene(self.vertices + np.asarray(shift, np.float64), self.faces, self.albedo, self.specular,
                     self.exponent, self.emission, self.camera, self.name, self.uv, self.texture, self.textures)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float64 corner positions."""
        return self.vertices[self.faces]

    @property
    def face_normals(self) -> np.ndarray:
        """(F, 3) float64 unit geometric normals (right-hand rule)."""
        if "normals" not in self._cache:
            t = self.triangles
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            length = np.linalg.norm(n, axis=1, keepdims=True)
            self._cache["normals"] = n / np.where(length > 0, length, 1.0)
        return self._cache["normals"]

    @property
    def face_areas(self) -> np.ndarray:
        """(F,) float64 triangle areas, world units squared."""
        if "areas" not in self._cache:
            t = self.triangles
            self._cache["areas"] = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        return self._cache["areas"]

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 axis-aligned bounding box of the vertices used by faces (computed once: a
        render asks for it per call, and the scan of the faces is tens of ms at 200K triangles)."""
        if "bounds" not in self._cache:
            if len(self.faces):
                mask = np.zeros(len(self.vertices), bool)  # not np.unique: seconds at 10^6 triangles
                mask[self.faces.ravel()] = True
                used = self.vertices[mask]
            else:
                used = self.vertices
            self._cache["bounds"] = np.stack([used.min(axis=0), used.max(axis=0)])
        return self._cache["bounds"].copy()

    @property
    def diagonal(self) -> float:
        """Length of the bounding box diagonal, world units."""
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @property
    def emitters(self) -> np.ndarray:
        """(E,) int64 ids of triangles with non-zero emission."""
        return np.flatnonzero(self.emission.max(axis=1) > 0)

    def check_emission(self, where: str) -> None:
        """LightcutsError ``<where>: ...`` unless every triangle's emitted radiance is finite, >= 0
        and at most ``MAX_RADIANCE``, and the emitted power (area x largest channel, summed over
        the emitters) at most ``MAX_EMITTED_POWER`` (lightcuts.limits): what every light made
        from the scene needs to stay within the light limits. ``where`` names the source."""
        e = self.emission
        top = np.maximum(np.maximum(e[:, 0], e[:, 1]), e[:, 2])  # NaN propagates; faster than max(axis=1)
        if not (np.isfinite(top).all() and e.min(initial=0.0) >= 0 and top.max(initial=0.0) <= MAX_RADIANCE):
            for bad, problem in ((~np.all(np.isfinite(e), axis=1), "NaN or infinite radiance"),
                                 (np.any(e < 0, axis=1), "negative radiance"),
                                 (np.any(e > MAX_RADIANCE, axis=1), f"radiance above {MAX_RADIANCE:g}")):
                if bad.any():
                    i = int(np.flatnonzero(bad)[0])
                    raise LightcutsError(f"{where}: {int(bad.sum())} triangles emit {problem} "
                                         f"(triangle {i}: {e[i].tolist()})")
        lit = np.flatnonzero(top > 0)
        t = self.vertices[self.faces[lit]]  # the emitters only: most triangles of a large scene are not
        with np.errstate(over="ignore", invalid="ignore"):
            area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
            power = float(np.sum(e[lit].max(axis=1) * area))
        if not power <= MAX_EMITTED_POWER * (1 + 1e-12):  # the sum's rounding: 1e30 x 1e30 at 1e30 is in
            raise LightcutsError(f"{where}: emitted power {power:.3g} W/sr (area x radiance, summed over "
                                 f"{len(lit)} emitting triangles) is above {MAX_EMITTED_POWER:g}")

    def save(self, path) -> Path:
        """Write the scene as .npz (keys = the field names; ``camera`` as 12 floats)."""
        arrays = dict(vertices=self.vertices, faces=self.faces, albedo=self.albedo, specular=self.specular,
                      exponent=self.exponent, emission=self.emission, name=np.array(self.name))
        if self.camera is not None:
            arrays["camera"] = self.camera.as_array()
        if self.textured:
            arrays.update(uv=self.uv, texture=self.texture, texels=self.textures.texels,
                          texture_table=self.textures.table, texture_names=np.array(self.textures.names))
        return save_npz(path, **arrays)

    @classmethod
    def load(cls, path) -> "Scene":
        try:
            with np.load(path, allow_pickle=False) as z:
                cam = Camera.from_array(z["camera"]) if "camera" in z else None
                tex = {}
                if "texture" in z:
                    tex = dict(uv=z["uv"], texture=z["texture"], textures=TextureSet(
                        z["texels"], z["texture_table"], list(z["texture_names"])))
                return cls(z["vertices"], z["faces"], z["albedo"], z["specular"], z["exponent"],
                           z["emission"], cam, str(z["name"]), **tex)
        except (OSError, KeyError, ValueError) as exc:
            raise LightcutsError(f"{path}: not a lightcuts scene file ({exc})") from None
