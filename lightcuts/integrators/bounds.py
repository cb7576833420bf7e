r"""Upper bounds of a cluster's material and geometric terms at a receiver: numba device functions.

A cluster (a light-tree node) has a box ``[lo, hi]`` over its lights' positions (directional
lights: over their unit directions), a normal cone (unit axis a, ``cone_cos`` = cos of its
half-angle) and a summed RGB intensity I_C. Its error bound, per RGB channel, is
``I_C * M_ub * G_ub * BOUND_SLACK`` (V_ub = 1), where each term is bounded for *every* light the
box and cone can hold, not only those the tree saw. The formulas are in docs/math.md, sections
"Error bound", "Cosine bound over a box", "Geometric bound", "Material bound", "The bound as one
ratio" and "Clamping".

The lightcut evaluates two bounds per refined node, so :func:`cluster_error_bound_framed` is
arranged for a short chain of dependent operations rather than to read like the formulas: ratios
with one square root and one division, selects instead of unpredictable branches, the receiver's
frames and the cone's frame coefficient computed once, ``forceinline`` everywhere, scalar arguments
(x0, x1, x2 for a vector x) (docs/performance.md, "Renderer"). The plain forms
(:func:`material_bound`, :func:`geometric_bound`, :func:`cluster_error_bound`) compute the same
bounds for tests and callers outside the kernel.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Relative margin on every bound, for rounding (the bound's extreme case is often attained exactly).
BOUND_SLACK = 1.0 + 1e-9

#: Light type codes inside kernels (order of lightcuts.lights.lightset.LIGHT_TYPES).
OMNI = 0
ORIENTED = 1
DIRECTIONAL = 2


@njit(cache=True, error_model="numpy", forceinline=True)
def box_distance2(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2):
    """Squared distance from the point x to the box [lo, hi]; 0 when x is inside."""
    return _gap2(x0, lo0, hi0) + _gap2(x1, lo1, hi1) + _gap2(x2, lo2, hi2)


@njit(cache=True, error_model="numpy", forceinline=True)
def _gap2(x, lo, hi):
    """Squared distance from x to the interval [lo, hi] (no branch: which side x lies on is not
    predictable from one cluster to the next)."""
    g = max(max(lo - x, x - hi), 0.0)
    return g * g


@njit(cache=True, error_model="numpy", forceinline=True)
def orthonormal_frame(z0, z1, z2):
    """Two unit vectors t1, t2 with (t1, t2, z) orthonormal, for a unit z (Duff et al. 2017)."""
    return orthonormal_frame_from(z0, z1, z2, frame_coefficient(z0, z1, z2))


@njit(cache=True, error_model="numpy", forceinline=True)
def frame_coefficient(z0, z1, z2):
    """The one division of :func:`orthonormal_frame`, ``-1 / (sign(z2) + z2)`` (in [-1, -1/2]): the
    light tree's records store it per node (lightcuts.integrators.forest.pack_nodes), which takes it off the
    cone bound's chain of dependent operations."""
    return -1.0 / ((1.0 if z2 >= 0.0 else -1.0) + z2)


@njit(cache=True, error_model="numpy", forceinline=True)
def orthonormal_frame_from(z0, z1, z2, a):
    """:func:`orthonormal_frame` with its coefficient ``a`` (:func:`frame_coefficient`) given."""
    sign = 1.0 if z2 >= 0.0 else -1.0
    b = z0 * z1 * a
    return (1.0 + sign * z0 * z0 * a, sign * b, -sign * z0), (b, sign + z1 * z1 * a, -z1)


@njit(cache=True, error_model="numpy", forceinline=True)
def _extent(u0, u1, u2, lo0, lo1, lo2, hi0, hi1, hi2):
    """[min, max] of u . v over the box [lo, hi]: the rotated box's extent along u."""
    a0, b0 = u0 * lo0, u0 * hi0
    a1, b1 = u1 * lo1, u1 * hi1
    a2, b2 = u2 * lo2, u2 * hi2
    return (min(a0, b0) + min(a1, b1) + min(a2, b2)), (max(a0, b0) + max(a1, b1) + max(a2, b2))


@njit(cache=True, error_model="numpy", forceinline=True)
def max_cos_in_box(z0, z1, z2, lo0, lo1, lo2, hi0, hi1, hi2):
    """Upper bound of cos(angle(z, v)) over all non-zero v in the box [lo, hi], in [-1, 1]; z is unit.

    <= 0 means every v is at least 90 degrees from z (docs/math.md, "Cosine bound over a box").
    """
    t1, t2 = orthonormal_frame(z0, z1, z2)
    return max_cos_in_frame(z0, z1, z2, t1[0], t1[1], t1[2], t2[0], t2[1], t2[2], lo0, lo1, lo2, hi0, hi1, hi2)


@njit(cache=True, error_model="numpy", forceinline=True)
def _frame_cos(z0, z1, z2, u0, u1, u2, v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2):
    """``(m, t2)`` of the cosine bound over a box: ``m = M.z``, ``t2 = tx^2 + ty^2`` (docs/math.md, "Cosine
    bound over a box"), so that the bound is ``m / sqrt(t2 + m^2)`` and its sine ``sqrt(t2) / sqrt(t2 + m^2)``."""
    _, m = _extent(z0, z1, z2, lo0, lo1, lo2, hi0, hi1, hi2)
    mx_lo, mx_hi = _extent(u0, u1, u2, lo0, lo1, lo2, hi0, hi1, hi2)
    my_lo, my_hi = _extent(v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2)
    # Without branches (selects): m > 0 wants the distance from 0 to each interval [lo, hi]
    # (0 if it holds 0, else min(|lo|, |hi|)), m <= 0 the largest |.| over it (max(-lo, hi)).
    up = m > 0.0
    gx = max(max(mx_lo, -mx_hi), 0.0) if up else max(-mx_lo, mx_hi)
    gy = max(max(my_lo, -my_hi), 0.0) if up else max(-my_lo, my_hi)
    return m, gx * gx + gy * gy


@njit(cache=True, error_model="numpy", forceinline=True)
def max_cos_in_frame(z0, z1, z2, u0, u1, u2, v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2):
    """:func:`max_cos_in_box` with the frame (u, v, z) of :func:`orthonormal_frame` given."""
    m, t2 = _frame_cos(z0, z1, z2, u0, u1, u2, v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2)
    if m == 0.0:
        return 0.0
    return max(-1.0, min(1.0, m / np.sqrt(t2 + m * m)))


@njit(cache=True, error_model="numpy", forceinline=True)
def _cone_ratio(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, cone_fa):
    """:func:`cone_cos_bound` as ``(num, qq)``, bound = num / sqrt(qq) with qq > 0 and num >= 0 (not
    clamped at 1): the caller folds the root into the cluster bound's single root and division.
    cone_fa : the axis's :func:`frame_coefficient` (a frame that is orthonormal up to float32
    rounding of it is covered by the records' widened cones, lightcuts.integrators.forest.CONE_WIDEN).

    With ``c_lo = m / q`` (``q = sqrt(t2 + m^2)``, :func:`_frame_cos` about the axis over the vectors
    x - y) and ``sin(theta_lo) = sqrt(t2) / q``, ``cos(theta_lo - beta) = (m cos(beta) + sqrt(t2)
    sin(beta)) / q``; ``theta_lo <= beta`` (``m >= cos(beta) q``) gives 1. ``sqrt(t2) sin(beta)`` is
    taken as one root, ``sqrt(t2 (1 - cos(beta)^2))``: square roots share the processor's divider
    with divisions, and this bound is computed twice per refined node.
    """
    if cone_cos <= -1.0:
        return 1.0, 1.0
    t1, t2 = orthonormal_frame_from(a0, a1, a2, cone_fa)
    # Vectors x - y for y in the box form the box [x - hi, x - lo].
    m, tt = _frame_cos(a0, a1, a2, t1[0], t1[1], t1[2], t2[0], t2[1], t2[2],
                       x0 - hi0, x1 - hi1, x2 - hi2, x0 - lo0, x1 - lo1, x2 - lo2)
    # theta_lo <= beta (m >= cos(beta) q, squared so that no root precedes the branch): some normal
    # of the cone may point straight at x. q = 0 (x on a flat box) counts as inside too.
    mm = m * m
    qq = tt + mm
    c2qq = cone_cos * cone_cos * qq
    inside = ((mm >= c2qq) & (m > 0.0)) if cone_cos > 0.0 else ((m >= 0.0) | (mm <= c2qq))
    inside |= qq <= 0.0
    # Otherwise theta_lo > beta and q > 0; both angles are in [0, pi], so both sines are >= 0.
    # Both outcomes are computed and one selected: the test is not predictable.
    num = max(0.0, m * cone_cos + np.sqrt(tt * max(0.0, 1.0 - cone_cos * cone_cos)))
    return (1.0 if inside else num), (1.0 if inside else qq)


@njit(cache=True, error_model="numpy", forceinline=True)
def cone_cos_bound(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos):
    """Upper bound of max(0, n . (x - y)/|x - y|) for every y in [lo, hi] and every unit n in the cone
    with axis a and cos(half-angle) ``cone_cos`` (<= -1: full sphere -> 1)."""
    num, qq = _cone_ratio(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos,
                          frame_coefficient(a0, a1, a2))
    return min(1.0, num / np.sqrt(qq))


@njit(cache=True, error_model="numpy", forceinline=True)
def material_bound(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                   lo0, lo1, lo2, hi0, hi1, hi2, directional):
    """Upper bound of M = f_r(wi, wo) max(0, N . wi) per RGB channel over the wi the box allows.

    x : receiver (ignored for directional boxes); n : unit normal N facing the viewer; r : unit
    mirror direction R = reflect(wo, N); rd, rs : RGB rho_d, rho_s; exponent : Phong n;
    lo, hi : the cluster box (positions, or directions when ``directional``).
    Returns (M_r, M_g, M_b), zeros when the whole box is behind the surface.
    """
    fn = receiver_frames(n0, n1, n2, r0, r1, r2)
    return material_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fn, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                                 lo0, lo1, lo2, hi0, hi1, hi2, directional)


@njit(cache=True, error_model="numpy", forceinline=True)
def receiver_frames(n0, n1, n2, r0, r1, r2):
    """The tangents of :func:`orthonormal_frame` about N and about R, as one 12-tuple
    ``(tn1, tn2, tr1, tr2)``: computed once per receiver, used by every cluster bound there."""
    a, b = orthonormal_frame(n0, n1, n2)
    c, d = orthonormal_frame(r0, r1, r2)
    return a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]


@njit(cache=True, error_model="numpy", forceinline=True)
def _material_ratio(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                    lo0, lo1, lo2, hi0, hi1, hi2, directional):
    """The material bound as ``(f_r, f_g, f_b, m, qq)``: ``M_ub = f * m / sqrt(qq)`` per channel (``f_ub``
    and ``cos_ub(N) = m / sqrt(qq)``, not clamped at 1), with the receiver's frames ``fr``
    (:func:`receiver_frames`).
    ``m <= 0`` (the rest meaningless) when every wi is at or below the horizon."""
    if not directional:
        lo0, lo1, lo2 = lo0 - x0, lo1 - x1, lo2 - x2
        hi0, hi1, hi2 = hi0 - x0, hi1 - x1, hi2 - x2
    # Every wi below the horizon (the common case for clusters behind the surface): no frame needed.
    if _extent(n0, n1, n2, lo0, lo1, lo2, hi0, hi1, hi2)[1] <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 1.0
    m, t2 = _frame_cos(n0, n1, n2, fr[0], fr[1], fr[2], fr[3], fr[4], fr[5], lo0, lo1, lo2, hi0, hi1, hi2)
    lobe = 0.0
    if rs0 > 0.0 or rs1 > 0.0 or rs2 > 0.0:
        cos_r = max(0.0, max_cos_in_frame(r0, r1, r2, fr[6], fr[7], fr[8], fr[9], fr[10], fr[11],
                                          lo0, lo1, lo2, hi0, hi1, hi2))
        lobe = (exponent + 2.0) / (2.0 * np.pi) * cos_r ** exponent
    return rd0 / np.pi + rs0 * lobe, rd1 / np.pi + rs1 * lobe, rd2 / np.pi + rs2 * lobe, m, t2 + m * m


@njit(cache=True, error_model="numpy", forceinline=True)
def material_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                          lo0, lo1, lo2, hi0, hi1, hi2, directional):
    """:func:`material_bound` with the receiver's frames ``fr`` (:func:`receiver_frames`) given."""
    f0, f1, f2, m, qq = _material_ratio(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                                        exponent, lo0, lo1, lo2, hi0, hi1, hi2, directional)
    if m <= 0.0:
        return 0.0, 0.0, 0.0
    cos_n = min(1.0, m / np.sqrt(qq))
    return f0 * cos_n, f1 * cos_n, f2 * cos_n


@njit(cache=True, error_model="numpy", forceinline=True)
def _geometric_ratio(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, cone_fa, clamp_d2):
    """:func:`geometric_bound` as ``(num, qq, d2)``, G_ub = num / (sqrt(qq) d2) with num >= 0, qq > 0 and
    d2 >= 0; d2 = 0 when x is inside a positional cluster's box (the bound is infinite)."""
    if light_type == DIRECTIONAL:
        return 1.0, 1.0, 1.0
    d2 = max(box_distance2(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2), clamp_d2)
    if d2 <= 0.0:
        return 1.0, 1.0, 0.0
    if light_type == ORIENTED:
        num, qq = _cone_ratio(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, cone_fa)
        return num, qq, d2
    return 1.0, 1.0, d2


@njit(cache=True, error_model="numpy", forceinline=True)
def geometric_bound(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, clamp_d2):
    """Upper bound of G over every light the box (and cone) can hold; inf when x is inside the box.

    light_type : OMNI, ORIENTED or DIRECTIONAL; a, cone_cos : the normal cone; clamp_d2 : squared
    clamping distance when every light of the cluster is indirect and clamping is on, else 0.
    """
    num, qq, d2 = _geometric_ratio(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos,
                                   frame_coefficient(a0, a1, a2), clamp_d2)
    if d2 <= 0.0:
        return np.inf
    return num / (np.sqrt(qq) * d2)


@njit(cache=True, error_model="numpy", forceinline=True)
def cluster_error_bound(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                        light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, i0, i1, i2, clamp_d2):
    """Error bound of a cluster, per RGB channel: I_C * M_ub * G_ub * BOUND_SLACK (V_ub = 1).

    i : the cluster's summed RGB intensity I_C; other arguments as in :func:`material_bound` and
    :func:`geometric_bound`. Inf where the receiver is inside a positional cluster's box and the
    material bound is non-zero.
    """
    fr = receiver_frames(n0, n1, n2, r0, r1, r2)
    return cluster_error_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                                      exponent, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos,
                                      frame_coefficient(a0, a1, a2), i0, i1, i2, clamp_d2)


@njit(cache=True, error_model="numpy", forceinline=True)
def cluster_error_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                               light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, cone_fa, i0, i1, i2,
                               clamp_d2):
    """:func:`cluster_error_bound` with the receiver's frames ``fr`` (:func:`receiver_frames`) and the cone
    axis's :func:`frame_coefficient` ``cone_fa`` given.
    The lightcut calls this once per cluster it considers.

    ``I f m / sqrt(qm) * num / (sqrt(qg) d2)``: the material and geometric bounds as ratios
    (:func:`_material_ratio`, :func:`_geometric_ratio`), so that one division and one square root,
    ``sqrt(qm qg)``, remain on the path from the box to the bound (docs/math.md, "The bound as one
    ratio"). qm and qg are squared lengths of float32-bounded boxes, so their product stays far
    from overflow.
    """
    f0, f1, f2, m, qm = _material_ratio(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                                        exponent, lo0, lo1, lo2, hi0, hi1, hi2, light_type == DIRECTIONAL)
    if m <= 0.0:
        return 0.0, 0.0, 0.0
    num, qg, d2 = _geometric_ratio(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos,
                                   cone_fa, clamp_d2)
    if d2 <= 0.0:  # x inside the box: infinite where the channel has intensity and reflectance
        return _scaled(i0 * f0, np.inf), _scaled(i1 * f1, np.inf), _scaled(i2 * f2, np.inf)
    s = m * num * BOUND_SLACK / (np.sqrt(qm * qg) * d2)
    return i0 * f0 * s, i1 * f1 * s, i2 * f2 * s


@njit(cache=True, error_model="numpy", forceinline=True)
def _scaled(a, g):
    """a * g for a, g >= 0, with 0 * inf = 0 (a channel without intensity or reflectance)."""
    return a * g if a > 0.0 and g > 0.0 else 0.0
