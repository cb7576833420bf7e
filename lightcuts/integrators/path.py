r"""The path integrator's kernel: a path tracer with lightcuts' own BRDF, also the exact-material
reference of ``lightcuts reference --renderer lightcuts``.

Mitsuba 3 has no Phong BSDF and its stand-in reflects more at oblique angles (``lightcuts.mitsuba.export``),
so on glossy scenes it is not the same image. This one computes lightcuts' scene as lightcuts defines
it: the eye rays of ``render.spp`` (lightcuts.integrators.camera) and their start (lightcuts.integrators.eye,
as every integrator's), Lambert plus energy-normalised Phong, two-sided surfaces, one-sided emitters
whose back absorbs. At every vertex: next-event estimation (an emitter triangle drawn by the
integrator's ``light_sampler``: in proportion to its power, all alike, or through a light tree over
the emitting triangles by each node's importance for the vertex, lightcuts.integrators.importance;
a uniform point on it, one shadow ray) and a direction drawn from the BRDF (lightcuts.sampling, as
the continuation draws it), the two combined by multiple importance sampling (power heuristic; a
BRDF-drawn hit on an emitter is weighted by the probability that next-event estimation at the
previous vertex, from the same point and normal, draws that triangle: docs/math.md, "Sampling
light trees"); Russian roulette on the throughput from the fourth vertex, at most
``max_depth`` vertices (:data:`MAX_VERTICES`), the last one taking its direct light from next-event
estimation alone (no BRDF draw follows it). Emitting triangles are the only light it knows: a run
with a sun or an environment map is refused. Random numbers are a hash of (seed, pixel, eye ray,
vertex, dimension): the same image on any thread count. The integrator is :class:`Path`
(registered as ``path``); the image loop is lightcuts.integrators.driver.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import intersect, new_scratch, occluded
from lightcuts.errors import LightcutsError
from lightcuts.hashing import mix64
from lightcuts.lights.indirect import Emitters
from lightcuts.lights.triangles import triangle_lights
from lightcuts.parallel import next_task
from lightcuts.registry import Param, declare
from lightcuts.integrators.camera import CAM_POSITION, eye_ray
from lightcuts.integrators.driver import BAND_PIXELS, Band, warm
from lightcuts.integrators.eye import eye_hit
from lightcuts.integrators.importance import REC_WIDTH, light_pmf, sample_light
from lightcuts.integrators.light_sampler import build_light_sampler
from lightcuts.integrators.registry import INTEGRATORS, Integrator
from lightcuts.integrators.shading import facing_normal, material_term
from lightcuts.sampling import brdf_pdf, reflect, sample_brdf
from lightcuts.scene.textures import albedo_at
from lightcuts.trees.build import build_tree
from lightcuts.trees.spec import TreeSpec, config_tree, tree_spec

#: Vertices of a path at most (Russian roulette ends nearly all paths long before): the default and
#: the bound of the integrator's ``max_depth``.
MAX_VERTICES = 64
_STREAM = np.uint64(0x50415448)  # "PATH"
#: Pixels a thread takes at a time.
CHUNK = 16


# The random numbers of a path vertex (_u's dim): the light sample's three (the light, the point on
# it), the BRDF sample's three, the roulette's. int64, not literal ints, so that _u compiles once.
_U_LIGHT, _U_TRI1, _U_TRI2 = np.int64(0), np.int64(1), np.int64(2)
_U_BRDF1, _U_BRDF2, _U_BRDF3, _U_RR = np.int64(3), np.int64(4), np.int64(5), np.int64(6)


@njit(cache=True, error_model="numpy", forceinline=True)
def _u(key, vertex, dim):
    h = mix64(key ^ mix64(np.uint64(vertex) * np.uint64(8) + np.uint64(dim)))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def _pixel(cdata, buf, cam, seed, spp, sx, sy, px, py, width, face_normal, albedo, tex, specular, exponent, emission,
           env_pixels, env_rotation, env_scale, em_tri, em_cdf, em_p0, em_e1, em_e2, em_prob, tri_light, face_area,
           tree, tree_mode, offset, max_depth):
    """Pixel (px, py)'s radiance averaged over its ``spp`` paths, its path vertices summed over
    them and its next-event shadow rays: ``(r, g, b, vertices, shadow_rays)``. The emitter arguments
    and ``tree``, ``tree_mode``: :class:`PathLights`."""
    rec, axis, child, parent, leaf, roots, root_type = tree
    o0, o1, o2 = cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]
    a0 = a1 = a2 = 0.0
    vertices = 0
    rays = 0
    pixel = np.int64(py) * np.int64(width) + np.int64(px)
    n_em = em_tri.shape[0]
    total = em_cdf[n_em - 1] if n_em > 0 else 0.0
    for s in range(spp):
        key = mix64(mix64(mix64(np.uint64(seed) ^ _STREAM) ^ np.uint64(pixel)) ^ np.uint64(s))
        x0, x1, x2 = o0, o1, o2
        d0, d1, d2 = eye_ray(cam, seed, px, py, s, sx, sy)
        t, prim, e0, e1, e2 = eye_hit(cdata, buf, x0, x1, x2, d0, d1, d2, face_normal, emission, env_pixels,
                                      env_rotation, env_scale)
        a0 += e0
        a1 += e1
        a2 += e2
        if prim < 0:
            continue
        b0 = b1 = b2 = 1.0
        for v in range(max_depth):  # vertex v at the hit (t, prim) of the segment from x along d
            vertices += 1
            last = v == max_depth - 1
            f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
            y0, y1, y2 = x0 + t * d0, x1 + t * d1, x2 + t * d2
            n0, n1, n2 = facing_normal(f0, f1, f2, -d0, -d1, -d2)
            r0, r1, r2 = reflect(-d0, -d1, -d2, n0, n1, n2)
            rd0, rd1, rd2 = albedo_at(albedo, tex, prim, y0, y1, y2)
            rs0, rs1, rs2 = specular[prim, 0], specular[prim, 1], specular[prim, 2]
            e = exponent[prim]
            qd, qs = max(rd0, rd1, rd2), max(rs0, rs1, rs2)
            if qd + qs <= 0.0:
                break
            s0, s1, s2 = y0 + offset * n0, y1 + offset * n1, y2 + offset * n2
            # next-event estimation: an emitter triangle (light k) with probability pk, a uniform point on it
            k, pk = -1, 0.0
            if tree_mode:
                k, pk = sample_light(rec, axis, child, roots, root_type, s0, s1, s2, n0, n1, n2, _u(key, v, _U_LIGHT))
            elif n_em > 0:
                k = min(np.searchsorted(em_cdf, _u(key, v, _U_LIGHT) * total, side="right"), n_em - 1)
                pk = em_prob[k]
            if k >= 0:
                u1, u2 = _u(key, v, _U_TRI1), _u(key, v, _U_TRI2)
                if u1 + u2 > 1.0:
                    u1, u2 = 1.0 - u1, 1.0 - u2
                q = em_tri[k]
                l0 = em_p0[k, 0] + u1 * em_e1[k, 0] + u2 * em_e2[k, 0] - s0
                l1 = em_p0[k, 1] + u1 * em_e1[k, 1] + u2 * em_e2[k, 1] - s1
                l2 = em_p0[k, 2] + u1 * em_e1[k, 2] + u2 * em_e2[k, 2] - s2
                dist = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
                if dist > offset:
                    w0, w1, w2 = l0 / dist, l1 / dist, l2 / dist
                    cos_l = -(face_normal[q, 0] * w0 + face_normal[q, 1] * w1 + face_normal[q, 2] * w2)
                    m0, m1, m2 = material_term(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, e, w0, w1, w2)
                    if cos_l > 0.0 and (m0 > 0.0 or m1 > 0.0 or m2 > 0.0):
                        rays += 1
                        if not occluded(cdata, buf, s0, s1, s2, w0, w1, w2, 0.0, dist - offset):
                            pl = pk / face_area[q] * dist * dist / cos_l
                            if last:
                                c = 1.0 / pl  # no BRDF draw follows to share the emitter with
                            else:
                                pb = brdf_pdf(n0, n1, n2, r0, r1, r2, qd, qs, e, w0, w1, w2)
                                c = pl / (pl * pl + pb * pb)  # the MIS weight over pl
                            a0 += b0 * m0 * emission[q, 0] * c
                            a1 += b1 * m1 * emission[q, 1] * c
                            a2 += b2 * m2 * emission[q, 2] * c
            if last:
                break
            # the next direction, from the BRDF
            w0, w1, w2, t0, t1, t2, pdf_prev, ok = sample_brdf(
                n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, e,
                _u(key, v, _U_BRDF1), _u(key, v, _U_BRDF2), _u(key, v, _U_BRDF3))
            if not ok:
                break
            b0 *= t0
            b1 *= t1
            b2 *= t2
            if v >= 3:
                rr = min(1.0, max(b0, b1, b2))
                if _u(key, v, _U_RR) >= rr:
                    break
                b0 /= rr
                b1 /= rr
                b2 /= rr
            x0, x1, x2 = s0, s1, s2
            d0, d1, d2 = w0, w1, w2
            # the next hit; an emitter's front adds its emission, weighted against next-event estimation
            t, prim = intersect(cdata, buf, x0, x1, x2, d0, d1, d2, 0.0, np.inf)
            if prim < 0:
                break
            cos_f = face_normal[prim, 0] * d0 + face_normal[prim, 1] * d1 + face_normal[prim, 2] * d2
            if emission[prim, 0] > 0.0 or emission[prim, 1] > 0.0 or emission[prim, 2] > 0.0:
                if cos_f >= 0.0:
                    break  # the back of an emitter absorbs
                # the probability that next-event estimation at the previous vertex (the point x, the
                # normal n it used there) drew this triangle
                k, pk = np.int64(tri_light[prim]), 0.0
                if k >= 0:
                    pk = light_pmf(rec, axis, child, parent, leaf, roots, root_type, k, x0, x1, x2, n0, n1, n2) \
                        if tree_mode else em_prob[k]
                w = 1.0
                if pdf_prev > 0.0 and pk > 0.0:
                    pl = pk / face_area[prim] * t * t / -cos_f
                    w = pdf_prev * pdf_prev / (pdf_prev * pdf_prev + pl * pl)
                a0 += b0 * emission[prim, 0] * w
                a1 += b1 * emission[prim, 1] * w
                a2 += b2 * emission[prim, 2] * w
    return a0 / spp, a1 / spp, a2 / spp, vertices, rays


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, cam, seed, spp, sx, sy, x0, x1, y0, y1, width, face_normal, albedo, tex, specular, exponent,
                 emission, env_pixels, env_rotation, env_scale, em_tri, em_cdf, em_p0, em_e1, em_e2, em_prob,
                 tri_light, face_area, tree, tree_mode, offset, max_depth, pixels, out_rgb, out_cut, out_rays, out_lost,
                 tasks):
    """Pixels [x0, x1) x [y0, y1) (or the listed ``pixels``) into the band's rows, as every band
    kernel (lightcuts.integrators.driver); out_cut : path vertices per eye ray; out_lost stays 0."""
    buf = new_scratch(cdata)
    cols = x1 - x0
    n = (y1 - y0) * cols
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
            r, g, b, vertices, rays = _pixel(cdata, buf, cam, seed, spp, sx, sy, px, py, width, face_normal, albedo,
                                             tex, specular, exponent, emission, env_pixels, env_rotation, env_scale,
                                             em_tri, em_cdf, em_p0, em_e1, em_e2, em_prob, tri_light, face_area,
                                             tree, tree_mode, offset, max_depth)
            out_rgb[row, col, 0] = r
            out_rgb[row, col, 1] = g
            out_rgb[row, col, 2] = b
            out_cut[row, col] = vertices / spp
            out_rays[row, col] = rays


#: How next-event estimation draws an emitting triangle (the integrator's ``light_sampler``).
LIGHT_SAMPLERS = ("power", "uniform", "tree")
#: The seed of the tree over the emitting triangles (for a builder that draws): one tree per scene and
#: builder, the same for every pass and tile.
TREE_SEED = 0


class PathLights(NamedTuple):
    """The scene's emitting triangles as next-event estimation draws them (:meth:`Path.forest`), made
    once per render and kept by a cluster's worker for all its tiles.

    kernel : the kernel's emitter arguments: em_tri (N,) int64 the triangle of light k (the order of
        lightcuts.lights.triangles.triangle_lights); em_cdf (N,) float64 the running sum of the draw
        weights (power: ``A * luminance(Le)``; uniform: 1); em_p0, em_e1, em_e2 (N, 3) a corner and the
        two edges from it; em_prob (N,) the CDF's probability of light k; tri_light (F,) int32 the light
        of every triangle, -1 for none; face_area (F,); tree, the light sampler's record arrays
        (lightcuts.integrators.light_sampler.LightSampler.arrays; empty unless drawn through a tree);
        tree_mode, 1 to draw through the tree, 0 by the CDF
    record : report.json's ``light_sampler``: ``type``, ``lights`` (N), ``build_seconds``,
        ``bytes_per_light`` (the sampling structure's bytes over N) and for a tree its ``builder``,
        ``metric`` and ``c``
    n_lights : {"oriented": N}, the triangles as the tree's light set
    """

    kernel: tuple
    record: dict
    n_lights: dict


def _empty_tree() -> tuple:
    """The light sampler's arrays with no node (the kernel's ``tree`` when it draws by the CDF)."""
    return (np.zeros((0, REC_WIDTH), np.float32), np.zeros(0, np.uint32), np.zeros(0, np.int32),
            np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.int64), np.zeros(0, np.int64))


def path_lights(scene, light_sampler: str = "power", tree: TreeSpec | None = None) -> PathLights:
    """The :class:`PathLights` of ``scene`` for the sampler ``light_sampler`` (:data:`LIGHT_SAMPLERS`);
    ``tree``: the builder of a ``tree`` sampler (default the schema's). LightcutsError naming the key
    for a tree over a scene without emitting triangles or more than the builder takes."""
    t0 = time.perf_counter()
    e = Emitters(scene)
    cdf = np.ascontiguousarray(e.cdf if light_sampler == "power" else np.arange(1.0, e.n + 1.0), np.float64)
    em_prob = np.diff(cdf, prepend=0.0) / cdf[-1] if e.n else np.zeros(0)
    tri_light = np.full(scene.n_faces, -1, np.int32)
    tri_light[e.tri] = np.arange(e.n, dtype=np.int32)
    record = {"type": light_sampler, "lights": e.n}
    arrays, mode, nbytes = _empty_tree(), 0, cdf.nbytes + em_prob.nbytes
    if light_sampler == "tree":
        if e.n == 0:
            raise LightcutsError("render.integrator.light_sampler: tree: the scene has no emitting triangles "
                                 "to build a light tree over")
        spec = tree if tree is not None else tree_spec()
        spec.check_size(e.n)
        t = triangle_lights(scene)
        lt = build_tree(t.lights, spec, seed=TREE_SEED)
        sampler = build_light_sampler({"oriented": t.lights}, {"oriented": lt}, {"oriented": (t.lo, t.hi)})
        arrays, mode, nbytes = sampler.arrays, 1, sampler.nbytes
        record.update(builder=spec.name, metric=lt.meta.get("metric"), c=lt.meta.get("c"))
    kernel = (e.tri, cdf, e.p0, e.e1, e.e2, em_prob, tri_light, np.ascontiguousarray(scene.face_areas, np.float64),
              arrays, mode)
    record.update(build_seconds=time.perf_counter() - t0, bytes_per_light=nbytes / e.n if e.n else 0.0)
    return PathLights(kernel, record, {"oriented": e.n})


@INTEGRATORS.register("path")
@declare(lens=False, cut_unit="path vertices per eye ray", kernels="lightcuts.integrators.path", reference=False,
         forest=False, params={
             "max_depth": Param(int, MAX_VERTICES, lo=1, hi=MAX_VERTICES,
                                doc="path vertices at most (1: the emitters seen and their direct light)"),
             "light_sampler": Param(str, "power", choices=LIGHT_SAMPLERS,
                                    doc="how next-event estimation draws an emitting triangle: power (in proportion "
                                        "to its power), uniform (all alike) or tree (through a light tree of "
                                        "tree.builder, by each node's importance for the shading point)")})
class Path(Integrator):
    """A path tracer with lightcuts' own BRDF, lit by the scene's emitting triangles: the exact
    image, without the config's lights or trees; its cut counts path vertices per eye ray.

    Its kernel is this module's: next-event estimation and BRDF draws combined by multiple
    importance sampling, Russian roulette, at most ``max_depth`` vertices per path. Next-event
    estimation draws an emitting triangle by ``light_sampler``; with ``tree`` through a light tree
    over the emitting triangles built by the config's builder (``tree``: its TreeSpec), once per
    render (:meth:`forest`). The emitting triangles are its only lights, so a run with a sun or an
    environment map is refused; its RenderResult's ``shadow_rays`` are its next-event rays. It is
    unbiased, its own reference: it has no brute-force counterpart.
    """

    def __init__(self, *, spp: int = 1, max_depth: int = MAX_VERTICES, light_sampler: str = "power",
                 tree: TreeSpec | None = None):
        super().__init__(spp=spp)
        self.max_depth = self.max_cut = self.param("max_depth", max_depth)
        self.light_sampler = self.param("light_sampler", light_sampler)
        self.tree = tree

    @classmethod
    def settings(cls, cfg) -> dict:
        for key, value in (("lights.sun", cfg.lights.sun), ("lights.environment", cfg.lights.environment)):
            if value is not None:
                raise LightcutsError(f"{key}: integrator 'path' renders the scene's emitting triangles only; "
                                     f"leave {key} out or use render.integrator: lightcuts")
        return {**super().settings(cfg), "tree": tree_spec(*config_tree(cfg.tree))}

    def forest(self, lights: dict, trees: dict | None, scene):
        """The scene's emitting triangles as its next-event estimation draws them (:class:`PathLights`;
        the config's lights and trees are not used)."""
        return path_lights(scene, self.light_sampler, self.tree)

    def sampler_record(self, forest) -> dict:
        """The :class:`PathLights`' record: its sampler, emitting triangles, build seconds, bytes."""
        return dict(forest.record)

    def band_kernel(self, f) -> Band:
        """The path kernel's call for the driver's frame ``f`` (lightcuts.integrators.driver): the scene's
        emitting triangles as next-event estimation draws them (``f.forest``, a :class:`PathLights`)."""
        if f.env[0].shape[0] > 0:
            raise LightcutsError("envmap: integrator 'path' renders the scene's emitting triangles only (no "
                                 "environment map)")
        head = (f.caster.data, f.cam, f.seed, self.spp, f.sx, f.sy)
        tail = (int(f.camera.width), *f.surfaces, *f.env, *f.forest.kernel, f.ray_offset, self.max_depth)
        return Band(_render_band, head, tail, max(1, BAND_PIXELS // f.cols), CHUNK)


def path_trace(scene, caster, camera=None, spp: int = 64, seed: int = 0, crop=None, max_depth: int = MAX_VERTICES,
               light_sampler: str = "power", tree: TreeSpec | None = None) -> tuple[np.ndarray, float]:
    """lightcuts' scene path-traced with its own BRDF (the :class:`Path` integrator in one call):
    ((H, W, 3) float32 linear RGB of the camera's image or ``crop`` window, wall seconds).
    ``caster``: a kernel-callable ray caster over the scene; ``light_sampler``, ``tree``: as
    :class:`Path`'s; LightcutsError for bad arguments."""
    result = Path(spp=spp, max_depth=max_depth, light_sampler=light_sampler, tree=tree).render(
        scene, caster, {}, None, camera=camera, seed=seed, crop=crop)
    return result.image, result.seconds


def warm_kernels() -> None:
    """Compile the band kernel into numba's cache (lightcuts.integrators.driver.warm), and the light
    sampler's construction with the default builder."""
    warm(Path())
    warm(Path(light_sampler="tree"))
