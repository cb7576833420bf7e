r"""Rendering an image with lightcuts (or the brute-force reference): one numba kernel over pixels.

Per eye ray (lightcuts.render.camera: ``spp`` stratified jittered samples per pixel): a miss shows
the environment map's radiance (black without one); the front of an emitter shows its emitted
radiance plus the light it reflects, its back is black (emitters are one-sided and absorb, as in
lightcuts.lights.indirect); any other hit is shaded by a lightcut through all trees
(lightcuts.render.cut) or, for the reference, by every light (lightcuts.render.reference); surfaces
are two-sided. The trees and lights are flattened into one forest
(lightcuts.render.forest.build_forest), so one kernel specialisation serves every light type and the
reference.

Shadow rays start ``ray_offset`` (:func:`shadow_ray_offset`, world units) off the surface along the
shading normal (on the light's side) and stop as far short of a light at a point (lights sit on
surfaces); rays to directional lights are unbounded. Clamping (``clamp=True``) applies to indirect
VPLs in the estimate and the bound alike (docs/math.md, "Clamping").

The kernel is ``nogil`` and runs on lightcuts.parallel's threads over bands of rows (a Python loop
over bands drives ``progress``), each thread taking the next chunk of pixels from an atomic counter
(pixels differ in cost, and the cores are shared), rather than a ``parallel=True`` kernel, which
compiles several times slower on a cold cache (docs/performance.md, "Renderer"). Every pixel is
computed by one thread and written to its own cells, so images do not depend on the thread count or
the scheduling.

The kernel compiles once per kernel caster (the tag in the caster's data, lightcuts.accel.kernel_api)
and calls that caster's device functions directly. numba caches each module's kernels keyed on that
module's source file only: after editing bounds, shading, forest, heap, cut, reference, camera or a
caster's device functions (lightcuts/accel), delete ``lightcuts/render/__pycache__/*.nb[ic]`` (or
touch this file), or a cached kernel built from the old code may still run.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numba import njit

from lightcuts.accel.base import kernel_caster_of
from lightcuts.accel.kernel_api import intersect, new_scratch
from lightcuts.accel.packets import new_ray_packet
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_CONTINUATION_RAYS
from lightcuts.hashing import mix64
from lightcuts.lights.environment import envmap_radiance
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.parallel import next_task, on_counter
from lightcuts.render import MAX_CUT
from lightcuts.render.camera import CAM_POSITION, CAM_WIDTH, camera_params, check_crop, eye_ray, strata
from lightcuts.render.continuation import continuation, path_key
from lightcuts.render.cut import lightcut, luminance
from lightcuts.render.forest import build_forest
from lightcuts.render.reference import all_lights
from lightcuts.render.shading import facing_normal, reflect
from lightcuts.scene.textures import albedo_at

#: Shadow-ray origin offset (and gap before a light), as a fraction of the scene's size or its
#: distance from the origin, whichever is larger: Embree works in float32 (7 digits), so this is
#: about a thousand float32 ulps of any coordinate.
RAY_OFFSET = 1e-4
#: Pixels a thread takes at a time.
CHUNK = 32
#: Pixels per band (the unit of progress reports).
BAND_PIXELS = 4096


@dataclass
class RenderResult:
    """What a render produced (H, W = the crop window's size, the whole image without a crop).

    image : (H, W, 3) float32, linear RGB radiance
    cut_size : (H, W) float32, nodes in the final cut (summed over the trees) averaged over the
        pixel's eye rays; for the reference, the number of lights evaluated. Eye rays that miss or
        see the back of an emitter count 0.
    shadow_rays_image : (H, W) int64, shadow rays cast per pixel (all its eye rays)
    shadow_rays, eye_rays : int, totals
    clamped_energy : float, mean luminance per pixel removed by clamping (the cut's estimate of it;
        exact for the reference)
    clamped_fraction : float, clamped_energy / (mean luminance + clamped_energy): the fraction of
        the reflected light that clamping removed
    seconds : float, wall time of the render (kernel and setup; a cold numba cache adds compile time)
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


@njit(cache=True, error_model="numpy")
def _render_pixel(cdata, width, cam, seed, spp, sx, sy, px, py,
                  face_normal, albedo, tex, specular, exponent, emission, node_b, node_bi, roots, light_f, light_i,
                  env_pixels, env_rotation, env_scale, eps, max_cut, clamp_d2, ray_offset, visibility, reference,
                  compensation, stochastic, buf, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot):
    """All eye rays of pixel (px, py): returns (L_r, L_g, L_b, cut, shadow_rays, clamp_lost), cut
    and clamp_lost summed over the eye rays. An empty env_pixels (0, 0, 3) means no environment.
    cdata, width : the caster's data and packet width (lightcuts.accel.base.KernelCaster); buf : its
    scratch. compensation : the eye-path continuations (lightcuts.render.continuation) averaged per
    eye ray (0: none), whose rays count as shadow rays; stochastic : stochastic representatives (lightcuts.render.cut)."""
    o0, o1, o2 = cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    cut = 0.0
    lost = 0.0
    rays = 0
    pixel = np.int64(py) * np.int64(cam[CAM_WIDTH]) + np.int64(px)
    for s in range(spp):
        d0, d1, d2 = eye_ray(cam, seed, px, py, s, sx, sy)
        t, prim = intersect(cdata, buf, o0, o1, o2, d0, d1, d2, 0.0, np.inf)
        if prim < 0:
            if env_pixels.shape[0] > 0:
                e0, e1, e2 = envmap_radiance(env_pixels, env_rotation, env_scale, d0, d1, d2)
                a0 += e0
                a1 += e1
                a2 += e2
            continue
        f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
        e0, e1, e2 = emission[prim, 0], emission[prim, 1], emission[prim, 2]
        if e0 > 0.0 or e1 > 0.0 or e2 > 0.0:
            if f0 * d0 + f1 * d1 + f2 * d2 >= 0.0:
                continue  # the back of an emitter is black (it absorbs: see lights.indirect)
            a0 += e0
            a1 += e1
            a2 += e2
        p0, p1, p2 = o0 + t * d0, o1 + t * d1, o2 + t * d2
        n0, n1, n2 = facing_normal(f0, f1, f2, -d0, -d1, -d2)
        r0, r1, r2 = reflect(-d0, -d1, -d2, n0, n1, n2)
        rd0, rd1, rd2 = albedo_at(albedo, tex, prim, p0, p1, p2)
        rs0, rs1, rs2 = specular[prim, 0], specular[prim, 1], specular[prim, 2]
        if reference:
            res = all_lights(p0, p1, p2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent[prim],
                             light_f, light_i, clamp_d2, ray_offset, visibility, cdata, buf)
        else:
            key = path_key(seed, pixel, s) if compensation or stochastic else np.uint64(0)
            skey = key if stochastic else np.uint64(0)
            res = lightcut(p0, p1, p2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent[prim],
                           node_b, node_bi, roots, light_f, eps, max_cut, clamp_d2, ray_offset, visibility,
                           cdata, buf, width, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot, 0.0, skey)
            # compensation continuations of this eye ray, averaged (0: off); the first keeps the eye ray's key
            for i in range(compensation):
                ckey = key if i == 0 else mix64(key ^ np.uint64(i)) | np.uint64(1)
                c = continuation(ckey, p0, p1, p2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2,
                                 exponent[prim], luminance(res[0], res[1], res[2]), face_normal, albedo, tex, specular,
                                 exponent, emission, node_b, node_bi, roots, light_f, eps, max_cut, clamp_d2,
                                 ray_offset, visibility, cdata, buf, width, pk, heap, slot_node, slot_mgv,
                                 slot_ratio, lane_slot, stochastic)
                a0 += c[0] / compensation
                a1 += c[1] / compensation
                a2 += c[2] / compensation
                rays += c[3]
        a0 += res[0]
        a1 += res[1]
        a2 += res[2]
        cut += res[3]
        rays += res[4]
        lost += res[5]
    return a0, a1, a2, cut, rays, lost


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, width, cam, seed, spp, sx, sy, x0, x1, y0, y1, face_normal, albedo, tex, specular, exponent,
                 emission, node_b, node_bi, roots, light_f, light_i, env_pixels, env_rotation, env_scale, eps,
                 max_cut, clamp_d2, ray_offset, visibility, reference, compensation, stochastic, pixels, out_rgb,
                 out_cut, out_rays, out_lost, tasks):
    """Render pixels [x0, x1) x [y0, y1) (full-image coordinates) into the band's output rows: one
    thread's share, chunks of CHUNK pixels taken from the counter ``tasks`` (int64 (1,), zero at the
    start; lightcuts.parallel.next_task) until none is left. A non-empty ``pixels`` ((K, 2) int64,
    x and y) renders those pixels instead, pixel i into row i of the window [0, 1) x [0, K).

    out_rgb (rows, cols, 3), out_cut (rows, cols), out_rays (rows, cols) int64, out_lost (rows, cols):
    per pixel, averaged over its eye rays except out_rays (summed).
    """
    cols = x1 - x0
    n = (y1 - y0) * cols
    cap = max(max_cut, roots.shape[0]) + 2
    buf = new_scratch(cdata)
    pk = new_ray_packet()
    lane_slot = np.empty(width, np.int64)
    heap = np.empty(cap, np.uint64)
    slot_node = np.empty(cap, np.int64)
    slot_mgv = np.empty((cap, 3))
    slot_ratio = np.empty(cap)
    while True:
        c = next_task(tasks)
        if c * CHUNK >= n:
            break
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            row = i // cols
            col = i - row * cols
            px, py = x0 + col, y0 + row
            if pixels.shape[0] > 0:
                px, py = pixels[i, 0], pixels[i, 1]
            a0, a1, a2, cut, rays, lost = _render_pixel(
                cdata, width, cam, seed, spp, sx, sy, px, py,
                face_normal, albedo, tex, specular, exponent, emission, node_b, node_bi, roots, light_f, light_i,
                env_pixels, env_rotation, env_scale, eps, max_cut, clamp_d2, ray_offset, visibility, reference,
                compensation, stochastic, buf, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot)
            out_rgb[row, col, 0] = a0 / spp
            out_rgb[row, col, 1] = a1 / spp
            out_rgb[row, col, 2] = a2 / spp
            out_cut[row, col] = cut / spp
            out_rays[row, col] = rays
            out_lost[row, col] = lost / spp


def _kernel_array(a, dtype) -> np.ndarray:
    """C-contiguous, writeable ``dtype`` array: a read-only input (a broadcast view) would make numba
    compile a second kernel specialisation."""
    a = np.ascontiguousarray(a, dtype)
    return a if a.flags.writeable else a.copy()


def shadow_ray_offset(scene) -> float:
    """Shadow-ray origin offset and gap before a light, world units (see ``RAY_OFFSET``)."""
    lo, hi = scene.bounds
    return RAY_OFFSET * max(float(np.linalg.norm(hi - lo)), float(np.abs(np.concatenate([lo, hi])).max()), 1e-30)


def _render(scene, caster, lights, trees, camera, spp, eps, max_cut, clamp, clamp_min_distance, envmap, seed,
            crop, progress, reference, visibility, pixels=None, compensation=False,
            representatives="fixed", continuation_rays=1, forest=None) -> RenderResult:
    t_start = time.perf_counter()
    camera = camera if camera is not None else scene.camera
    cam = camera_params(camera)
    x0, y0, x1, y1 = check_crop(crop, camera)
    if pixels is None:
        pix = np.zeros((0, 2), np.int64)
    else:
        pix = np.ascontiguousarray(pixels, np.int64).reshape(-1, 2)
        if crop is not None or len(pix) == 0 or (pix < 0).any() or (pix[:, 0] >= camera.width).any() \
                or (pix[:, 1] >= camera.height).any():
            raise LightcutsError(f"pixels: {len(pix)} pixel(s), expected at least one, each inside the "
                                 f"{camera.width} x {camera.height} image, and no crop")
        x0, y0, x1, y1 = 0, 0, 1, len(pix)
    if int(spp) != spp or spp < 1:
        raise LightcutsError(f"render.spp: {spp} must be a positive integer")
    if not (eps >= 0 and math.isfinite(eps)):
        raise LightcutsError(f"render.eps: {eps} must be a finite number >= 0")
    if int(max_cut) != max_cut or not 1 <= max_cut <= MAX_CUT:
        raise LightcutsError(f"render.max_cut: {max_cut} must be an integer from 1 to {MAX_CUT}")
    if not (clamp_min_distance >= 0 and math.isfinite(clamp_min_distance)):
        raise LightcutsError(f"render.clamp.min_distance: {clamp_min_distance} must be a finite number >= 0")
    if int(seed) != seed or seed < 0:
        raise LightcutsError(f"seed: {seed} must be a non-negative integer")
    if int(continuation_rays) != continuation_rays or not 1 <= continuation_rays <= MAX_CONTINUATION_RAYS:
        raise LightcutsError(f"render.continuation_rays: {continuation_rays} must be an integer from 1 to "
                             f"{MAX_CONTINUATION_RAYS}")
    if representatives not in ("fixed", "stochastic"):
        raise LightcutsError(f"render.representatives: {representatives!r} must be 'fixed' or 'stochastic'")
    stochastic = representatives == "stochastic"
    kc = kernel_caster_of(caster)
    if kc is None:
        raise LightcutsError(f"render.ray_caster: {type(caster).__name__} cannot be called from kernels; "
                             f"use a kernel-callable caster such as 'embree'")
    if forest is None:
        forest = build_forest(lights, None if reference else trees)
    spp, max_cut, seed = int(spp), int(max_cut), int(seed)
    sx, sy = strata(spp)
    diag = scene.diagonal
    clamp_d2 = (clamp_min_distance * diag) ** 2 if clamp else 0.0
    ray_offset = shadow_ray_offset(scene)
    face_normal, albedo, specular, emission = (_kernel_array(a, np.float64) for a in (
        scene.face_normals, scene.albedo, scene.specular, scene.emission))
    exponent = _kernel_array(scene.exponent, np.float64)
    if envmap is None:
        env_pixels, env_rotation, env_scale = np.zeros((0, 0, 3), np.float32), np.eye(3), 0.0
    else:
        env_pixels = _kernel_array(envmap.pixels, np.float32)
        env_rotation = _kernel_array(envmap.rotation, np.float64)
        env_scale = float(envmap.scale)

    rows, cols = y1 - y0, x1 - x0
    rgb = np.zeros((rows, cols, 3))
    cut = np.zeros((rows, cols))
    rays = np.zeros((rows, cols), np.int64)
    lost = np.zeros((rows, cols))
    band = max(1, BAND_PIXELS // cols)
    f = forest
    for b0 in range(0, rows, band):
        b1 = min(rows, b0 + band)
        on_counter(_render_band, (b1 - b0) * cols, 2 * CHUNK, *kc, cam, seed, spp, sx, sy, x0, x1, y0 + b0,
                   y0 + b1, face_normal, albedo, scene.texture_data(), specular, exponent, emission, f.node_b, f.node_bi, f.roots,
                   f.light_f, f.light_i, env_pixels, env_rotation, env_scale, float(eps), max_cut, float(clamp_d2),
                   float(ray_offset), bool(visibility), bool(reference), int(continuation_rays) if compensation and not reference else 0,
                   bool(stochastic and not reference), pix[b0:b1] if len(pix) else pix,
                   rgb[b0:b1], cut[b0:b1], rays[b0:b1], lost[b0:b1])
        if progress is not None:
            progress(b1 - b0)

    lum = rgb @ LUMINANCE
    clamped = float(lost.mean())
    total = float(lum.mean()) + clamped
    return RenderResult(
        image=rgb.astype(np.float32), cut_size=cut.astype(np.float32), shadow_rays_image=rays,
        shadow_rays=int(rays.sum()), eye_rays=rows * cols * spp, clamped_energy=clamped,
        clamped_fraction=clamped / total if total > 0 else 0.0, seconds=time.perf_counter() - t_start,
        spp=spp, eps=float(eps), max_cut=max_cut, reference=reference,
        crop=(x0, y0, x1, y1) if pixels is None else None, n_lights=forest.n_lights)


def render_image(scene, caster, lights: dict, trees: dict, camera=None, spp: int = 1, eps: float = 0.02,
                 max_cut: int = 1000, clamp: bool = True, clamp_min_distance: float = 0.05, envmap=None,
                 seed: int = 0, crop=None, progress: Callable[[int], object] | None = None,
                 reference: bool = False, visibility: bool = True, pixels=None, compensation: bool = False,
                 representatives: str = "fixed", continuation_rays: int = 1, forest=None) -> RenderResult:
    """Render with lightcuts (or, with ``reference=True``, every light at every pixel).

    scene : lightcuts.scene.Scene; caster : a kernel-callable ray caster (``kernel_caster``: ``embree``,
    ``bvh-sah``, ...)
    lights : {type: LightSet} (types of LIGHT_TYPES; empty or absent types contribute nothing)
    trees : {type: LightTree}, one per light set (ignored for the reference)
    camera : lightcuts.scene.Camera (default: ``scene.camera``)
    spp : eye rays per pixel (stratified, jittered); eps : relative error threshold of the cut (0:
    refine until every node in the cut is exact); max_cut : largest cut, nodes over all trees
    clamp, clamp_min_distance : clamping of indirect VPLs at ``clamp_min_distance * scene diagonal``
    envmap : lightcuts.lights.environment.EnvironmentMap seen by eye rays that miss, or None (black)
    seed : seed of the eye-ray jitter; crop : (x0, y0, x1, y1) window of the image, pixels, or None
    progress : called with the number of image rows finished after each band (e.g. ``tqdm.update``)
    reference : evaluate every light at every hit instead of a cut (see :func:`render_reference`)
    visibility : False casts no shadow rays (every light visible): unshadowed images, and the cost of
        the cut without Embree's share (benchmarks/bench_render.py)
    pixels : (K, 2) int (x, y) of the pixels to render instead of the image or crop (e.g. a sample of
        pixels for an error measurement); then the result's arrays are (K, 1, ...), pixel i in row i,
        with the same values as those pixels of a whole-image render
    compensation : add the light the VPLs lose to clamping and to glossy surfaces, by a continuation
        of the eye path (lightcuts.render.continuation; the VPLs must come from glossy particle
        paths, ``indirect_lights(glossy=True)``); its rays count as shadow rays
    representatives : ``fixed`` (the trees') or ``stochastic`` (one light drawn per cut node and
        eye ray, lightcuts.render.cut.stochastic_estimate)
    continuation_rays : with compensation, the continuations averaged per eye ray (1 to
        MAX_CONTINUATION_RAYS): less noise in the compensated light for one primary cut
    forest : ``build_forest(lights, trees)`` (for the reference, ``build_forest(lights, None)``) made
        once for several calls over the same lights, e.g. the tiles of one image; None: built here

    The caster must stay open during the call. LightcutsError for invalid parameters or inputs.
    """
    return _render(scene, caster, lights, trees, camera, spp, eps, max_cut, clamp, clamp_min_distance, envmap,
                   seed, crop, progress, reference, visibility, pixels, compensation, representatives,
                   continuation_rays, forest)


def render_reference(scene, caster, lights: dict, camera=None, spp: int = 1, clamp: bool = True,
                     clamp_min_distance: float = 0.05, envmap=None, seed: int = 0, crop=None,
                     progress: Callable[[int], object] | None = None, visibility: bool = True,
                     pixels=None, forest=None) -> RenderResult:
    """The brute-force reference: the same eye rays and shading as :func:`render_image`, every light
    at every hit with one shadow ray each (no trees). Arguments as :func:`render_image`."""
    return _render(scene, caster, lights, None, camera, spp, 0.0, 1, clamp, clamp_min_distance, envmap, seed,
                   crop, progress, True, visibility, pixels, forest=forest)


def warm_kernels() -> None:
    """Compile the render kernel into numba's cache (and the forest's packing kernel it calls first)
    by rendering one pixel of the built-in Cornell box without lights: a kernel's specialisation
    depends only on its arguments' types, which are those of every render
    (lightcuts.commands.warmup runs this in a child process while the command builds the trees)."""
    from lightcuts.accel import make_caster
    from lightcuts.scene.cornell import cornell_box

    scene = cornell_box()
    with make_caster(scene, "embree") as caster:
        render_image(scene, caster, {}, {}, crop=(0, 0, 1, 1))
