"""LightSet: N point lights of one type, as flat arrays.

Conventions (Lightcuts 2005, Table 1):

- ``omni``: ``position`` (N,3) world units; ``normal`` zeros; contribution ``M * I / r^2``.
- ``oriented`` (cosine-weighted, area-light samples and indirect VPLs): ``position``, unit ``normal``;
  contribution ``M * I * max(0, n . (x - y)/|x - y|) / r^2``. ``I`` is radiant intensity along the
  normal, W/sr, so the light's power is ``pi * I``.
- ``directional`` (sun, environment-map samples): ``position`` holds the unit direction *towards* the
  light (a point on the unit sphere, so trees cluster directional lights by direction with the same
  code as positions); ``normal`` zeros; ``I`` is irradiance at normal incidence, W/m^2; contribution
  ``M * I`` (shadow ray to infinity).

``intensity`` is RGB, (N,3) float64, non-negative. ``indirect`` (N,) bool marks indirect VPLs, the
only lights that clamping touches.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.io import read_npz, save_npz
from lightcuts.limits import MAX_COORD, MAX_INTENSITY, MAX_LIGHTS

LIGHT_TYPES = ("omni", "oriented", "directional")
# Metadata that builders compute with (lightcuts.trees.build.default_c), checked on reading.
_NUMERIC_META = ("scene_diagonal", "diagonal")

# Rec. 709 / sRGB luminance weights: scalar intensity for metrics, representatives and eps.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@dataclass
class LightSet:
    """Point lights of one type.

    position : (N, 3) float64, world units (directional: unit direction towards the light)
    normal : (N, 3) float64, unit (oriented) or zeros (omni, directional)
    intensity : (N, 3) float64, RGB; W/sr (omni, oriented) or W/m^2 (directional)
    type : one of ``LIGHT_TYPES``
    indirect : (N,) bool, True for indirect VPLs (particle-traced)
    meta : dict of scalars/strings saved with the set (scene name, bounds, seed, ...)
    """

    position: np.ndarray
    normal: np.ndarray
    intensity: np.ndarray
    type: str
    indirect: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.type not in LIGHT_TYPES:
            raise LightcutsError(f"light type {self.type!r} is not one of {', '.join(LIGHT_TYPES)}")
        self.position = np.ascontiguousarray(self.position, np.float64).reshape(-1, 3)
        n = len(self.position)
        self.normal = np.ascontiguousarray(self.normal, np.float64).reshape(-1, 3)
        self.intensity = np.ascontiguousarray(self.intensity, np.float64).reshape(-1, 3)
        if self.indirect is None:
            self.indirect = np.zeros(n, bool)
        self.indirect = np.ascontiguousarray(self.indirect, bool).reshape(-1)
        if not (len(self.normal) == len(self.intensity) == len(self.indirect) == n):
            raise LightcutsError(
                f"light arrays disagree in length: position {n}, normal {len(self.normal)}, "
                f"intensity {len(self.intensity)}, indirect {len(self.indirect)}")

    def __len__(self) -> int:
        return len(self.position)

    @property
    def luminance(self) -> np.ndarray:
        """(N,) float64 scalar intensity (Rec. 709 luminance of the RGB intensity)."""
        # Per element, not ``intensity @ LUMINANCE``: the BLAS call starts OpenBLAS threads whose
        # spinning takes a core from the numba kernels that follow (docs/performance.md).
        i = self.intensity
        return i[:, 0] * LUMINANCE[0] + i[:, 1] * LUMINANCE[1] + i[:, 2] * LUMINANCE[2]

    @property
    def power(self) -> np.ndarray:
        """(3,) float64 total RGB power, W: pi * sum(I) for oriented, 4 pi * sum(I) for omni.

        For directional lights the sum of irradiances is returned (W/m^2; no finite power).
        """
        s = self.intensity.sum(axis=0)
        return s * {"oriented": np.pi, "omni": 4 * np.pi, "directional": 1.0}[self.type]

    @staticmethod
    def concatenate(sets: list["LightSet"]) -> "LightSet":
        """One set from several of the same type (metadata of the first)."""
        if not sets:
            raise ValueError("no light sets to concatenate")
        types = {s.type for s in sets}
        if len(types) != 1:
            raise ValueError(f"cannot concatenate light sets of types {sorted(types)}")
        return LightSet(np.concatenate([s.position for s in sets]), np.concatenate([s.normal for s in sets]),
                        np.concatenate([s.intensity for s in sets]), sets[0].type,
                        np.concatenate([s.indirect for s in sets]), dict(sets[0].meta))

    def save(self, path) -> Path:
        """Write as .npz: position, normal, intensity, type, indirect, and ``meta_<key>`` entries."""
        arrays = dict(position=self.position, normal=self.normal, intensity=self.intensity,
                      type=np.array(self.type), indirect=self.indirect)
        for k, v in self.meta.items():
            arrays[f"meta_{k}"] = np.asarray(v)
        return save_npz(path, **arrays)

    @classmethod
    def load(cls, path) -> "LightSet":
        """Read a light file; LightcutsError naming the file and the problem if it is malformed."""
        path = Path(path)
        z = read_npz(path, "light")
        missing = [k for k in ("position", "normal", "intensity", "type") if k not in z]
        if missing:
            raise LightcutsError(f"{path}: missing key(s) {', '.join(missing)}")
        arrays = {k: z[k] for k in ("position", "normal", "intensity")}
        for k, a in arrays.items():
            if a.ndim != 2 or a.shape[1] != 3:
                raise LightcutsError(f"{path}: {k} has shape {a.shape}, expected (N, 3)")
            if a.dtype.kind not in "biuf" or not np.all(np.isfinite(a)):
                raise LightcutsError(f"{path}: {k} has non-finite or non-numeric values")
        if np.any(arrays["intensity"] < 0):
            raise LightcutsError(f"{path}: intensity has negative values")
        for k, limit in (("position", MAX_COORD), ("intensity", MAX_INTENSITY)):
            if arrays[k].size and float(np.abs(arrays[k]).max()) > limit:
                raise LightcutsError(f"{path}: {k} has values beyond {limit:g} in magnitude "
                                     "(the clustering metric would overflow)")
        if z["type"].ndim != 0 or z["type"].dtype.kind != "U":
            raise LightcutsError(f"{path}: type must be a 0-d string, one of {', '.join(LIGHT_TYPES)}")
        typ = str(z["type"])
        if typ not in LIGHT_TYPES:
            raise LightcutsError(f"{path}: type {typ!r} is not one of {', '.join(LIGHT_TYPES)}")
        indirect = z.get("indirect")
        n = len(arrays["position"])
        if indirect is not None and (indirect.dtype.kind not in "biu" or indirect.shape != (n,)):
            raise LightcutsError(f"{path}: indirect must be (N,) bool, got {indirect.dtype} {indirect.shape}")
        if len(arrays["normal"]) != n or len(arrays["intensity"]) != n:
            raise LightcutsError(f"{path}: position, normal and intensity differ in length")
        if n == 0:
            raise LightcutsError(f"{path}: holds no lights")
        if n > MAX_LIGHTS:
            raise LightcutsError(f"{path}: holds {n:,} lights, more than {MAX_LIGHTS:,} (lightcuts.limits.MAX_LIGHTS)")
        meta = {}
        for k, a in z.items():
            if not k.startswith("meta_"):
                continue
            if k[5:] in _NUMERIC_META and (a.ndim != 0 or a.dtype.kind not in "biuf" or not np.isfinite(a)):
                raise LightcutsError(f"{path}: {k} must be a finite number, got {a.dtype} {a.shape}")
            if k[5:] in _NUMERIC_META and not 0 <= a <= 16 * MAX_COORD:  # the bound of a scene's diagonal
                raise LightcutsError(f"{path}: {k} = {a.item():g} is not in [0, {16 * MAX_COORD:g}]")
            meta[k[5:]] = a.item() if a.ndim == 0 else a
        return cls(arrays["position"], arrays["normal"], arrays["intensity"], typ, indirect, meta)
