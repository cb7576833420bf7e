r"""The stochastic lightcuts integrator (Yuksel, "Stochastic lightcuts", HPG 2019): per eye ray a cut
of at most ``max_cut`` nodes of the light trees, chosen by importance, and one light drawn below each
cut node (lightcuts.integrators.stochastic_cut).

Its light forest (:class:`SampledForest`, made once per lights and trees:
:meth:`StochasticLightcuts.forest`) is the light sampler's records over the render's trees
(lightcuts.integrators.light_sampler) beside the light rows the lightcut shades with
(lightcuts.integrators.forest), and, when the lights stage made the emitting triangles the direct
lights (``lights.direct.source: triangles``), those triangles' corners, with every tree node's box
refitted to the triangles below it. The eye rays and their start are every integrator's
(lightcuts.integrators.camera, eye); random numbers are a hash of (seed, pixel, eye ray, cut slot,
dimension), so an image does not depend on the thread count, the bands, a crop window or the tiles
of a cluster. Clamping (``render.clamp``) applies to indirect VPLs as in the lightcut, off unless
the config sets it. The integrator is :class:`StochasticLightcuts` (registered as
``stochastic-lightcuts``); its brute-force reference is the lightcut's all-lights reference over the
same lights, the sum this estimator is unbiased for (with point lights).

numba caches this module's kernels keyed on this file only: after editing stochastic_cut,
importance, cut, heap, shading, camera, eye or driver, delete
``lightcuts/integrators/__pycache__/*.nb[ic]`` (or touch this file).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import new_scratch
from lightcuts.accel.packets import new_ray_packet
from lightcuts.config.schema import DEFAULT_CLAMP_VPLS
from lightcuts.errors import LightcutsError
from lightcuts.integrators import MAX_CUT
from lightcuts.integrators.camera import CAM_POSITION, CAM_WIDTH, eye_ray
from lightcuts.integrators.continuation import path_key
from lightcuts.integrators.driver import BAND_PIXELS, Band, band_pixel, warm
from lightcuts.integrators.eye import eye_hit
from lightcuts.integrators.forest import build_forest
from lightcuts.integrators.importance import REC_WIDTH
from lightcuts.integrators.light_sampler import build_light_sampler
from lightcuts.integrators.lightcut import Lightcuts
from lightcuts.integrators.registry import INTEGRATORS, Integrator, check_non_negative, clamp_radius
from lightcuts.integrators.shading import facing_normal, reflect
from lightcuts.integrators.stochastic_cut import TG_WIDTH, stochastic_lightcut
from lightcuts.lights.lightset import LIGHT_TYPES
from lightcuts.lights.triangles import leading_triangles, triangle_lights
from lightcuts.parallel import next_task
from lightcuts.registry import Param, declare
from lightcuts.scene.textures import albedo_at

#: Pixels a thread takes at a time.
CHUNK = 32
#: The integrator's default ``max_cut``.
DEFAULT_MAX_CUT = 16


@dataclass
class SampledForest:
    """The lights and trees of a render as the stochastic lightcut reads them.

    sampler : (rec, axis, child, roots, root_type), the light sampler's records
        (lightcuts.integrators.light_sampler; empty without lights)
    light_f, light_i : (L, 8), (L, 3) float64 the light rows and RGB intensities
        (lightcuts.integrators.forest.build_forest), global light ids in LIGHT_TYPES order
    light_tri : (L,) int64 the row of tri_geo of a light that is an emitting triangle, -1 otherwise
    tri_geo : (T, 9) float64 per emitting triangle a corner and the two edges from it
        (lightcuts.integrators.stochastic_cut ``TG_*``)
    n_lights : {type: count}
    vpl_spacing, vpl_count : the indirect VPLs' spacing and number (lightcuts.integrators.forest.Forest),
        from which the clamp radius is made
    """

    sampler: tuple
    light_f: np.ndarray
    light_i: np.ndarray
    light_tri: np.ndarray
    tri_geo: np.ndarray
    n_lights: dict
    vpl_spacing: float = 0.0
    vpl_count: int = 0


def sampled_forest(lights: dict, trees: dict | None, scene) -> SampledForest:
    """The :class:`SampledForest` of ``lights`` ({type: LightSet}) and their ``trees`` ({type:
    LightTree}, any builder's) in ``scene``; LightcutsError naming the set for a mismatch (no trees,
    or triangle lights that are not the scene's emitting triangles)."""
    points = build_forest(lights, None)
    light_tri = np.full(len(points.light_f), -1, np.int64)
    tri_geo = np.zeros((0, TG_WIDTH))
    if not points.n_lights:
        empty = (np.zeros((0, REC_WIDTH), np.float32), np.zeros(0, np.uint32), np.zeros(0, np.int32),
                 np.zeros(0, np.int64), np.zeros(0, np.int64))
        return SampledForest(empty, points.light_f, points.light_i, light_tri, tri_geo, {})
    if trees is None:
        raise LightcutsError("trees: stochastic lightcuts draw their lights through the light trees; none given")
    boxes = {}
    ls = lights.get("oriented")
    n_tri = leading_triangles(ls) if ls is not None else 0
    if n_tri:
        tl = triangle_lights(scene)
        if len(tl.lights) != n_tri or not (np.array_equal(ls.position[:n_tri], tl.lights.position)
                                           and np.array_equal(ls.intensity[:n_tri], tl.lights.intensity)):
            raise LightcutsError(f"lights.oriented: its first {n_tri} lights are not the scene's "
                                 f"{len(tl.lights)} emitting triangles (lights.direct.source: triangles)")
        lo, hi = ls.position.copy(), ls.position.copy()
        lo[:n_tri], hi[:n_tri] = tl.lo, tl.hi
        boxes["oriented"] = (lo, hi)
        base = sum(points.n_lights.get(t, 0) for t in LIGHT_TYPES[:LIGHT_TYPES.index("oriented")])
        light_tri[base:base + n_tri] = np.arange(n_tri)
        corners = scene.triangles[tl.tri]
        tri_geo = np.ascontiguousarray(np.concatenate(
            [corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]], axis=1), np.float64)
    s = build_light_sampler(lights, trees, boxes)
    return SampledForest((s.rec, s.axis, s.child, s.roots, s.root_type), points.light_f, points.light_i, light_tri,
                         tri_geo, dict(points.n_lights), points.vpl_spacing, points.vpl_count)


@njit(cache=True, error_model="numpy")
def _render_pixel(cdata, width, cam, seed, spp, sx, sy, px, py, face_normal, albedo, tex, specular, exponent,
                  emission, rec, axis, child, roots, root_type, light_f, light_i, light_tri, tri_geo, env_pixels,
                  env_rotation, env_scale, max_cut, clamp_d2, ray_offset, visibility, buf, pk, heap, slot_node,
                  slot_est, slot_ratio, free, lane_slot):
    """All eye rays of pixel (px, py): ``(L_r, L_g, L_b, cut, shadow_rays, clamp_lost)``, cut and
    clamp_lost summed over the eye rays (arguments as :func:`_render_band`)."""
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
        p0, p1, p2 = o0 + t * d0, o1 + t * d1, o2 + t * d2
        n0, n1, n2 = facing_normal(face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2], -d0, -d1, -d2)
        r0, r1, r2 = reflect(-d0, -d1, -d2, n0, n1, n2)
        rd0, rd1, rd2 = albedo_at(albedo, tex, prim, p0, p1, p2)
        res = stochastic_lightcut(p0, p1, p2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, specular[prim, 0],
                                  specular[prim, 1], specular[prim, 2], exponent[prim], rec, axis, child, roots,
                                  root_type, light_f, light_i, light_tri, tri_geo, max_cut, clamp_d2, ray_offset,
                                  visibility, cdata, buf, width, pk, heap, slot_node, slot_est, slot_ratio, free,
                                  lane_slot, path_key(seed, pixel, s))
        a0 += res[0]
        a1 += res[1]
        a2 += res[2]
        cut += res[3]
        rays += res[4]
        lost += res[5]
    return a0, a1, a2, cut, rays, lost


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, width, cam, seed, spp, sx, sy, x0, x1, y0, y1, face_normal, albedo, tex, specular, exponent,
                 emission, rec, axis, child, roots, root_type, light_f, light_i, light_tri, tri_geo, env_pixels,
                 env_rotation, env_scale, max_cut, clamp_d2, ray_offset, visibility, pixels, out_rgb, out_cut,
                 out_rays, out_lost, tasks):
    """Pixels [x0, x1) x [y0, y1) (or the listed ``pixels``) into the band's rows, as every band
    kernel (lightcuts.integrators.driver): chunks of CHUNK pixels from the counter ``tasks``.
    out_rgb, out_cut, out_lost : averaged over the pixel's eye rays; out_rays : summed."""
    cols = x1 - x0
    n = (y1 - y0) * cols
    cap = max(max_cut, roots.shape[0]) + 2
    buf = new_scratch(cdata)
    pk = new_ray_packet()
    lane_slot = np.empty(width, np.int64)
    heap = np.empty(cap, np.uint64)
    slot_node = np.empty(cap, np.int64)
    slot_est = np.empty((cap, 3))
    slot_ratio = np.empty(cap)
    free = np.empty(cap, np.int64)
    while True:
        c = next_task(tasks)
        if c * CHUNK >= n:
            break
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            row, col, px, py = band_pixel(i, cols, x0, y0, pixels)
            a0, a1, a2, cut, rays, lost = _render_pixel(
                cdata, width, cam, seed, spp, sx, sy, px, py, face_normal, albedo, tex, specular, exponent, emission,
                rec, axis, child, roots, root_type, light_f, light_i, light_tri, tri_geo, env_pixels, env_rotation,
                env_scale, max_cut, clamp_d2, ray_offset, visibility, buf, pk, heap, slot_node, slot_est,
                slot_ratio, free, lane_slot)
            out_rgb[row, col, 0] = a0 / spp
            out_rgb[row, col, 1] = a1 / spp
            out_rgb[row, col, 2] = a2 / spp
            out_cut[row, col] = cut / spp
            out_rays[row, col] = rays
            out_lost[row, col] = lost / spp


@INTEGRATORS.register("stochastic-lightcuts")
@declare(lens=False, cut_unit="cut nodes per eye ray", kernels="lightcuts.integrators.stochastic", converging=False,
         reference=True, forest=True, triangle_lights=True, params={
             "max_cut": Param(int, DEFAULT_MAX_CUT, lo=1, hi=MAX_CUT,
                              doc="cut nodes per eye ray at most, one light drawn below each (render.max_cut "
                                  "is the lightcut's)")})
class StochasticLightcuts(Integrator):
    """Stochastic lightcuts (Yuksel 2019): per eye ray a cut of at most ``max_cut`` nodes chosen by
    importance and one light drawn below each, unbiased for the sum over the lights.

    Its kernel is this module's. Settings: spp; clamp, clamp_vpls, clamp_min_distance (``render.clamp``)
    as the lightcut's clamping of indirect VPLs, off unless the config sets ``render.clamp.enabled``
    (:meth:`settings`); visibility : False casts no shadow rays; max_cut : its own parameter.
    Renders the emitting triangles themselves when the lights stage made them the direct lights
    (``lights.direct.source: triangles``). Its reference is the lightcut's all-lights reference over
    the same lights. A pinhole camera only.
    """

    def __init__(self, *, spp: int = 1, max_cut: int = DEFAULT_MAX_CUT, clamp: bool = False,
                 clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                 visibility: bool = True):
        super().__init__(spp=spp)
        self.max_cut = self.param("max_cut", max_cut)
        self.clamp = bool(clamp)
        self.clamp_vpls = check_non_negative(clamp_vpls, "render.clamp.vpls")
        self.clamp_min_distance = None if clamp_min_distance is None else \
            check_non_negative(clamp_min_distance, "render.clamp.min_distance")
        self.visibility = bool(visibility)

    @classmethod
    def settings(cls, cfg) -> dict:
        """spp and the clamping: ``render.clamp.enabled`` where the config gives it, else off (the
        lightcut's default is on; off is unbiased for the VPL set and gave the lower error against a
        path tracer: docs/performance.md, "Stochastic lightcuts")."""
        c = cfg.render.clamp
        clamp = c.enabled if "enabled" in c.model_fields_set else False
        return {**super().settings(cfg), "clamp": clamp, "clamp_vpls": c.vpls,
                "clamp_min_distance": c.min_distance if c.mode == "diagonal" else None}

    def clamp_radius(self, scene, forest) -> float:
        """The clamping radius of indirect VPLs, as the lightcut's (lightcuts.integrators.registry.clamp_radius)."""
        return clamp_radius(self.clamp, self.clamp_vpls, self.clamp_min_distance, scene, forest)

    def forest(self, lights: dict, trees: dict | None, scene) -> SampledForest:
        """:func:`sampled_forest` of the lights and trees in ``scene``."""
        return sampled_forest(lights, trees, scene)

    def reference(self) -> Lightcuts:
        """The lightcut's all-lights reference: every light at every eye ray's hit, the same eye rays,
        shading and clamping (the sum this integrator is unbiased for)."""
        return Lightcuts(spp=self.spp, clamp=self.clamp, clamp_vpls=self.clamp_vpls,
                         clamp_min_distance=self.clamp_min_distance, visibility=self.visibility).reference()

    def band_kernel(self, f) -> Band:
        """The kernel's call for the driver's frame ``f`` (lightcuts.integrators.driver)."""
        fo = f.forest
        clamp_d2 = self.clamp_radius(f.scene, fo) ** 2
        head = (*f.caster, f.cam, f.seed, self.spp, f.sx, f.sy)
        tail = (*f.surfaces, *fo.sampler, fo.light_f, fo.light_i, fo.light_tri, fo.tri_geo, *f.env, self.max_cut,
                clamp_d2, f.ray_offset, self.visibility)
        return Band(_render_band, head, tail, max(1, BAND_PIXELS // f.cols), CHUNK)


def warm_kernels() -> None:
    """Compile the band kernel into numba's cache (lightcuts.integrators.driver.warm)."""
    warm(StochasticLightcuts())
