r"""The lightcuts integrator's kernel (or its brute-force reference's): a lightcut per eye ray.

Per eye ray (lightcuts.integrators.camera: ``spp`` stratified jittered samples per pixel) the eye-ray
start (lightcuts.integrators.eye: the environment on a miss, an emitter front's emission, black behind
an emitter); any hit to shade is shaded by a lightcut through all trees (lightcuts.integrators.cut) or,
for the reference, by every light (lightcuts.integrators.reference); surfaces are two-sided. The trees
and lights are flattened into one forest (lightcuts.integrators.forest.build_forest), so one kernel
specialisation serves every light type and the reference. The integrator is :class:`Lightcuts`
(registered as ``lightcuts``); the image loop around the band kernel is lightcuts.integrators.driver.

Shadow rays start ``ray_offset`` (lightcuts.integrators.driver.shadow_ray_offset, world units) off the
surface along the shading normal (on the light's side) and stop as far short of a light at a point
(lights sit on surfaces); rays to directional lights are unbounded. Clamping applies to indirect
VPLs in the estimate and the bound alike (docs/math.md, "Clamping").

The kernel compiles once per kernel caster (the tag in the caster's data, lightcuts.accel.kernel_api)
and calls that caster's device functions directly. numba caches each module's kernels keyed on that
module's source file only: after editing bounds, shading, forest, heap, cut, reference, camera, eye,
driver or a caster's device functions (lightcuts/accel), delete ``lightcuts/integrators/__pycache__/*.nb[ic]``
(or touch this file), or a cached kernel built from the old code may still run.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import new_scratch
from lightcuts.accel.packets import new_ray_packet
from lightcuts.config.schema import DEFAULT_CLAMP_VPLS
from lightcuts.errors import LightcutsError
from lightcuts.hashing import mix64
from lightcuts.limits import MAX_CONTINUATION_RAYS
from lightcuts.parallel import next_task
from lightcuts.registry import declare
from lightcuts.integrators.camera import CAM_POSITION, CAM_WIDTH, eye_ray
from lightcuts.integrators.continuation import continuation, path_key
from lightcuts.integrators.cut import lightcut, luminance
from lightcuts.integrators.driver import BAND_PIXELS, Band, RenderResult, band_pixel, warm
from lightcuts.integrators.eye import eye_hit
from lightcuts.integrators.reference import all_lights
from lightcuts.integrators.registry import INTEGRATORS, CutIntegrator, check_count
from lightcuts.integrators.shading import facing_normal, reflect
from lightcuts.scene.textures import albedo_at

#: Pixels a thread takes at a time.
CHUNK = 32


@njit(cache=True, error_model="numpy")
def _render_pixel(cdata, width, cam, seed, spp, sx, sy, px, py,
                  face_normal, albedo, tex, specular, exponent, emission, node_b, node_bi, roots, light_f, light_i,
                  env_pixels, env_rotation, env_scale, eps, max_cut, clamp_d2, ray_offset, visibility, reference,
                  compensation, stochastic, buf, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot):
    """All eye rays of pixel (px, py): returns (L_r, L_g, L_b, cut, shadow_rays, clamp_lost), cut
    and clamp_lost summed over the eye rays. An empty env_pixels (0, 0, 3) means no environment.
    cdata, width : the caster's data and packet width (lightcuts.accel.base.KernelCaster); buf : its
    scratch. compensation : the eye-path continuations (lightcuts.integrators.continuation) averaged per
    eye ray (0: none), whose rays count as shadow rays; stochastic : stochastic representatives (lightcuts.integrators.cut)."""
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
        t, prim, e0, e1, e2 = eye_hit(cdata, buf, o0, o1, o2, d0, d1, d2, face_normal, emission, env_pixels,
                                      env_rotation, env_scale)
        a0 += e0
        a1 += e1
        a2 += e2
        if prim < 0:
            continue
        f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
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
            row, col, px, py = band_pixel(i, cols, x0, y0, pixels)
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


@INTEGRATORS.register("lightcuts")
@declare(lens=False, cut_unit="light nodes per eye ray", cuts_per="eye ray", kernels="lightcuts.integrators.lightcut", converging=True,
         reference=True, forest=True)
class Lightcuts(CutIntegrator):
    """A lightcut per eye ray through every light tree (Walter et al. 2005).

    Its kernel is this module's. Settings as :class:`CutIntegrator`, plus compensation : add the light
    the VPLs lose to clamping and to glossy surfaces by a continuation of the eye path
    (lightcuts.integrators.continuation; the VPLs must come from glossy particle paths), whose rays count as
    shadow rays; representatives : ``fixed`` (the trees') or ``stochastic`` (one light drawn per cut
    node and eye ray, lightcuts.integrators.cut.stochastic_estimate); continuation_rays : with compensation,
    the continuations averaged per eye ray (1 to MAX_CONTINUATION_RAYS); all_lights : the brute-force
    reference instead (every light at every hit, one shadow ray each, no trees). A pinhole camera only
    (the plan refuses an aperture).
    """

    def __init__(self, *, spp: int = 1, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                 visibility: bool = True, compensation: bool = False, representatives: str = "fixed",
                 continuation_rays: int = 1, all_lights: bool = False):
        super().__init__(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_vpls=clamp_vpls,
                         clamp_min_distance=clamp_min_distance, visibility=visibility)
        self.continuation_rays = check_count(continuation_rays, "render.continuation_rays", MAX_CONTINUATION_RAYS)
        if representatives not in ("fixed", "stochastic"):
            raise LightcutsError(f"render.representatives: {representatives!r} must be 'fixed' or 'stochastic'")
        self.compensation = bool(compensation)
        self.representatives = representatives
        self.brute_force = bool(all_lights)

    @classmethod
    def settings(cls, cfg) -> dict:
        r = cfg.render
        return {**super().settings(cfg), "compensation": r.compensation, "representatives": r.representatives,
                "continuation_rays": r.continuation_rays}

    def reference(self) -> "Lightcuts":
        """Every light at every eye ray's hit, the same eye rays and shading (no trees, eps 0, no
        compensation)."""
        return Lightcuts(spp=self.spp, eps=0.0, max_cut=1, **self.clamp_settings(), visibility=self.visibility,
                         all_lights=True)

    def band_kernel(self, f) -> Band:
        """The lightcut kernel's call for the driver's frame ``f`` (lightcuts.integrators.driver)."""
        fo, reference = f.forest, self.brute_force
        head = (*f.caster, f.cam, f.seed, self.spp, f.sx, f.sy)
        tail = (*f.surfaces, fo.node_b, fo.node_bi, fo.roots, fo.light_f, fo.light_i, *f.env, float(self.eps),
                self.max_cut, self.clamp_d2(f.scene, fo), f.ray_offset, self.visibility, reference,
                self.continuation_rays if self.compensation and not reference else 0,
                self.representatives == "stochastic" and not reference)
        return Band(_render_band, head, tail, max(1, BAND_PIXELS // f.cols), CHUNK)


def render_image(scene, caster, lights: dict, trees: dict, camera=None, spp: int = 1, eps: float = 0.02,
                 max_cut: int = 1000, clamp: bool = True, clamp_vpls: float = DEFAULT_CLAMP_VPLS,
                 clamp_min_distance: float | None = None, envmap=None, seed: int = 0, crop=None,
                 progress: Callable[[int], object] | None = None,
                 reference: bool = False, visibility: bool = True, pixels=None, compensation: bool = False,
                 representatives: str = "fixed", continuation_rays: int = 1, forest=None) -> RenderResult:
    """The :class:`Lightcuts` integrator of these settings (with ``reference=True``, its reference:
    every light at every hit) rendering in one call; arguments as the integrator's constructor and
    :meth:`~lightcuts.integrators.registry.Integrator.render`."""
    integ = Lightcuts(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_vpls=clamp_vpls,
                      clamp_min_distance=clamp_min_distance, visibility=visibility, compensation=compensation,
                      representatives=representatives, continuation_rays=continuation_rays)
    if reference:
        integ = integ.reference()
    return integ.render(scene, caster, lights, trees, forest=forest, camera=camera, envmap=envmap, seed=seed,
                        crop=crop, pixels=pixels, progress=progress)


def render_reference(scene, caster, lights: dict, camera=None, spp: int = 1, clamp: bool = True,
                     clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                     envmap=None, seed: int = 0, crop=None, progress: Callable[[int], object] | None = None,
                     visibility: bool = True, pixels=None, forest=None) -> RenderResult:
    """The brute-force reference of :func:`render_image`: the same eye rays and shading, every light
    at every hit with one shadow ray each (no trees)."""
    return render_image(scene, caster, lights, None, camera, spp, clamp=clamp, clamp_vpls=clamp_vpls,
                        clamp_min_distance=clamp_min_distance, envmap=envmap, seed=seed, crop=crop,
                        progress=progress, reference=True, visibility=visibility, pixels=pixels, forest=forest)


def warm_kernels() -> None:
    """Compile the band kernel into numba's cache (lightcuts.integrators.driver.warm)."""
    warm(Lightcuts())
