r"""Eye rays of the pinhole camera: stratified jittered samples, counter-based random numbers.

Pixel ``(px, py)`` (row ``py = 0`` at the top of the image) and sample ``s`` of ``spp`` get the film
position ``(px + u, py + v)`` with ``(u, v)`` jittered inside stratum ``s`` of an ``sx x sy`` grid over
the pixel (``sx * sy = spp``, the factorisation closest to square; a prime spp gives a 1-row grid).
The jitter comes from a counter-based hash of ``(seed, pixel index in the full image, s, dimension)``,
so each pixel's rays depend on nothing else: not on the thread count, the band or the crop window
(a crop renders exactly the full image's pixels).

Camera model (lightcuts.scene.Camera): vertical field of view ``fov``; the ray through film position
``(fx, fy)`` has direction ``forward + a * right + b * up`` with
``a = (2 fx / W - 1) tan(fov / 2) W / H`` and ``b = (1 - 2 fy / H) tan(fov / 2)``, normalised.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.hashing import mix64

#: Layout of the (16,) float64 camera parameter array used by kernels.
CAM_POSITION, CAM_RIGHT, CAM_UP, CAM_FORWARD = 0, 3, 6, 9
CAM_SCALE_X, CAM_SCALE_Y, CAM_WIDTH, CAM_HEIGHT = 12, 13, 14, 15

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S11 = np.uint64(11)


@njit(cache=True, error_model="numpy", inline="always")
def hash_uniform(seed, pixel, sample, dim):
    """A uniform float64 in [0, 1) determined only by the four non-negative integer counters."""
    h = mix64(np.uint64(seed) + _GOLDEN)
    h = mix64(h ^ np.uint64(pixel))
    h = mix64(h ^ (np.uint64(sample) * np.uint64(4) + np.uint64(dim)))
    return np.float64(h >> _S11) * (1.0 / 9007199254740992.0)


def strata(spp: int) -> tuple[int, int]:
    """(sx, sy): the grid of strata per pixel, sx * sy = spp, sx >= sy, as square as possible."""
    sy = max(d for d in range(1, math.isqrt(spp) + 1) if spp % d == 0)
    return spp // sy, sy


@njit(cache=True, error_model="numpy")
def eye_ray(cam, seed, px, py, s, sx, sy):
    """Direction (unit, world) of sample s of pixel (px, py); the origin is the camera position.

    cam : (16,) float64 from :func:`camera_params`; sx, sy : the strata grid (:func:`strata`).
    """
    width = cam[CAM_WIDTH]
    pixel = np.int64(py) * np.int64(width) + np.int64(px)
    u = (s % sx + hash_uniform(seed, pixel, s, 0)) / sx
    v = (s // sx + hash_uniform(seed, pixel, s, 1)) / sy
    a = (2.0 * (px + u) / width - 1.0) * cam[CAM_SCALE_X]
    b = (1.0 - 2.0 * (py + v) / cam[CAM_HEIGHT]) * cam[CAM_SCALE_Y]
    d0 = cam[CAM_FORWARD] + a * cam[CAM_RIGHT] + b * cam[CAM_UP]
    d1 = cam[CAM_FORWARD + 1] + a * cam[CAM_RIGHT + 1] + b * cam[CAM_UP + 1]
    d2 = cam[CAM_FORWARD + 2] + a * cam[CAM_RIGHT + 2] + b * cam[CAM_UP + 2]
    norm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return d0 / norm, d1 / norm, d2 / norm


@njit(cache=True, error_model="numpy")
def _disk(u, v):
    """Shirley's concentric map of the unit square onto the unit disk (area-preserving)."""
    a, b = 2.0 * u - 1.0, 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r, phi = a, (np.pi / 4.0) * (b / a)
    else:
        r, phi = b, np.pi / 2.0 - (np.pi / 4.0) * (a / b)
    return r * np.cos(phi), r * np.sin(phi)


@njit(cache=True, error_model="numpy")
def lens_ray(cam, seed, px, py, s, sx, sy, aperture, focus):
    """Origin and unit direction of sample s of pixel (px, py) through a thin lens.

    aperture : lens radius, world units (0: exactly :func:`eye_ray` from the camera position);
    focus : distance along the view axis of the plane in focus, world units. The lens position is
    stratified over the same sx x sy grid (mapped to the disk), its stratum a per-pixel random
    cyclic shift of s, so pixel and lens strata are paired differently in every pixel.
    """
    d0, d1, d2 = eye_ray(cam, seed, px, py, s, sx, sy)
    o0, o1, o2 = cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]
    if aperture <= 0.0:
        return o0, o1, o2, d0, d1, d2
    spp = sx * sy
    pixel = np.int64(py) * np.int64(cam[CAM_WIDTH]) + np.int64(px)
    t = (s + np.int64(hash_uniform(seed, pixel, spp, 2) * spp)) % spp
    u = (t % sx + hash_uniform(seed, pixel, s, 2)) / sx
    v = (t // sx + hash_uniform(seed, pixel, s, 3)) / sy
    lx, ly = _disk(u, v)
    lx, ly = lx * aperture, ly * aperture
    # The pinhole ray meets the plane of focus at f; the lens ray aims at the same point.
    cos_f = d0 * cam[CAM_FORWARD] + d1 * cam[CAM_FORWARD + 1] + d2 * cam[CAM_FORWARD + 2]
    k = focus / cos_f
    f0, f1, f2 = o0 + k * d0, o1 + k * d1, o2 + k * d2
    o0 += lx * cam[CAM_RIGHT] + ly * cam[CAM_UP]
    o1 += lx * cam[CAM_RIGHT + 1] + ly * cam[CAM_UP + 1]
    o2 += lx * cam[CAM_RIGHT + 2] + ly * cam[CAM_UP + 2]
    e0, e1, e2 = f0 - o0, f1 - o1, f2 - o2
    norm = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    return o0, o1, o2, e0 / norm, e1 / norm, e2 / norm


def camera_params(camera) -> np.ndarray:
    """(16,) float64 kernel parameters of a lightcuts.scene.Camera (layout: the ``CAM_*`` offsets).

    LightcutsError if the camera cannot form an image (fov, resolution, degenerate frame).
    """
    if camera is None:
        raise LightcutsError("camera: the scene has no camera and none was given")
    if not 0.0 < camera.fov < 180.0:
        raise LightcutsError(f"camera.fov: {camera.fov} is not in (0, 180) degrees")
    if camera.width < 1 or camera.height < 1:
        raise LightcutsError(f"camera.resolution: {camera.width} x {camera.height} is not a positive size")
    vecs = np.stack([camera.position, camera.look_at, camera.up])
    if not np.all(np.isfinite(vecs)):
        raise LightcutsError("camera: position, look_at and up must be finite")
    with np.errstate(invalid="ignore", divide="ignore"):
        right, up, fwd = camera.frame()
    if not (np.all(np.isfinite(right)) and np.all(np.isfinite(fwd))):
        raise LightcutsError("camera: look_at equals position, or up is parallel to the view direction")
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    return np.concatenate([camera.position, right, up, fwd,
                           [tan_half * camera.width / camera.height, tan_half, camera.width, camera.height]])


@njit(cache=True, error_model="numpy")
def _eye_rays(cam, seed, x0, y0, x1, y1, spp, sx, sy, dirs):
    k = 0
    for py in range(y0, y1):
        for px in range(x0, x1):
            for s in range(spp):
                dirs[k, 0], dirs[k, 1], dirs[k, 2] = eye_ray(cam, seed, px, py, s, sx, sy)
                k += 1


def eye_rays(camera, spp: int = 1, seed: int = 0, crop=None) -> tuple[np.ndarray, np.ndarray]:
    """All eye rays of an image (or of ``crop = (x0, y0, x1, y1)``), as the renderer casts them.

    Returns origins and unit directions, each (H, W, spp, 3) float64 (H, W of the crop window),
    in row-major pixel order with row 0 at the top.
    """
    cam = camera_params(camera)
    x0, y0, x1, y1 = check_crop(crop, camera)
    sx, sy = strata(spp)
    dirs = np.empty(((y1 - y0) * (x1 - x0) * spp, 3))
    _eye_rays(cam, seed, x0, y0, x1, y1, spp, sx, sy, dirs)
    dirs = dirs.reshape(y1 - y0, x1 - x0, spp, 3)
    return np.broadcast_to(camera.position, dirs.shape).copy(), dirs


def check_crop(crop, camera) -> tuple[int, int, int, int]:
    """The window ``(x0, y0, x1, y1)`` (half-open, pixels) checked against the image; None = all."""
    if crop is None:
        return 0, 0, camera.width, camera.height
    x0, y0, x1, y1 = (int(v) for v in crop)
    if not (0 <= x0 < x1 <= camera.width and 0 <= y0 < y1 <= camera.height):
        raise LightcutsError(f"render.crop: {list(crop)} is not a non-empty window [x0, y0, x1, y1) inside "
                             f"the {camera.width} x {camera.height} image")
    return x0, y0, x1, y1
