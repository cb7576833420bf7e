r"""The path integrator's kernel: a path tracer with lightcuts' own BRDF, also the exact-material
reference of ``lightcuts reference --renderer lightcuts``.

Mitsuba 3 has no Phong BSDF and its stand-in reflects more at oblique angles (``lightcuts.mitsuba.export``),
so on glossy scenes it is not the same image. This one computes lightcuts' scene as lightcuts defines
it: the eye rays of ``render.spp`` (lightcuts.integrators.camera) and their start (lightcuts.integrators.eye,
as every integrator's), Lambert plus energy-normalised Phong, two-sided surfaces, one-sided emitters
whose back absorbs. At every vertex: next-event estimation (an emitter triangle drawn in proportion
to its power, a uniform point on it, one shadow ray) and a direction drawn from the BRDF
(lightcuts.sampling, as the continuation draws it), the two combined by multiple importance
sampling (power heuristic); Russian roulette on the throughput from the fourth vertex, at most
``max_depth`` vertices (:data:`MAX_VERTICES`), the last one taking its direct light from next-event
estimation alone (no BRDF draw follows it). Emitting triangles are the only light it knows: a run
with a sun or an environment map is refused. Random numbers are a hash of (seed, pixel, eye ray,
vertex, dimension): the same image on any thread count. The integrator is :class:`Path`
(registered as ``path``); the image loop is lightcuts.integrators.driver.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import intersect, new_scratch, occluded
from lightcuts.errors import LightcutsError
from lightcuts.hashing import mix64
from lightcuts.lights.indirect import Emitters
from lightcuts.parallel import next_task
from lightcuts.registry import Param, declare
from lightcuts.integrators.camera import CAM_POSITION, eye_ray
from lightcuts.integrators.driver import BAND_PIXELS, Band, warm
from lightcuts.integrators.eye import eye_hit
from lightcuts.integrators.registry import INTEGRATORS, Integrator
from lightcuts.integrators.shading import facing_normal, material_term
from lightcuts.sampling import brdf_pdf, reflect, sample_brdf
from lightcuts.scene.textures import albedo_at

#: Vertices of a path at most (Russian roulette ends nearly all paths long before): the default and
#: the bound of the integrator's ``max_depth``.
MAX_VERTICES = 64
_STREAM = np.uint64(0x50415448)  # "PATH"
#: Pixels a thread takes at a time.
CHUNK = 16


@njit(cache=True, error_model="numpy", forceinline=True)
def _u(key, vertex, dim):
    h = mix64(key ^ mix64(np.uint64(vertex) * np.uint64(8) + np.uint64(dim)))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, error_model="numpy")
def _pixel(cdata, buf, cam, seed, spp, sx, sy, px, py, width, face_normal, albedo, tex, specular, exponent, emission,
           env_pixels, env_rotation, env_scale, em_tri, em_cdf, em_p0, em_e1, em_e2, tri_prob, face_area, offset,
           max_depth):
    """Pixel (px, py)'s radiance averaged over its ``spp`` paths, its path vertices summed over
    them and its next-event shadow rays: ``(r, g, b, vertices, shadow_rays)``."""
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
            # next-event estimation: an emitter triangle by power, a uniform point on it
            if n_em > 0:
                k = np.searchsorted(em_cdf, _u(key, v, 0) * total, side="right")
                k = min(k, n_em - 1)
                u1, u2 = _u(key, v, 1), _u(key, v, 2)
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
                            pl = tri_prob[q] / face_area[q] * dist * dist / cos_l
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
            w0, w1, w2, t0, t1, t2, pdf_prev, ok = sample_brdf(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1,
                                                               rs2, e, _u(key, v, 3), _u(key, v, 4), _u(key, v, 5))
            if not ok:
                break
            b0 *= t0
            b1 *= t1
            b2 *= t2
            if v >= 3:
                rr = min(1.0, max(b0, b1, b2))
                if _u(key, v, 6) >= rr:
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
                w = 1.0
                if pdf_prev > 0.0 and tri_prob[prim] > 0.0:
                    pl = tri_prob[prim] / face_area[prim] * t * t / -cos_f
                    w = pdf_prev * pdf_prev / (pdf_prev * pdf_prev + pl * pl)
                a0 += b0 * emission[prim, 0] * w
                a1 += b1 * emission[prim, 1] * w
                a2 += b2 * emission[prim, 2] * w
    return a0 / spp, a1 / spp, a2 / spp, vertices, rays


@njit(cache=True, nogil=True, error_model="numpy")
def _render_band(cdata, cam, seed, spp, sx, sy, x0, x1, y0, y1, width, face_normal, albedo, tex, specular, exponent,
                 emission, env_pixels, env_rotation, env_scale, em_tri, em_cdf, em_p0, em_e1, em_e2, tri_prob,
                 face_area, offset, max_depth, pixels, out_rgb, out_cut, out_rays, out_lost, tasks):
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
                                             em_tri, em_cdf, em_p0, em_e1, em_e2, tri_prob, face_area, offset,
                                             max_depth)
            out_rgb[row, col, 0] = r
            out_rgb[row, col, 1] = g
            out_rgb[row, col, 2] = b
            out_cut[row, col] = vertices / spp
            out_rays[row, col] = rays


@INTEGRATORS.register("path")
@declare(lens=False, cut_unit="path vertices per eye ray", kernels="lightcuts.integrators.path", reference=False,
         forest=False, params={
             "max_depth": Param(int, MAX_VERTICES, lo=1, hi=MAX_VERTICES,
                                doc="path vertices at most (1: the emitters seen and their direct light)")})
class Path(Integrator):
    """A path tracer with lightcuts' own BRDF, lit by the scene's emitting triangles: the exact
    image, without lights or trees; its cut counts path vertices per eye ray.

    Its kernel is this module's: next-event estimation and BRDF draws combined by multiple
    importance sampling, Russian roulette, at most ``max_depth`` vertices per path. The emitting
    triangles are its only lights, so a run with a sun or an environment map is refused; its
    RenderResult's ``shadow_rays`` are its next-event rays. It is unbiased, its own reference: it
    has no brute-force counterpart.
    """

    def __init__(self, *, spp: int = 1, max_depth: int = MAX_VERTICES):
        super().__init__(spp=spp)
        self.max_depth = self.max_cut = self.param("max_depth", max_depth)

    @classmethod
    def settings(cls, cfg) -> dict:
        for key, value in (("lights.sun", cfg.lights.sun), ("lights.environment", cfg.lights.environment)):
            if value is not None:
                raise LightcutsError(f"{key}: integrator 'path' renders the scene's emitting triangles only; "
                                     f"leave {key} out or use render.integrator: lightcuts")
        return super().settings(cfg)

    def forest(self, lights: dict, trees: dict | None, scene):
        """None: it renders without a light forest."""
        return None

    def band_kernel(self, f) -> Band:
        """The path kernel's call for the driver's frame ``f`` (lightcuts.integrators.driver): the scene's
        emitting triangles as next-event estimation draws them."""
        if f.env[0].shape[0] > 0:
            raise LightcutsError("envmap: integrator 'path' renders the scene's emitting triangles only (no "
                                 "environment map)")
        scene = f.scene
        e = Emitters(scene)
        tri_prob = np.zeros(scene.n_faces)  # the probability that next-event estimation draws a triangle
        if e.n:
            tri_prob[e.tri] = np.diff(e.cdf, prepend=0.0) / e.cdf[-1]
        em = (e.tri, np.ascontiguousarray(e.cdf, np.float64), e.p0, e.e1, e.e2, tri_prob,
              np.ascontiguousarray(scene.face_areas, np.float64))
        head = (f.caster.data, f.cam, f.seed, self.spp, f.sx, f.sy)
        tail = (int(f.camera.width), *f.surfaces, *f.env, *em, f.ray_offset, self.max_depth)
        return Band(_render_band, head, tail, max(1, BAND_PIXELS // f.cols), CHUNK)


def path_trace(scene, caster, camera=None, spp: int = 64, seed: int = 0, crop=None,
               max_depth: int = MAX_VERTICES) -> tuple[np.ndarray, float]:
    """lightcuts' scene path-traced with its own BRDF (the :class:`Path` integrator in one call):
    ((H, W, 3) float32 linear RGB of the camera's image or ``crop`` window, wall seconds).
    ``caster``: a kernel-callable ray caster over the scene; LightcutsError for bad arguments."""
    result = Path(spp=spp, max_depth=max_depth).render(scene, caster, {}, None, camera=camera, seed=seed, crop=crop)
    return result.image, result.seconds


def warm_kernels() -> None:
    """Compile the band kernel into numba's cache (lightcuts.integrators.driver.warm)."""
    warm(Path())
