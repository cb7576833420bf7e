"""Distant light: the sun (one directional light) and lat-long HDR environment maps.

Environment-map convention (Mitsuba 3's, so maps and renders compare directly):

* +y is up. A map of H rows and W columns covers the sphere in equal steps of angle: row ``i`` spans
  polar angles ``theta`` in ``[pi i / H, pi (i + 1) / H]`` from +y (row 0 is the zenith), column ``j``
  spans azimuths ``phi`` in ``[2 pi j / W, 2 pi (j + 1) / W]``.
* Direction <-> (u, v): ``u = phi / (2 pi) = atan2(x, -z) / (2 pi) mod 1``, ``v = theta / pi = acos(y) / pi``;
  inversely ``d = (sin(phi) sin(theta), cos(theta), -cos(phi) sin(theta))``: the map's centre column
  (u = 0.5) looks along +z, u = 0 and 1 along -z, u = 0.25 along +x.
* The map is piecewise constant: a direction has the radiance of the pixel that contains it (no
  filtering), the same function that ``environment_lights`` samples, so the lights and the
  background the renderer shows agree exactly.
* ``rotate`` (degrees) turns the map about +y, right-handed: a feature at map direction ``d``
  appears in the world at ``R_y(rotate) d``, with ``R_y(a) = [[cos a, 0, sin a], [0, 1, 0],
  [-sin a, 0, cos a]]``. ``scale`` multiplies the radiance. A map may also have a ``frame``, any
  rotation (an orthogonal (3, 3) matrix, Mitsuba's ``to_world`` of an ``envmap``), applied first:
  map direction ``d`` is then at ``R_y(rotate) frame d``.

Radiance is W/(m^2 sr) per RGB channel (linear). A directional light's ``position`` is the unit
direction *towards* the light and its intensity the irradiance it gives at normal incidence, W/m^2.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit, prange

from lightcuts.errors import LightcutsError
from lightcuts.io import atomic_path
from lightcuts.lights.direct import radical_inverse_base2
from lightcuts.lights.lightset import LUMINANCE, LightSet


#: Largest |frame^T frame - I| entry of an environment map's frame (float32 transforms of files included).
FRAME_TOLERANCE = 1e-5


def sun_light(direction, irradiance) -> LightSet:
    """One directional light: ``direction`` (3,) towards the sun (normalised here), ``irradiance`` (3,)
    W/m^2 at normal incidence. LightcutsError naming ``lights.sun.*`` on a zero or non-finite direction
    or a negative irradiance."""
    d = np.asarray(direction, np.float64).reshape(3)
    length = float(np.linalg.norm(d))
    if not np.isfinite(length) or length == 0.0:
        raise LightcutsError(f"lights.sun.direction: {list(d)} has no direction (zero or non-finite length)")
    e = np.asarray(irradiance, np.float64).reshape(3)
    if not np.all(np.isfinite(e)) or np.any(e < 0):
        raise LightcutsError(f"lights.sun.irradiance: {list(e)} must be finite and >= 0")
    return LightSet((d / length)[None], np.zeros((1, 3)), e[None], "directional", np.zeros(1, bool))


def rotation_y(degrees: float) -> np.ndarray:
    """(3, 3) rotation about +y by ``degrees``, right-handed (x towards -z)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@njit(cache=True)
def envmap_radiance(pixels, rotation, scale, dx, dy, dz):
    """Radiance (r, g, b) of the lat-long map ``pixels`` (H, W, 3) towards world direction d (unit).

    For use inside numba kernels (the renderer's misses); ``rotation`` (3, 3) maps map directions to
    world directions, so the map direction is ``rotation.T @ d``.
    """
    mx = rotation[0, 0] * dx + rotation[1, 0] * dy + rotation[2, 0] * dz
    my = rotation[0, 1] * dx + rotation[1, 1] * dy + rotation[2, 1] * dz
    mz = rotation[0, 2] * dx + rotation[1, 2] * dy + rotation[2, 2] * dz
    h, w = pixels.shape[0], pixels.shape[1]
    u = math.atan2(mx, -mz) / (2.0 * math.pi)
    if u < 0.0:
        u += 1.0
    v = math.acos(min(1.0, max(-1.0, my))) / math.pi
    j = min(int(u * w), w - 1)
    i = min(int(v * h), h - 1)
    return scale * pixels[i, j, 0], scale * pixels[i, j, 1], scale * pixels[i, j, 2]


@njit(parallel=True, cache=True)
def _radiance_batch(pixels, rotation, scale, dirs, out):
    for k in prange(dirs.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = envmap_radiance(pixels, rotation, scale, dirs[k, 0], dirs[k, 1],
                                                          dirs[k, 2])


class EnvironmentMap:
    """A lat-long HDR environment (see the module docstring for the convention).

    pixels : (H, W, 3) float32, C-contiguous, linear radiance W/(m^2 sr), finite and >= 0
    rotate : rotation about +y, degrees; ``rotation`` is the (3, 3) matrix map -> world,
        ``R_y(rotate) @ frame``
    scale : radiance multiplier
    name : where the map came from (file path or "procedural sky"), for messages and metadata
    frame : (3, 3) orthogonal matrix map -> world applied before ``rotate`` (None: the identity)

    Numba kernels use ``envmap_radiance(env.pixels, env.rotation, env.scale, dx, dy, dz)``.
    """

    def __init__(self, pixels, rotate: float = 0.0, scale: float = 1.0, name: str = "environment", frame=None):
        pixels = np.ascontiguousarray(pixels, np.float32)
        if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.shape[0] < 1 or pixels.shape[1] < 1:
            raise LightcutsError(f"{name}: environment map has shape {pixels.shape}, expected (H, W, 3)")
        if not np.all(np.isfinite(pixels)):
            raise LightcutsError(f"{name}: environment map has non-finite values")
        if np.any(pixels < 0):
            raise LightcutsError(f"{name}: environment map has negative values")
        self.pixels = pixels
        self.rotate = float(rotate)
        frame = np.eye(3) if frame is None else np.asarray(frame, np.float64)
        if frame.shape != (3, 3) or not np.all(np.isfinite(frame)) or \
                np.abs(frame.T @ frame - np.eye(3)).max() > FRAME_TOLERANCE:
            raise LightcutsError(f"{name}: environment frame is not a rotation (an orthogonal 3x3 matrix)")
        self.rotation = rotation_y(self.rotate) @ frame
        self.scale = float(scale)
        self.name = name

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W)."""
        return self.pixels.shape[0], self.pixels.shape[1]

    def radiance(self, dirs) -> np.ndarray:
        """(n, 3) float64 radiance towards world directions ``dirs`` (n, 3) (unit), scale included."""
        dirs = np.ascontiguousarray(np.asarray(dirs, np.float64).reshape(-1, 3))
        out = np.empty((len(dirs), 3))
        _radiance_batch(self.pixels, self.rotation, self.scale, dirs, out)
        return out

    def directions(self, u, v) -> np.ndarray:
        """(n, 3) world unit directions at map coordinates u, v (n,) in [0, 1] (rotation applied)."""
        phi = 2.0 * np.pi * np.asarray(u, np.float64)
        theta = np.pi * np.asarray(v, np.float64)
        d = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], axis=-1)
        return d @ self.rotation.T

    @classmethod
    def load(cls, path, rotate: float = 0.0, scale: float = 1.0) -> "EnvironmentMap":
        """Read a lat-long EXR with R, G, B channels (any pixel type; A and others ignored).

        LightcutsError naming the file if it is missing, unreadable, not RGB, or has non-finite or
        negative values.
        """
        import OpenEXR

        path = Path(path)
        if not path.is_file():
            raise LightcutsError(f"{path}: no such environment map")
        try:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                channels = {k: v.pixels for k, v in f.channels().items()}
        except Exception as exc:
            raise LightcutsError(f"{path}: cannot read as OpenEXR ({exc})") from None
        missing = [c for c in "RGB" if c not in channels]
        if missing:
            raise LightcutsError(f"{path}: not an RGB image (channels {', '.join(sorted(channels)) or 'none'}; "
                                 f"missing {', '.join(missing)})")
        try:
            rgb = np.stack([np.asarray(channels[c], np.float32) for c in "RGB"], axis=-1)
        except ValueError as exc:
            raise LightcutsError(f"{path}: R, G, B channels differ in size ({exc})") from None
        return cls(rgb, rotate, scale, str(path))

    def save(self, path) -> Path:
        """Write ``pixels`` (without rotation or scale) as a ZIP-compressed float32 RGB EXR, atomically."""
        import OpenEXR

        path = Path(path)
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with atomic_path(path, suffix=".exr") as tmp:
            with OpenEXR.File(header, {"RGB": np.ascontiguousarray(self.pixels, np.float32)}) as f:
                f.write(str(tmp))
        return path


def procedural_sky(sun_direction=(0.3, 1.0, 0.2), resolution=(256, 128), zenith=(0.25, 0.45, 1.0),
                   horizon=(0.9, 0.95, 1.0), ground=(0.15, 0.13, 0.11), sun_irradiance=15.0,
                   sun_colour=(1.0, 0.95, 0.85), sun_radius=2.0, rotate: float = 0.0,
                   scale: float = 1.0) -> EnvironmentMap:
    """A plausible clear-sky HDR map in the lat-long convention of this module, no download needed.

    Above the horizon, radiance blends from ``horizon`` to ``zenith`` with elevation (``1 -
    exp(-4 sin(elevation))``) and brightens in a glow around the sun (Gaussian, 12 degrees wide,
    up to twice the sky); below, the ``ground`` radiance (a diffuse ground, darkening slightly
    with depression). The sun is a disc of angular radius ``sun_radius`` degrees (default 2, larger
    than the real 0.27 so that a 256-wide map resolves it) and constant radiance chosen so that it
    gives ``sun_irradiance * sun_colour`` W/m^2 at normal incidence (about 7x the sky's irradiance
    on the ground with the defaults); it is hidden when below the horizon.

    sun_direction : (3,) towards the sun; resolution : (W, H) pixels; zenith, horizon, ground,
    sun_colour : (3,) RGB radiance. LightcutsError naming the procedural key on bad input.
    """
    key = "lights.environment.procedural"
    s = np.asarray(sun_direction, np.float64).reshape(3)
    ls = float(np.linalg.norm(s))
    if not np.isfinite(ls) or ls == 0.0:
        raise LightcutsError(f"{key}.sun_direction: {list(s)} has no direction (zero or non-finite length)")
    s = s / ls
    w, h = (int(x) for x in resolution)
    if w < 1 or h < 1:
        raise LightcutsError(f"{key}.resolution: {[w, h]} must be positive")
    # pixel centres, map frame (the map is generated unrotated; rotate applies to lookups and samples)
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    theta, phi = np.meshgrid(np.pi * v, 2.0 * np.pi * u, indexing="ij")
    d = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], axis=-1)
    y = d[..., 1:2]
    zen, hor, gnd = (np.asarray(c, np.float64).reshape(1, 1, 3) for c in (zenith, horizon, ground))
    sky = hor + (zen - hor) * (1.0 - np.exp(-4.0 * np.maximum(y, 0.0)))
    cos_sun = np.clip(d @ s, -1.0, 1.0)[..., None]
    angle = np.arccos(cos_sun)
    if s[1] > 0:
        sky = sky * (1.0 + np.exp(-(angle / math.radians(12.0)) ** 2))
    rgb = np.where(y > 0, sky, gnd * (0.8 + 0.2 * np.exp(4.0 * np.minimum(y, 0.0))))
    if s[1] > 0:
        radius = math.radians(float(sun_radius))
        disc = (angle[..., 0] <= radius) & (y[..., 0] > 0)
        if not disc.any():  # a disc smaller than a pixel: light the pixel holding the sun's centre
            i = min(int(np.arccos(s[1]) / np.pi * h), h - 1)
            j = min(int((math.atan2(s[0], -s[2]) / (2 * np.pi) % 1.0) * w), w - 1)
            disc[i, j] = True
        # radiance so that the disc's pixels (their true solid angles) give the wanted irradiance
        d_omega = _pixel_solid_angles(h, w)[:, None] * np.ones((1, w))
        omega = float((d_omega * disc).sum())
        radiance = float(sun_irradiance) / omega * np.asarray(sun_colour, np.float64)
        rgb = np.where(disc[..., None], radiance.reshape(1, 1, 3), rgb)
    return EnvironmentMap(rgb.astype(np.float32), rotate, scale, "procedural sky")


def _pixel_solid_angles(h: int, w: int) -> np.ndarray:
    """(H,) solid angle of one pixel in each row, sr: (2 pi / W) (cos theta_top - cos theta_bottom)."""
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    return (2.0 * np.pi / w) * (edges[:-1] - edges[1:])


def environment_lights(envmap: EnvironmentMap, count: int, seed: int, scale: float = 1.0) -> LightSet:
    """Importance-sample the map into ``count`` directional lights.

    Pixels are chosen by luminance x pixel solid angle (``(2 pi / W)(cos theta_top - cos theta_bottom)``,
    the exact form of ``sin(theta)``), with jittered stratified 1D samples over their CDF (one
    stratum of width 1/count per light); within the pixel the direction is uniform in solid angle
    (azimuth from the stratum sample's remainder, cos(theta) from a randomly shifted radical
    inverse). So ``pdf(w) = luminance(L(w)) / S`` with ``S = sum(luminance x solid angle)``, and each
    light's irradiance is ``I_k = L(w_k) / (count * pdf(w_k)) = L(w_k) * S / (count *
    luminance(L(w_k)))``: ``sum_k I_k V(w_k) max(0, n . w_k)`` is an unbiased estimate of the
    irradiance ``integral L(w) V(w) max(0, n . w) dw`` for any receiver. Each light carries the same
    luminance ``S / count``.

    envmap : EnvironmentMap (its rotation and scale apply); count : > 0; seed : int (numpy
    ``default_rng``); scale : extra radiance factor on top of ``envmap.scale``.

    Returns a ``directional`` LightSet (empty for an all-black map).
    """
    count = int(count)
    h, w = envmap.shape
    pixels = envmap.pixels.astype(np.float64).reshape(-1, 3)
    lum = pixels @ LUMINANCE
    weight = lum * np.repeat(_pixel_solid_angles(h, w), w)
    positive = np.flatnonzero(weight > 0)
    if count <= 0 or len(positive) == 0:
        return LightSet(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), "directional")
    rng = np.random.default_rng(seed)
    cdf = np.cumsum(weight)
    total = cdf[-1]
    x = (np.arange(count) + rng.random(count)) / count * total
    k = np.minimum(np.searchsorted(cdf, x, side="right"), positive[-1])
    r = np.clip((x - (cdf[k] - weight[k])) / weight[k], 0.0, np.nextafter(1.0, 0.0))
    row, col = np.divmod(k, w)
    s = (radical_inverse_base2(np.arange(count)) + rng.random()) % 1.0
    cos_top = np.cos(np.pi * row / h)
    cos_bottom = np.cos(np.pi * (row + 1) / h)
    cos_theta = cos_top - s * (cos_top - cos_bottom)
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta ** 2))
    phi = 2.0 * np.pi * (col + r) / w
    d = np.stack([np.sin(phi) * sin_theta, cos_theta, -np.cos(phi) * sin_theta], axis=-1) @ envmap.rotation.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    intensity = pixels[k] * (total * envmap.scale * float(scale) / (count * lum[k]))[:, None]
    return LightSet(d, np.zeros((count, 3)), intensity, "directional", np.zeros(count, bool),
                    {"environment_count": count})
