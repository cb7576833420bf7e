r"""The multidimensional integrator's kernel (or its brute-force reference's): a product cut per pixel.

Per pixel: its gather points (lightcuts.integrators.multidim.gather: ``spp`` eye rays over the pixel and
the lens), its gather tree (gather_tree), then one product cut (product_cut) over the gather tree
and the light forest, or, for the reference, every gather point with every light. The integrator
is :class:`Multidimensional` (registered as ``multidimensional``); the image loop around the band
kernel, shared with the other integrators, is lightcuts.integrators.driver (every random number a hash of
the seed and the pixel, so images do not depend on the thread count). The result's ``cut_size`` is the number of
(gather, light) pairs in each pixel's cut (for the reference: gather points x lights).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import new_scratch
from lightcuts.accel.packets import new_ray_packet
from lightcuts.config.schema import DEFAULT_CLAMP_VPLS
from lightcuts.errors import LightcutsError
from lightcuts.parallel import next_task
from lightcuts.registry import Param, declare
from lightcuts.integrators import MAX_CUT
from lightcuts.integrators.camera import CAM_WIDTH
from lightcuts.integrators.driver import BAND_PIXELS, Band, RenderResult, band_pixel, warm
from lightcuts.integrators.multidim.gather import GP_WIDTH, pixel_gather
from lightcuts.integrators.multidim.gather_check import GC_WIDTH, SK_WIDTH
from lightcuts.integrators.multidim.gather_tree import GK_WIDTH, GN_WIDTH, build_gather_tree, gather_representatives
from lightcuts.integrators.multidim.product_cut import all_pairs, light_representatives, product_cut
from lightcuts.integrators.registry import INTEGRATORS, CutIntegrator, check_non_negative

#: Light representatives per light node (1: the tree's own only): the integrator's default.
DEFAULT_REPRESENTATIVES = 4
#: Gather points a thread takes at a time (pixels x gather points; at least one pixel): the cost of a
#: pixel grows with its gather points and varies with its cut, and threads wait for each other at
#: the end of every band of rows, so tasks stay small.
TASK_GATHER_POINTS = 128
#: Gather-representative columns per gather node: the integrator's default (one per point at 16 spp).
DEFAULT_GATHER_REPRESENTATIVES = 16


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, width, cam, seed, spp, sx, sy, aperture, focus, x0, x1, y0, y1, face_normal, albedo, tex,
                 specular, exponent, emission, node_b, node_bi, roots, light_f, light_i, lreps, g_count, env_pixels,
                 env_rotation, env_scale, eps, max_cut, clamp_d2, ray_offset, visibility, reference, chunk, pixels,
                 out_rgb, out_cut, out_rays, out_lost, tasks):
    """Pixels [x0, x1) x [y0, y1) (or the listed ``pixels``) into the band's rows, as every band
    kernel (lightcuts.integrators.driver), ``chunk`` pixels a task; cdata, width : the caster's data
    and packet width (lightcuts.accel.base.KernelCaster); out_cut : pairs in the cut per pixel."""
    cols = x1 - x0
    n = (y1 - y0) * cols
    cap = max(max_cut, roots.shape[0]) + 2
    buf = new_scratch(cdata)
    pk = new_ray_packet()
    lane_slot = np.empty(width, np.int64)
    gp = np.empty((spp, GP_WIDTH))
    gn = np.empty((2 * spp, GN_WIDTH))
    gk = np.empty((2 * spp, GK_WIDTH), np.int64)
    greps = np.empty((2 * spp, g_count), np.int64)
    idx = np.empty(spp, np.int64)
    stack = np.empty((2 * spp, 3), np.int64)
    heap = np.zeros(cap, np.uint64)
    slot_k = np.empty((cap, SK_WIDTH), np.int64)
    gcheck = np.empty((2 * spp, GC_WIDTH), np.int64)
    slot_mgv = np.empty((cap, 3))
    slot_ratio = np.empty(cap)
    slot_vis = np.empty(cap, np.bool_)
    image_width = np.int64(cam[CAM_WIDTH])
    while True:
        c = next_task(tasks)
        if c * chunk >= n:
            break
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            row, col, px, py = band_pixel(i, cols, x0, y0, pixels)
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
                    root = build_gather_tree(gp, ng, gn, gk, idx, stack, seed, np.int64(py) * image_width + px)
                    gather_representatives(gn, gk, idx, ng, seed, np.int64(py) * image_width + px, greps)
                    r0, r1, r2, pairs, rays, lost = product_cut(
                        gp, gn, gk, idx, greps, root, node_b, node_bi, roots, light_f, lreps, eps, max_cut, clamp_d2,
                        ray_offset, visibility, cdata, buf, width, pk, lane_slot, heap, slot_k, slot_mgv, slot_ratio,
                        slot_vis, gcheck)
                a0 += r0
                a1 += r1
                a2 += r2
            out_rgb[row, col, 0] = a0
            out_rgb[row, col, 1] = a1
            out_rgb[row, col, 2] = a2
            out_cut[row, col] = pairs
            out_rays[row, col] = rays
            out_lost[row, col] = lost


@INTEGRATORS.register("multidimensional")
@declare(lens=True, cut_unit="pairs per pixel", cuts_per="pixel", kernels="lightcuts.integrators.multidim.render", reference=True,
         forest=True, params={
             "representatives": Param(int, DEFAULT_REPRESENTATIVES, lo=1, hi=64,
                                      doc="light representatives per light node (1: the tree's own only)"),
             "gather_representatives": Param(int, DEFAULT_GATHER_REPRESENTATIVES, lo=1, hi=64,
                                             doc="representative gather points per gather node, taken in turn "
                                                 "by its pairs (1: one point per node)")})
class Multidimensional(CutIntegrator):
    """One cut per pixel through (gather tree) x (light trees) (Walter et al. 2006); its cut counts
    (gather point, light) pairs per pixel.

    Its kernel is this module's. Settings as :class:`CutIntegrator` (``max_cut``: pairs per gather
    point, so the pixel's cut holds at most ``max_cut * spp`` pairs, up to MAX_CUT: a config means the
    same effort per eye ray for both cut integrators), plus aperture : lens radius, world units (0:
    pinhole, exactly the lightcuts integrator's eye rays); focus_distance : distance of the plane in
    focus along the view axis (None: |look_at - position|); representatives : light representatives per
    light node (1: the tree's own only); gather_representatives : representative gather points
    (columns) per gather node, stratified over its points and taken in turn by the pairs that hold
    it (1: one point per node; docs/math.md, "Gather representatives"); all_pairs : the brute-force
    reference instead (every gather point with every light).
    """

    def __init__(self, *, spp: int = 16, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                 visibility: bool = True, aperture: float = 0.0,
                 focus_distance: float | None = None, representatives: int = DEFAULT_REPRESENTATIVES,
                 gather_representatives: int = DEFAULT_GATHER_REPRESENTATIVES, all_pairs: bool = False):
        super().__init__(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_vpls=clamp_vpls,
                         clamp_min_distance=clamp_min_distance, visibility=visibility)
        self.aperture = check_non_negative(aperture, "camera.aperture")
        if focus_distance is not None and not (focus_distance > 0 and math.isfinite(focus_distance)):
            raise LightcutsError(f"camera.focus_distance: {focus_distance} must be a finite number > 0")
        self.focus_distance = None if focus_distance is None else float(focus_distance)
        self.representatives = self.param("representatives", representatives)
        self.gather_representatives = self.param("gather_representatives", gather_representatives)
        self.brute_force = bool(all_pairs)

    @classmethod
    def settings(cls, cfg) -> dict:
        return {**super().settings(cfg), "aperture": cfg.camera.aperture, "focus_distance": cfg.camera.focus_distance}

    def reference(self) -> "Multidimensional":
        """Every gather point of every pixel with every light (one shadow ray each): the same gather
        points."""
        return Multidimensional(spp=self.spp, eps=self.eps, max_cut=self.max_cut, **self.clamp_settings(),
                                visibility=self.visibility,
                                aperture=self.aperture, focus_distance=self.focus_distance,
                                representatives=self.representatives,
                                gather_representatives=self.gather_representatives, all_pairs=True)

    def band_kernel(self, f) -> Band:
        """The product cut kernel's call for the driver's frame ``f`` (lightcuts.integrators.driver): the
        light representatives of every forest node drawn, the pixel's pair budget (``max_cut`` per
        gather point, up to MAX_CUT) and the focus distance set."""
        fo, spp = f.forest, self.spp
        pair_budget = min(self.max_cut * spp, MAX_CUT)
        focus = self.focus_distance if self.focus_distance is not None else \
            float(np.linalg.norm(np.asarray(f.camera.look_at) - np.asarray(f.camera.position)))
        lreps = np.zeros((len(fo.node_f), self.representatives), np.int64)
        if len(fo.node_f):
            light_representatives(fo.node_f, fo.node_k, self.representatives, f.seed, lreps)
        head = (*f.caster, f.cam, f.seed, spp, f.sx, f.sy, self.aperture, focus)
        chunk = max(1, TASK_GATHER_POINTS // spp)
        tail = (*f.surfaces, fo.node_b, fo.node_bi, fo.roots, fo.light_f, fo.light_i, lreps,
                self.gather_representatives, *f.env, self.eps, pair_budget, self.clamp_d2(f.scene, fo), f.ray_offset,
                self.visibility, self.brute_force, np.int64(chunk))
        return Band(_render_band, head, tail, max(1, BAND_PIXELS // max(1, f.cols * spp // 4)), chunk)


def render_multidimensional(scene, caster, lights: dict, trees: dict | None, camera=None, spp: int = 16,
                            eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                            clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                            envmap=None, seed: int = 0, crop=None,
                            progress=None, reference: bool = False, visibility: bool = True, pixels=None,
                            aperture: float = 0.0, focus_distance: float | None = None,
                            representatives: int = DEFAULT_REPRESENTATIVES,
                            gather_representatives: int = DEFAULT_GATHER_REPRESENTATIVES,
                            forest=None) -> RenderResult:
    """The :class:`Multidimensional` integrator of these settings (with ``reference=True``, its
    reference: every gather point with every light; ``trees`` may be None) rendering in one call;
    arguments as the integrator's constructor and :meth:`~lightcuts.integrators.registry.Integrator.render`."""
    integ = Multidimensional(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_vpls=clamp_vpls,
                             clamp_min_distance=clamp_min_distance, visibility=visibility, aperture=aperture,
                             focus_distance=focus_distance,
                             representatives=representatives, gather_representatives=gather_representatives)
    if reference:
        integ = integ.reference()
    return integ.render(scene, caster, lights, trees, forest=forest, camera=camera, envmap=envmap, seed=seed,
                        crop=crop, pixels=pixels, progress=progress)


def render_multidimensional_reference(scene, caster, lights: dict, camera=None, spp: int = 16, **kwargs):
    """The brute-force reference of :func:`render_multidimensional`: the same gather points, each
    with every light (one shadow ray each). Keyword arguments as render_multidimensional."""
    return render_multidimensional(scene, caster, lights, None, camera=camera, spp=spp, reference=True, **kwargs)


def warm_kernels() -> None:
    """Compile the band kernel into numba's cache (lightcuts.integrators.driver.warm)."""
    warm(Multidimensional(spp=1))
