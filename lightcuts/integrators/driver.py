r"""The image driver every integrator shares: from a window of the image to a :class:`RenderResult`.

:func:`render_window` checks the per-run inputs (crop window or pixel list, seed, a kernel-callable
ray caster), makes the scene's and the environment's kernel arrays and the light forest the
integrator asks for, then runs the integrator's band kernel (:meth:`Integrator.band_kernel
<lightcuts.integrators.registry.Integrator.band_kernel>`) over bands of rows, reporting progress after
each, and sums the per-pixel outputs into the result.

A band kernel is called as ``kernel(*head, x0, x1, y0, y1, *tail, pixels, out_rgb, out_cut,
out_rays, out_lost, tasks)``: it renders the pixels [x0, x1) x [y0, y1) (full-image coordinates;
a non-empty ``pixels`` (K, 2) int64 renders those pixels instead, pixel i into row i) into the
band's rows of out_rgb (rows, cols, 3), out_cut (rows, cols), out_rays (rows, cols) int64 and
out_lost (rows, cols), each thread taking chunks of pixels from the counter ``tasks``
(lightcuts.parallel.on_counter). It runs ``nogil`` on lightcuts.parallel's threads rather than as a
``parallel=True`` kernel, which compiles several times slower on a cold cache (docs/performance.md,
"Renderer"). Every pixel is computed by one thread and written to its own cells, seeded by its
absolute coordinates, so images do not depend on the thread count, the bands or the crop window.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np
from numba import njit

from lightcuts.accel.base import KernelCaster, kernel_caster_of
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.parallel import on_counter
from lightcuts.scene.scene import kernel_array
from lightcuts.integrators.camera import camera_params, check_crop, strata

#: Shadow-ray origin offset (and gap before a light), as a fraction of the scene's size or its
#: distance from the origin, whichever is larger: Embree works in float32 (7 digits), so this is
#: about a thousand float32 ulps of any coordinate.
RAY_OFFSET = 1e-4
#: Pixels per band (the unit of progress reports) of a one-eye-ray-per-pixel render.
BAND_PIXELS = 4096


@dataclass
class RenderResult:
    """What a render produced (H, W = the crop window's size, the whole image without a crop; with a
    pixel list of K pixels, H = K and W = 1, pixel i in row i).

    image : (H, W, 3) float32, linear RGB radiance
    cut_size : (H, W) float32, the pixel's cut in the integrator's ``cut_unit``: for ``lightcuts``,
        nodes in the final cut (summed over the trees) averaged over the pixel's eye rays, for its
        reference the number of lights evaluated; for ``multidimensional``, the (gather, light)
        pairs of the pixel's cut; for ``path``, path vertices per eye ray. Eye rays that miss or see
        the back of an emitter count 0.
    shadow_rays_image : (H, W) int64, shadow rays cast per pixel (all its eye rays)
    shadow_rays, eye_rays : int, totals
    clamped_energy : float, mean luminance per pixel removed by clamping (the cut's estimate of it;
        exact for the reference)
    clamped_fraction : float, clamped_energy / (mean luminance + clamped_energy): the fraction of
        the reflected light that clamping removed
    seconds : float, wall time of the render (kernel and setup; a cold numba cache adds compile time)
    spp, eps, max_cut : the integrator's settings (max_cut: the bound of cut_size per eye ray)
    reference : whether a brute-force reference rendered it
    crop : the window rendered (None for a pixel list); n_lights : {type: count} of the forest
    clamp_radius : the radius within which indirect VPLs were clamped, world units (0: none)
    light_sampler : how the render drew lights (the integrator's :meth:`sampler_record
        <lightcuts.integrators.registry.Integrator.sampler_record>`, report.json's ``light_sampler``),
        {} for an integrator that draws none
    """

    image: np.ndarray
    cut_size: np.ndarray
    shadow_rays_image: np.ndarray
    shadow_rays: int
    eye_rays: int
    clamped_energy: float
    clamped_fraction: float
    seconds: float
    spp: int
    eps: float
    max_cut: int
    reference: bool
    crop: tuple[int, int, int, int] | None
    n_lights: dict = field(default_factory=dict)
    clamp_radius: float = 0.0
    light_sampler: dict = field(default_factory=dict)


class Frame(NamedTuple):
    """What the driver hands an integrator's :meth:`band_kernel`: the run's kernel inputs.

    scene, camera : the Scene and the Camera rendered; cam : (16,) float64 camera_params(camera)
    caster : the caster's KernelCaster (data, width); seed : the eye rays' seed; sx, sy : the strata
    surfaces : (face_normal, albedo, tex, specular, exponent, emission), the scene's per-triangle
        arrays (tex: its texture tuple, lightcuts.scene.textures.albedo_at)
    env : (env_pixels, env_rotation, env_scale), the environment map (env_pixels (0, 0, 3): none)
    forest : the light forest (the integrator's :meth:`forest`), or None
    ray_offset : :func:`shadow_ray_offset` of the scene; cols : the window's width, pixels
    """

    scene: object
    camera: object
    cam: np.ndarray
    caster: KernelCaster
    seed: int
    sx: int
    sy: int
    surfaces: tuple
    env: tuple
    forest: object
    ray_offset: float
    cols: int


class Band(NamedTuple):
    """An integrator's band kernel call (module docstring): ``kernel(*head, x0, x1, y0, y1, *tail,
    pixels, out_rgb, out_cut, out_rays, out_lost, tasks)``; ``rows``: image rows per band; ``chunk``:
    the pixels a thread takes at a time (the kernel's own constant)."""

    kernel: Callable
    head: tuple
    tail: tuple
    rows: int
    chunk: int


@njit(cache=True, inline="always")
def band_pixel(i, cols, x0, y0, pixels):
    """In a band kernel: the band's i-th pixel as ``(row, col, px, py)``, its cell in the band's
    outputs and its full-image coordinates (row i of a non-empty pixel list ``pixels``)."""
    row = i // cols
    col = i - row * cols
    if pixels.shape[0] > 0:
        return row, col, pixels[i, 0], pixels[i, 1]
    return row, col, x0 + col, y0 + row


def shadow_ray_offset(scene) -> float:
    """Shadow-ray origin offset and gap before a light, world units (see ``RAY_OFFSET``)."""
    lo, hi = scene.bounds
    return RAY_OFFSET * max(float(np.linalg.norm(hi - lo)), float(np.abs(np.concatenate([lo, hi])).max()), 1e-30)


def _window(camera, crop, pixels) -> tuple[int, int, int, int, np.ndarray]:
    """The window (x0, y0, x1, y1) and the pixel list ((0, 2) for none), checked."""
    x0, y0, x1, y1 = check_crop(crop, camera)
    if pixels is None:
        return x0, y0, x1, y1, np.zeros((0, 2), np.int64)
    pix = np.ascontiguousarray(pixels, np.int64).reshape(-1, 2)
    if crop is not None or len(pix) == 0 or (pix < 0).any() or (pix[:, 0] >= camera.width).any() \
            or (pix[:, 1] >= camera.height).any():
        raise LightcutsError(f"pixels: {len(pix)} pixel(s), expected at least one, each inside the "
                             f"{camera.width} x {camera.height} image, and no crop")
    return 0, 0, 1, len(pix), pix


def render_window(integrator, scene, caster, lights: dict, trees: dict | None, *, forest=None, camera=None,
                  envmap=None, seed: int = 0, crop=None, pixels=None,
                  progress: Callable[[int], object] | None = None) -> RenderResult:
    """The integrator's image of the window ``crop`` (or of the pixel list ``pixels``); arguments as
    :meth:`lightcuts.integrators.registry.Integrator.render`. LightcutsError naming the key for bad
    per-run inputs."""
    t_start = time.perf_counter()
    camera = camera if camera is not None else scene.camera
    cam = camera_params(camera)
    x0, y0, x1, y1, pix = _window(camera, crop, pixels)
    if int(seed) != seed or seed < 0:
        raise LightcutsError(f"seed: {seed} must be a non-negative integer")
    kc = kernel_caster_of(caster)
    if kc is None:
        raise LightcutsError(f"render.ray_caster: {type(caster).__name__} cannot be called from kernels; "
                             f"use a kernel-callable caster such as 'embree'")
    if forest is None:
        forest = integrator.forest(lights, trees, scene)
    sx, sy = strata(integrator.spp)
    surfaces = tuple(kernel_array(a, np.float64) for a in (scene.face_normals, scene.albedo))
    surfaces += (scene.texture_data(),) + tuple(kernel_array(a, np.float64) for a in (
        scene.specular, scene.exponent, scene.emission))
    if envmap is None:
        env = (np.zeros((0, 0, 3), np.float32), np.eye(3), 0.0)
    else:
        env = (kernel_array(envmap.pixels, np.float32), kernel_array(envmap.rotation, np.float64),
               float(envmap.scale))
    rows, cols = y1 - y0, x1 - x0
    band = integrator.band_kernel(Frame(scene, camera, cam, kc, int(seed), sx, sy, surfaces, env, forest,
                                        float(shadow_ray_offset(scene)), cols))
    rgb = np.zeros((rows, cols, 3))
    cut = np.zeros((rows, cols))
    rays = np.zeros((rows, cols), np.int64)
    lost = np.zeros((rows, cols))
    for b0 in range(0, rows, band.rows):
        b1 = min(rows, b0 + band.rows)
        on_counter(band.kernel, (b1 - b0) * cols, 2 * band.chunk, *band.head, x0, x1, y0 + b0, y0 + b1, *band.tail,
                   pix[b0:b1] if len(pix) else pix, rgb[b0:b1], cut[b0:b1], rays[b0:b1], lost[b0:b1])
        if progress is not None:
            progress(b1 - b0)

    lum = rgb @ LUMINANCE
    clamped = float(lost.mean())
    total = float(lum.mean()) + clamped
    return RenderResult(
        image=rgb.astype(np.float32), cut_size=cut.astype(np.float32), shadow_rays_image=rays,
        shadow_rays=int(rays.sum()), eye_rays=rows * cols * integrator.spp, clamped_energy=clamped,
        clamped_fraction=clamped / total if total > 0 else 0.0, seconds=time.perf_counter() - t_start,
        spp=integrator.spp, eps=integrator.eps, max_cut=integrator.max_cut, reference=integrator.brute_force,
        crop=(x0, y0, x1, y1) if pixels is None else None, n_lights=forest.n_lights if forest is not None else {},
        clamp_radius=integrator.clamp_radius(scene, forest),
        light_sampler=integrator.sampler_record(forest))


def warm(integrator) -> None:
    """Compile ``integrator``'s band kernel into numba's cache (and the kernels it calls first) by
    rendering one pixel of the built-in Cornell box without lights: a kernel's specialisation depends
    only on its arguments' types, which are those of every render (lightcuts.pipeline.warmup runs the
    kernels module's ``warm_kernels()``, which calls this, in a child process while the command makes
    the lights and trees)."""
    from lightcuts.accel import make_caster
    from lightcuts.scene.cornell import cornell_box

    scene = cornell_box()
    with make_caster(scene, "embree") as caster:
        integrator.render(scene, caster, {}, {}, crop=(0, 0, 1, 1))
