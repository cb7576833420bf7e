r"""The eye-path continuation of ``render.compensation`` (docs/math.md, "Converging images"): the light
that the VPLs do not carry, estimated without bias by continuing the eye path from each receiver.

At a receiver x the lightcut sums the direct lights and the VPLs; it misses the light that reaches x
from a surface point y by (a) the part of y's diffuse reflection that clamping removes, a fraction
``w(x, y) = max(0, 1 - |x - y|^2 / clamp_d2)`` of it (Kollig and Keller 2004), and (b) y's glossy
reflection, since VPLs re-emit diffusely. So the path goes on: a direction is sampled from x's BRDF
(the diffuse or the Phong lobe, each exactly, lightcuts.sampling), the ray finds y, and a lightcut at
y with the BRDF ``w(x, y) f_d + f_s`` is added, weighted by the path's throughput ``f cos / pdf``.
The light that lightcut misses in turn is the same problem one vertex on, with that BRDF in place of
x's: the path goes on from y the same way, with Russian roulette on the throughput from the second
vertex. A vertex whose BRDF is zero (a diffuse y farther than the clamping distance) ends the path:
then the continuation costs one ray and no lightcut. Emitters are seen by the direct lights only
(a continuation ray that hits an emitter's front adds its reflection, not its emission; its back
absorbs) and the environment by its directional lights (a miss ends the path).

Each secondary lightcut stops at ``eps`` of its own total or at ``tol = eps * L_1 / beta`` (``L_1``
the receiver's estimate, ``beta`` the largest channel of the throughput), whichever is larger: its
error then stays within eps of the pixel, and a dim continuation costs a few nodes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import intersect
from lightcuts.hashing import mix64
from lightcuts.integrators.cut import lightcut
from lightcuts.integrators.shading import facing_normal
from lightcuts.sampling import reflect, sample_brdf
from lightcuts.scene.textures import albedo_at

#: Path vertices after the receiver at most (Russian roulette ends nearly every path long before).
MAX_VERTICES = 32
#: The first vertex on which Russian roulette decides (1 = the first one after the receiver).
RR_START = 2
_STREAM = np.uint64(0x434F4E54)  # "CONT": the continuation's stream, apart from the eye rays'
# The random numbers of a vertex (_u01's dim): the BRDF sample's three, the roulette's. int64, not
# literal ints, so that _u01 compiles once rather than once per constant.
_U_BRDF1, _U_BRDF2, _U_BRDF3, _U_RR = np.int64(0), np.int64(1), np.int64(2), np.int64(3)


@njit(cache=True, error_model="numpy", forceinline=True)
def _u01(key, vertex, dim):
    h = mix64(key ^ mix64(np.uint64(vertex) * np.uint64(8) + np.uint64(dim)))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, error_model="numpy")
def path_key(seed, pixel, sample):
    """The hash key of one eye ray's continuation (and of its stochastic representatives)."""
    h = mix64(np.uint64(seed) ^ _STREAM)
    h = mix64(h ^ np.uint64(pixel))
    return mix64(h ^ np.uint64(sample)) | np.uint64(1)  # never 0: 0 means fixed representatives


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def continuation(key, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, l1,
                 face_normal, albedo, tex, specular, exponents, emission, node_b, node_bi, roots, light_f, eps, max_cut,
                 clamp_d2, ray_offset, visibility, cdata, buf, width, pk, heap, slot_node, slot_mgv, slot_ratio,
                 lane_slot, stochastic):
    """The compensation at one receiver (module docstring): ``(L_r, L_g, L_b, rays)``, the radiance
    towards the viewer that the receiver's lightcut misses, and the rays cast (continuation rays
    and the secondary cuts' shadow rays).

    x, n, r, rd, rs, exponent : the receiver as in lightcuts.integrators.cut.lightcut (n facing the
    viewer, r the mirror direction of the view); l1 : the luminance of its lightcut's estimate;
    key : :func:`path_key`; the scene's per-triangle arrays, the forest, cut settings and scratch as
    for the render kernel; stochastic : the secondary cuts use stochastic representatives.
    """
    b0, b1, b2 = 1.0, 1.0, 1.0
    a0, a1, a2 = 0.0, 0.0, 0.0
    rays = 0
    wd0, wd1, wd2 = rd0, rd1, rd2
    ws0, ws1, ws2 = rs0, rs1, rs2
    e = exponent
    for v in range(1, MAX_VERTICES + 1):
        if max(wd0, wd1, wd2) + max(ws0, ws1, ws2) <= 0.0:
            break
        w0, w1, w2, t0, t1, t2, _, ok = sample_brdf(n0, n1, n2, r0, r1, r2, wd0, wd1, wd2, ws0, ws1, ws2, e,
                                                 _u01(key, v, _U_BRDF1), _u01(key, v, _U_BRDF2), _u01(key, v, _U_BRDF3))
        if not ok:
            break
        b0 *= t0
        b1 *= t1
        b2 *= t2
        if v >= RR_START:
            q = min(1.0, max(b0, b1, b2))
            if q <= 0.0 or _u01(key, v, _U_RR) >= q:
                break
            b0 /= q
            b1 /= q
            b2 /= q
        rays += 1
        t, prim = intersect(cdata, buf, x0 + ray_offset * n0, x1 + ray_offset * n1, x2 + ray_offset * n2,
                            w0, w1, w2, 0.0, np.inf)
        if prim < 0:
            break
        f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
        if (emission[prim, 0] > 0.0 or emission[prim, 1] > 0.0 or emission[prim, 2] > 0.0) \
                and f0 * w0 + f1 * w1 + f2 * w2 >= 0.0:
            break  # the back of an emitter absorbs
        y0, y1, y2 = x0 + ray_offset * n0 + t * w0, x1 + ray_offset * n1 + t * w1, x2 + ray_offset * n2 + t * w2
        ny0, ny1, ny2 = facing_normal(f0, f1, f2, -w0, -w1, -w2)
        ry0, ry1, ry2 = reflect(-w0, -w1, -w2, ny0, ny1, ny2)
        dx0, dx1, dx2 = y0 - x0, y1 - x1, y2 - x2
        d2 = dx0 * dx0 + dx1 * dx1 + dx2 * dx2
        w = 1.0 - d2 / clamp_d2 if d2 < clamp_d2 else 0.0
        al0, al1, al2 = albedo_at(albedo, tex, prim, y0, y1, y2)
        wd0, wd1, wd2 = w * al0, w * al1, w * al2
        ws0, ws1, ws2 = specular[prim, 0], specular[prim, 1], specular[prim, 2]
        e = exponents[prim]
        if max(wd0, wd1, wd2) + max(ws0, ws1, ws2) <= 0.0:
            break
        beta = max(b0, b1, b2)
        tol = eps * l1 / beta if beta > 0.0 else 0.0
        skey = mix64(key ^ np.uint64(v)) | np.uint64(1) if stochastic else np.uint64(0)
        res = lightcut(y0, y1, y2, ny0, ny1, ny2, ry0, ry1, ry2, wd0, wd1, wd2, ws0, ws1, ws2, e,
                       node_b, node_bi, roots, light_f, eps, max_cut, clamp_d2, ray_offset, visibility,
                       cdata, buf, width, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot, tol, skey)
        a0 += b0 * res[0]
        a1 += b1 * res[1]
        a2 += b2 * res[2]
        rays += res[4]
        x0, x1, x2, n0, n1, n2, r0, r1, r2 = y0, y1, y2, ny0, ny1, ny2, ry0, ry1, ry2
    return a0, a1, a2, rays
