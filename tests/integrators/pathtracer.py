"""A brute-force path tracer: the oracle of the converging renderer's tests.

Unidirectional, no light sampling: each eye ray (the renderer's own, lightcuts.integrators.camera) walks
the scene with cosine-distributed directions, weighted by ``f cos / pdf = pi f`` with the full BRDF
``rho_d / pi + rho_s (n + 2) / (2 pi) cos^n(alpha)``, and adds the emission of every emitter front
it hits. Surfaces reflect on both sides; an emitter's back absorbs. Russian roulette from the fourth
vertex on. Written apart from the renderer's sampling code (lightcuts.sampling) so that an error
there cannot hide in the oracle. Deterministic: random numbers are a hash of (seed, pixel, sample,
vertex, dimension).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lightcuts.accel.base import kernel_caster_of
from lightcuts.accel.kernel_api import intersect, new_scratch
from lightcuts.hashing import mix64
from lightcuts.parallel import next_task, on_counter
from lightcuts.integrators.camera import CAM_POSITION, camera_params, eye_ray, strata
from lightcuts.integrators.driver import shadow_ray_offset

MAX_VERTICES = 64


@njit(cache=True)
def _u(seed, pixel, sample, vertex, dim):
    h = mix64(np.uint64(seed) ^ np.uint64(0x5054))
    h = mix64(h ^ np.uint64(pixel))
    h = mix64(h ^ np.uint64(sample))
    h = mix64(h ^ np.uint64(vertex * 4 + dim))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _cosine(n0, n1, n2, u1, u2):
    # any orthonormal frame about n
    if abs(n0) > 0.5:
        a0, a1, a2 = 0.0, 1.0, 0.0
    else:
        a0, a1, a2 = 1.0, 0.0, 0.0
    t0, t1, t2 = a1 * n2 - a2 * n1, a2 * n0 - a0 * n2, a0 * n1 - a1 * n0
    tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0, t1, t2 = t0 / tn, t1 / tn, t2 / tn
    b0, b1, b2 = n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    x, y, z = r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1))
    return x * t0 + y * b0 + z * n0, x * t1 + y * b1 + z * n1, x * t2 + y * b2 + z * n2


@njit(cache=True, nogil=True)
def _trace(cdata, cam, seed, spp, sx, sy, width, face_normal, albedo, specular, exponent, emission, offset, out,
           tasks):
    buf = new_scratch(cdata)
    n = out.shape[0] * out.shape[1]
    while True:
        i = next_task(tasks)
        if i >= n:
            break
        py, px = i // width, i % width
        a0 = a1 = a2 = 0.0
        for s in range(spp):
            o0, o1, o2 = cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]
            d0, d1, d2 = eye_ray(cam, seed, px, py, s, sx, sy)
            b0 = b1 = b2 = 1.0
            for v in range(MAX_VERTICES):
                t, prim = intersect(cdata, buf, o0, o1, o2, d0, d1, d2, 0.0, np.inf)
                if prim < 0:
                    break
                f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
                front = f0 * d0 + f1 * d1 + f2 * d2 < 0.0
                if emission[prim, 0] > 0.0 or emission[prim, 1] > 0.0 or emission[prim, 2] > 0.0:
                    if not front:
                        break
                    a0 += b0 * emission[prim, 0]
                    a1 += b1 * emission[prim, 1]
                    a2 += b2 * emission[prim, 2]
                if not front:
                    f0, f1, f2 = -f0, -f1, -f2
                x0, x1, x2 = o0 + t * d0, o1 + t * d1, o2 + t * d2
                w0, w1, w2 = _cosine(f0, f1, f2, _u(seed, i, s, v, 0), _u(seed, i, s, v, 1))
                # mirror direction of the view (-d) about the normal
                c = -2.0 * (f0 * d0 + f1 * d1 + f2 * d2)
                r0, r1, r2 = d0 + c * f0, d1 + c * f1, d2 + c * f2
                e = exponent[prim]
                lobe = (e + 2.0) / 2.0 * max(0.0, r0 * w0 + r1 * w1 + r2 * w2) ** e  # pi f_s / rho_s
                b0 *= albedo[prim, 0] + specular[prim, 0] * lobe
                b1 *= albedo[prim, 1] + specular[prim, 1] * lobe
                b2 *= albedo[prim, 2] + specular[prim, 2] * lobe
                if v >= 3:
                    q = min(1.0, max(b0, b1, b2))
                    if _u(seed, i, s, v, 2) >= q:
                        break
                    b0 /= q
                    b1 /= q
                    b2 /= q
                o0, o1, o2 = x0 + offset * f0, x1 + offset * f1, x2 + offset * f2
                d0, d1, d2 = w0, w1, w2
        out[py, px, 0] = a0 / spp
        out[py, px, 1] = a1 / spp
        out[py, px, 2] = a2 / spp


def path_trace(scene, caster, camera, spp: int, seed: int) -> np.ndarray:
    """(H, W, 3) float64: the radiance of every pixel of ``camera`` by ``spp`` paths per pixel."""
    data, _ = kernel_caster_of(caster)
    cam = camera_params(camera)
    sx, sy = strata(spp)
    out = np.zeros((camera.height, camera.width, 3))
    arrays = (np.ascontiguousarray(a, np.float64) for a in (scene.face_normals, scene.albedo, scene.specular,
                                                            scene.exponent, scene.emission))
    on_counter(_trace, camera.height * camera.width, 2, data, cam, int(seed), int(spp), sx, sy, camera.width,
               *arrays, shadow_ray_offset(scene), out)
    return out
