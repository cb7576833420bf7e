"""Direction sampling shared by the particle tracer (lightcuts.lights.indirect), the eye-path
continuation (lightcuts.integrators.continuation) and the path tracer (lightcuts.integrators.path):
numba device functions of scalars.

The BRDF is Lambert plus energy-normalised Phong, ``f = rho_d / pi + rho_s (n + 2) / (2 pi)
cos^n(alpha)`` with alpha the angle between the sampled direction and the mirror direction R
(docs/math.md, "Light contribution"). Both lobes are sampled exactly: the diffuse lobe with
``pdf = cos(theta) / pi``, the Phong lobe with ``pdf = (n + 1) / (2 pi) cos^n(alpha)`` about R.
"""

from __future__ import annotations

import math

import numpy as np

from numba import njit


@njit(cache=True, error_model="numpy")
def reflect(wo0, wo1, wo2, n0, n1, n2):
    """Mirror direction R = 2 (N . wo) N - wo of the unit wo about the unit N."""
    c = 2.0 * (n0 * wo0 + n1 * wo1 + n2 * wo2)
    return c * n0 - wo0, c * n1 - wo1, c * n2 - wo2


@njit(cache=True, error_model="numpy")
def frame_direction(z0, z1, z2, lx, ly, lz):
    """The local direction (lx, ly, lz) in the orthonormal frame whose third axis is the unit z
    (the frame of Duff et al. 2017)."""
    sign = 1.0 if z2 >= 0.0 else -1.0
    a = -1.0 / (sign + z2)
    b = z0 * z1 * a
    tx, ty, tz = 1.0 + sign * z0 * z0 * a, sign * b, -sign * z0
    bx, by, bz = b, sign + z1 * z1 * a, -z1
    return (lx * tx + ly * bx + lz * z0, lx * ty + ly * by + lz * z1, lx * tz + ly * bz + lz * z2)


@njit(cache=True, error_model="numpy")
def cosine_direction(nx, ny, nz, u1, u2):
    """Cosine-distributed unit direction about the unit normal n, from two uniforms in [0, 1)."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    return frame_direction(nx, ny, nz, r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1)))


@njit(cache=True, error_model="numpy")
def phong_direction(r0, r1, r2, n0, n1, n2, exponent, u1, u2):
    """A unit direction w with density ``(n + 1) / (2 pi) cos^n(alpha)`` about the unit mirror
    direction r, and ``N . w`` (<= 0: below the surface, where the BRDF is zero)."""
    ca = u1 ** (1.0 / (exponent + 1.0))
    sa = math.sqrt(max(0.0, 1.0 - ca * ca))
    phi = 2.0 * math.pi * u2
    w0, w1, w2 = frame_direction(r0, r1, r2, sa * math.cos(phi), sa * math.sin(phi), ca)
    return w0, w1, w2, n0 * w0 + n1 * w1 + n2 * w2


@njit(cache=True, error_model="numpy", forceinline=True)
def sample_brdf(n0, n1, n2, r0, r1, r2, wd0, wd1, wd2, ws0, ws1, ws2, exponent, u0, u1, u2):
    """A direction from the BRDF ``wd / pi + ws (n + 2) / (2 pi) cos^n`` (RGB weights wd, ws of the
    two lobes) at a point with unit normal n and mirror direction r: the lobe with probability in
    proportion to its weight's largest channel, then its direction exactly. Returns
    ``(w0, w1, w2, t0, t1, t2, pdf, ok)``: the direction and ``f cos / pdf`` per channel (the mixture's
    pdf), the pdf itself; ok False for a direction below the surface (zero contribution)."""
    qd = max(wd0, wd1, wd2)
    qs = max(ws0, ws1, ws2)
    q = qd + qs
    if u0 * q < qd:
        w0, w1, w2 = cosine_direction(n0, n1, n2, u1, u2)
        cos_i = n0 * w0 + n1 * w1 + n2 * w2
    else:
        w0, w1, w2, cos_i = phong_direction(r0, r1, r2, n0, n1, n2, exponent, u1, u2)
    if cos_i <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    lobe = 0.0
    if qs > 0.0:
        lobe = (exponent + 2.0) / (2.0 * np.pi) * max(0.0, r0 * w0 + r1 * w1 + r2 * w2) ** exponent
    pdf = qd / q * cos_i / np.pi + qs / q * lobe * (exponent + 1.0) / (exponent + 2.0)
    if pdf <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    k = cos_i / pdf
    return (w0, w1, w2, (wd0 / np.pi + ws0 * lobe) * k, (wd1 / np.pi + ws1 * lobe) * k,
            (wd2 / np.pi + ws2 * lobe) * k, pdf, True)


@njit(cache=True, error_model="numpy")
def brdf_pdf(n0, n1, n2, r0, r1, r2, qd, qs, exponent, w0, w1, w2):
    """Density (solid angle) of :func:`sample_brdf` drawing the unit
    w: the lobe mixture with weights qd, qs (the lobes' largest channels)."""
    cos_i = n0 * w0 + n1 * w1 + n2 * w2
    if cos_i <= 0.0 or qd + qs <= 0.0:
        return 0.0
    pdf = qd * cos_i / np.pi
    if qs > 0.0:
        pdf += qs * (exponent + 1.0) / (2.0 * np.pi) * max(0.0, r0 * w0 + r1 * w1 + r2 * w2) ** exponent
    return pdf / (qd + qs)
