r"""Rendering an image with multidimensional lightcuts (or its brute-force reference): the pixel loop.

Per pixel: its gather points (lightcuts.render.multidim.gather: ``spp`` eye rays over the pixel and
the lens), its gather tree (gather_tree), then one product cut (product_cut) over the gather tree
and the light forest, or, for the reference, every gather point with every light. The kernel runs
on lightcuts.parallel's threads like lightcuts.render.integrator's (chunks of pixels from an atomic
counter, every pixel written by one thread, every random number a hash of the seed and the pixel),
so images do not depend on the thread count. The result is a lightcuts.render.integrator
RenderResult whose ``cut_size`` is the number of (gather, light) pairs in each pixel's cut (for the
reference: gather points x lights).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from lightcuts.accel.base import kernel_caster_of
from lightcuts.accel.kernel_api import new_scratch
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.parallel import next_task, on_counter
from lightcuts.render import DEFAULT_REPRESENTATIVES, MAX_CUT
from lightcuts.render.camera import CAM_WIDTH, camera_params, check_crop, strata
from lightcuts.render.forest import build_forest
from lightcuts.render.integrator import BAND_PIXELS, CHUNK, RenderResult, _kernel_array, shadow_ray_offset
from lightcuts.render.multidim.gather import GP_WIDTH, pixel_gather
from lightcuts.render.multidim.gather_tree import GK_WIDTH, GN_WIDTH, build_gather_tree, gather_representatives
from lightcuts.render.multidim.product_cut import all_pairs, light_representatives, product_cut


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, cam, seed, spp, sx, sy, aperture, focus, x0, x1, y0, y1, face_normal, albedo, tex, specular,
                 exponent, emission, node_b, node_bi, roots, light_f, light_i, lreps, g_count, env_pixels, env_rotation,
                 env_scale, eps, max_cut, clamp_d2, ray_offset, visibility, reference, pixels, out_rgb, out_cut,
                 out_rays, out_lost, tasks):
    """Pixels [x0, x1) x [y0, y1) (or the listed ``pixels``) into the band's rows, as
    lightcuts.render.integrator._render_band; out_cut : pairs in the cut per pixel."""
    cols = x1 - x0
    n = (y1 - y0) * cols
    cap = max(max_cut, roots.shape[0]) + 2
    buf = new_scratch(cdata)
    gp = np.empty((spp, GP_WIDTH))
    gn = np.empty((2 * spp, GN_WIDTH))
    gk = np.empty((2 * spp, GK_WIDTH), np.int64)
    greps = np.empty((2 * spp, g_count), np.int64)
    idx = np.empty(spp, np.int64)
    stack = np.empty((2 * spp, 3), np.int64)
    heap = np.zeros(cap, np.uint64)
    slot_g = np.empty(cap, np.int64)
    slot_l = np.empty(cap, np.int64)
    slot_rep = np.empty(cap, np.int64)
    slot_mgv = np.empty((cap, 3))
    slot_ratio = np.empty(cap)
    slot_vis = np.empty(cap, np.bool_)
    width = np.int64(cam[CAM_WIDTH])
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
            ng, a0, a1, a2 = pixel_gather(cdata, buf, cam, seed, spp, sx, sy, px, py, aperture, focus, face_normal,
                                          albedo, tex, specular, exponent, emission, env_pixels, env_rotation, env_scale,
                                          gp)
            a0 /= spp
            a1 /= spp
            a2 /= spp
            pairs = 0
            rays = 0
            lost = 0.0
            if ng > 0 and light_f.shape[0] > 0:
                if reference:
                    r0, r1, r2, pairs, rays, lost = all_pairs(gp, ng, light_f, light_i, clamp_d2, ray_offset,
                                                              visibility, cdata, buf)
                else:
                    root = build_gather_tree(gp, ng, gn, gk, idx, stack, seed, np.int64(py) * width + px)
                    gather_representatives(gn, gk, ng, seed, np.int64(py) * width + px, greps)
                    r0, r1, r2, pairs, rays, lost = product_cut(
                        gp, gn, gk, idx, greps, root, node_b, node_bi, roots, light_f, lreps, eps, max_cut, clamp_d2,
                        ray_offset, visibility, cdata, buf, heap, slot_g, slot_l, slot_rep, slot_mgv, slot_ratio,
                        slot_vis)
                a0 += r0
                a1 += r1
                a2 += r2
            out_rgb[row, col, 0] = a0
            out_rgb[row, col, 1] = a1
            out_rgb[row, col, 2] = a2
            out_cut[row, col] = pairs
            out_rays[row, col] = rays
            out_lost[row, col] = lost


def _check(camera, crop, pixels, spp, eps, max_cut, clamp_min_distance, seed, aperture, focus_distance,
           representatives, gather_representatives):
    """The window and pixel list after the checks (LightcutsError naming the key on bad input)."""
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
    if not (aperture >= 0 and math.isfinite(aperture)):
        raise LightcutsError(f"camera.aperture: {aperture} must be a finite number >= 0")
    if focus_distance is not None and not (focus_distance > 0 and math.isfinite(focus_distance)):
        raise LightcutsError(f"camera.focus_distance: {focus_distance} must be a finite number > 0")
    if int(representatives) != representatives or not 1 <= representatives <= 64:
        raise LightcutsError(f"render.integrator.representatives: {representatives} must be an integer from 1 to 64")
    if int(gather_representatives) != gather_representatives or not 1 <= gather_representatives <= 64:
        raise LightcutsError(f"render.integrator.gather_representatives: {gather_representatives} must be an "
                             f"integer from 1 to 64")
    return x0, y0, x1, y1, pix


def render_multidimensional(scene, caster, lights: dict, trees: dict | None, camera=None, spp: int = 16,
                            eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                            clamp_min_distance: float = 0.05, envmap=None, seed: int = 0, crop=None,
                            progress=None, reference: bool = False, visibility: bool = True, pixels=None,
                            aperture: float = 0.0, focus_distance: float | None = None,
                            representatives: int = DEFAULT_REPRESENTATIVES,
                            gather_representatives: int = 1, forest=None) -> RenderResult:
    """Render with multidimensional lightcuts: one product cut per pixel over its ``spp`` gather points.

    Arguments as lightcuts.render.integrator.render_image (``cut_size`` of the result: pairs in the
    pixel's cut; ``max_cut``: pairs per gather point, so the pixel's cut holds at most ``max_cut *
    spp`` pairs, up to MAX_CUT: a config means the same effort per eye ray for both integrators),
    plus aperture : lens radius, world units (0: pinhole, exactly render_image's eye rays); focus_distance : distance of the plane in focus
    along the view axis (None: |look_at - position|); representatives : light representatives per
    light node (1: the tree's own only); gather_representatives : representative gather points per
    gather node, the pair (G, L) using the one of column L mod R (1: the gather tree's own only;
    more decorrelates the pairs' errors at the cost of shadow rays). ``reference=True`` (``trees``
    may be None) sums every gather point with every light instead of cutting: the brute-force
    reference of the same gather points. forest : as render_image's.
    """
    t_start = time.perf_counter()
    camera = camera if camera is not None else scene.camera
    cam = camera_params(camera)
    x0, y0, x1, y1, pix = _check(camera, crop, pixels, spp, eps, max_cut, clamp_min_distance, seed, aperture,
                                 focus_distance, representatives, gather_representatives)
    kc = kernel_caster_of(caster)
    if kc is None:
        raise LightcutsError(f"render.ray_caster: {type(caster).__name__} cannot be called from kernels; "
                             f"use a kernel-callable caster such as 'embree'")
    cdata = kc[0]
    if forest is None:
        forest = build_forest(lights, None if reference else trees)
    spp, max_cut, seed = int(spp), int(max_cut), int(seed)
    pair_budget = min(max_cut * spp, MAX_CUT)  # the pixel's cut: max_cut pairs per gather point
    sx, sy = strata(spp)
    focus = float(focus_distance) if focus_distance is not None else \
        float(np.linalg.norm(np.asarray(camera.look_at) - np.asarray(camera.position)))
    lreps = np.zeros((len(forest.node_f), int(representatives)), np.int64)
    if len(forest.node_f):
        light_representatives(forest.node_f, forest.node_k, int(representatives), seed, lreps)
    clamp_d2 = (clamp_min_distance * scene.diagonal) ** 2 if clamp else 0.0
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
    band = max(1, BAND_PIXELS // max(1, cols * spp // 4))
    f = forest
    for b0 in range(0, rows, band):
        b1 = min(rows, b0 + band)
        on_counter(_render_band, (b1 - b0) * cols, 2 * CHUNK, cdata, cam, seed, spp, sx, sy, float(aperture), focus,
                   x0, x1, y0 + b0, y0 + b1, face_normal, albedo, scene.texture_data(), specular, exponent, emission, f.node_b, f.node_bi,
                   f.roots, f.light_f, f.light_i, lreps, int(gather_representatives), env_pixels, env_rotation,
                   env_scale, float(eps), pair_budget,
                   float(clamp_d2), float(shadow_ray_offset(scene)), bool(visibility), bool(reference),
                   pix[b0:b1] if len(pix) else pix, rgb[b0:b1], cut[b0:b1], rays[b0:b1], lost[b0:b1])
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


def render_multidimensional_reference(scene, caster, lights: dict, camera=None, spp: int = 16, **kwargs):
    """The brute-force reference of :func:`render_multidimensional`: the same gather points, each
    with every light (one shadow ray each). Keyword arguments as render_multidimensional."""
    return render_multidimensional(scene, caster, lights, None, camera=camera, spp=spp, reference=True, **kwargs)


def warm_kernels() -> None:
    """Compile the render kernel into numba's cache by rendering one pixel of the built-in Cornell
    box without lights, as lightcuts.render.integrator.warm_kernels does for the lightcut's kernel
    (lightcuts.commands.warmup runs it in a child process while the command builds the trees)."""
    from lightcuts.accel import make_caster
    from lightcuts.scene.cornell import cornell_box

    scene = cornell_box()
    with make_caster(scene, "embree") as caster:
        render_multidimensional(scene, caster, {}, {}, spp=1, crop=(0, 0, 1, 1))
