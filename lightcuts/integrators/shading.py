r"""Exact shading of one light at one receiver: numba device functions (also callable from Python).

A light's contribution is ``M G V I`` per RGB channel, with ``M = f_r(wi, wo) max(0, N . wi)``
(Lambert plus energy-normalised Phong) and G by light type; clamped indirect VPLs use
``max(d^2, clamp_d2)`` for ``d^2`` (callers pass ``clamp_d2 = 0`` for a light that is not clamped):
docs/math.md, "Light contribution" and "Clamping". Surfaces are two-sided (:func:`facing_normal`
turns the normal N towards the viewer); emitters are one-sided. lightcuts.integrators.bounds bounds the
same terms over a cluster, and the lightcut and the reference both shade with these functions, so
their images differ only by the cut. Arguments are scalars (``x0, x1, x2`` for a vector x; ``rd``,
``rs`` the RGB reflectances), as in lightcuts.integrators.bounds.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.bounds import DIRECTIONAL, ORIENTED
from lightcuts.sampling import reflect  # noqa: F401  (re-exported: the shading functions' home)


@njit(cache=True, error_model="numpy")
def facing_normal(n0, n1, n2, wo0, wo1, wo2):
    """The unit normal n turned to the side of wo (two-sided shading)."""
    if n0 * wo0 + n1 * wo1 + n2 * wo2 < 0.0:
        return -n0, -n1, -n2
    return n0, n1, n2


@njit(cache=True, error_model="numpy")
def material_term(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, w0, w1, w2):
    """M = f_r(wi, wo) max(0, N . wi) per RGB channel for the unit wi = w.

    n : unit shading normal N; r : R = reflect(wo, N); rd, rs : RGB rho_d, rho_s;
    exponent : Phong n. Returns (M_r, M_g, M_b).
    """
    cos_i = n0 * w0 + n1 * w1 + n2 * w2
    if cos_i <= 0.0:
        return 0.0, 0.0, 0.0
    lobe = 0.0
    if rs0 > 0.0 or rs1 > 0.0 or rs2 > 0.0:
        lobe = (exponent + 2.0) / (2.0 * np.pi) * max(0.0, r0 * w0 + r1 * w1 + r2 * w2) ** exponent
    return ((rd0 / np.pi + rs0 * lobe) * cos_i, (rd1 / np.pi + rs1 * lobe) * cos_i,
            (rd2 / np.pi + rs2 * lobe) * cos_i)


@njit(cache=True, error_model="numpy")
def light_geometry(light_type, p0, p1, p2, nl0, nl1, nl2, x0, x1, x2, clamp_d2):
    """Direction, distance and geometric term of one light seen from x.

    light_type : OMNI, ORIENTED or DIRECTIONAL; p, nl : the light's position (directional: unit
    direction towards it) and normal; clamp_d2 : squared clamping distance (0: not clamped).
    Returns (w0, w1, w2, dist, G, ratio): unit wi towards the light, distance (inf for directional
    lights), G with the clamp, and G without the clamp over G with it (>= 1).

    One division for the direction (a reciprocal): divisions and square roots share the processor's
    divider, and the lightcut evaluates this for every new representative.
    """
    if light_type == DIRECTIONAL:
        return p0, p1, p2, np.inf, 1.0, 1.0
    v0, v1, v2 = p0 - x0, p1 - x1, p2 - x2
    d2 = v0 * v0 + v1 * v1 + v2 * v2
    if d2 <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0
    d = np.sqrt(d2)
    inv = 1.0 / d
    w0, w1, w2 = v0 * inv, v1 * inv, v2 * inv
    cos_l = 1.0
    if light_type == ORIENTED:
        cos_l = max(0.0, -(nl0 * w0 + nl1 * w1 + nl2 * w2))
    dc2 = max(d2, clamp_d2)
    return w0, w1, w2, d, cos_l / dc2, dc2 / d2


@njit(cache=True, error_model="numpy")
def unshadowed_contribution(light_type, p0, p1, p2, nl0, nl1, nl2, i0, i1, i2, x0, x1, x2, n0, n1, n2,
                            r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2):
    """M * G * I per RGB channel of one light at x, without visibility (V = 1).

    Arguments as :func:`light_geometry` and :func:`material_term`; i : the light's RGB intensity.
    """
    w0, w1, w2, _, g, _ = light_geometry(light_type, p0, p1, p2, nl0, nl1, nl2, x0, x1, x2, clamp_d2)
    if g <= 0.0:
        return 0.0, 0.0, 0.0
    m0, m1, m2 = material_term(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, w0, w1, w2)
    return m0 * g * i0, m1 * g * i1, m2 * g * i2
