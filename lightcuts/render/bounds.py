r"""Upper bounds over a cluster's bounding box (Walter et al. 2005, section 4.1): numba device functions.

A cluster C (a light-tree node) with box B = [lo, hi] over its lights' positions (directional
lights: over their unit directions), normal cone (axis a, half-angle beta) and summed RGB intensity
I_C has the error bound

    I_C * M_ub * G_ub          (V_ub = 1)

which is >= M * G * V * I_j summed over every light j of C (each light's contribution is bounded by
M_ub * G_ub * I_j). Every function here returns an upper bound of its term for *every* light that the
box (and cone) can hold, so the bound also holds for lights the tree never saw.

The box-in-a-frame trick
------------------------
Several terms need ``cos_ub``: an upper bound of the cosine of the angle between a unit axis ``z``
and any vector ``v`` in an axis-aligned box ``[vlo, vhi]``. Express the box in an orthonormal frame
``(t1, t2, z)``; the AABB ``[m, M]`` of the rotated box is, per frame axis ``u``,
``[sum_i min(u_i vlo_i, u_i vhi_i), sum_i max(u_i vlo_i, u_i vhi_i)]`` (exactly the AABB of the 8
rotated corners, computed without the corners). It contains the rotated box, so

    cos(theta_lo) = M.z / sqrt(tx^2 + ty^2 + M.z^2)

bounds the cosine from above. If ``M.z > 0``: ``tx^2 = 0`` if ``m.x <= 0 <= M.x`` else
``min(m.x^2, M.x^2)`` (likewise ty): for a fixed z > 0 the smallest angle has the smallest
``x^2 + y^2``, and the largest z wins. If ``M.z <= 0`` (every vector at or past 90 degrees):
``tx^2 = max(m.x^2, M.x^2)`` (likewise ty): a negative cosine is closest to 0 for the largest
``x^2 + y^2`` and the smallest ``|z|``. (The notes' rule returns 0 in this case; the negative value
is tighter for cones and the same for the material bound, which clamps at 0.)

Terms
-----
- distance: ``d_min^2`` = squared distance from x to B, 0 inside B (bound infinite: refine);
- omni: ``G_ub = 1 / d_min^2``;
- oriented: ``G_ub = cos_ub / d_min^2`` where, with ``theta_lo`` from the trick about the cone axis a
  over the vectors ``x - y`` (y in B, the box ``[x - hi, x - lo]``), ``cos_ub = 1`` if
  ``theta_lo <= beta``, else ``cos(theta_lo - beta)``; a full-sphere cone (``cone_cos <= -1``) gives 1;
- directional: ``G = 1``; the box holds the directions wi themselves;
- material ``M = f_r(wi, wo) * max(0, N . wi)``: ``M_ub = f_ub * cos_ub(N)`` with ``cos_ub(N)`` from
  the trick about N over the vectors wi can take (``[lo - x, hi - x]`` for positional lights, B itself
  for directional ones), 0 when it is <= 0. Lambert: ``f = rho_d / pi``; energy-normalised Phong (the
  2005 paper's glossy model): ``f = rho_d / pi + rho_s (n + 2) / (2 pi) max(0, R . wi)^n`` with
  ``R = reflect(wo, N)``, so ``f_ub`` uses ``cos_ub(R)`` (the trick about R) clamped to [0, 1].

Clamping of indirect VPLs
-------------------------
Indirect lights use ``G`` with ``max(d^2, r_c^2)`` in place of ``d^2`` (``r_c = min_distance *
scene diagonal``), in the estimate and in the bound alike. A cluster's bound uses the clamped
distance only when *every* light below it is indirect (``all_indirect``, precomputed per node): a
cluster that mixes direct and indirect lights keeps ``1 / d_min^2``, which bounds both kinds.

Device functions take scalars (x0, x1, x2 for a vector x): array views passed to numba functions
that LLVM does not inline cost a reference-count update each, a measured 3-4x slowdown here.

Rounding: every bound is multiplied by ``BOUND_SLACK`` (1 + 1e-9) so that a light sitting exactly on
the bound's extreme (a box corner, the cone's edge) cannot exceed it by a rounding error.
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


@njit(cache=True, error_model="numpy")
def box_distance2(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2):
    """Squared distance from the point x to the box [lo, hi]; 0 when x is inside."""
    return _gap2(x0, lo0, hi0) + _gap2(x1, lo1, hi1) + _gap2(x2, lo2, hi2)


@njit(cache=True, error_model="numpy")
def _gap2(x, lo, hi):
    """Squared distance from x to the interval [lo, hi]."""
    if x < lo:
        return (lo - x) * (lo - x)
    if x > hi:
        return (x - hi) * (x - hi)
    return 0.0


@njit(cache=True, error_model="numpy")
def orthonormal_frame(z0, z1, z2):
    """Two unit vectors t1, t2 with (t1, t2, z) orthonormal, for a unit z (Duff et al. 2017)."""
    sign = 1.0 if z2 >= 0.0 else -1.0
    a = -1.0 / (sign + z2)
    b = z0 * z1 * a
    return (1.0 + sign * z0 * z0 * a, sign * b, -sign * z0), (b, sign + z1 * z1 * a, -z1)


@njit(cache=True, error_model="numpy")
def _extent(u0, u1, u2, lo0, lo1, lo2, hi0, hi1, hi2):
    """[min, max] of u . v over the box [lo, hi]: the rotated box's extent along u."""
    a0, b0 = u0 * lo0, u0 * hi0
    a1, b1 = u1 * lo1, u1 * hi1
    a2, b2 = u2 * lo2, u2 * hi2
    return (min(a0, b0) + min(a1, b1) + min(a2, b2)), (max(a0, b0) + max(a1, b1) + max(a2, b2))


@njit(cache=True, error_model="numpy")
def max_cos_in_box(z0, z1, z2, lo0, lo1, lo2, hi0, hi1, hi2):
    """Upper bound of cos(angle(z, v)) over all non-zero v in the box [lo, hi], in [-1, 1]; z is unit.

    <= 0 means every v is at least 90 degrees from z (see the module docstring for the method).
    """
    t1, t2 = orthonormal_frame(z0, z1, z2)
    return max_cos_in_frame(z0, z1, z2, t1[0], t1[1], t1[2], t2[0], t2[1], t2[2], lo0, lo1, lo2, hi0, hi1, hi2)


@njit(cache=True, error_model="numpy")
def max_cos_in_frame(z0, z1, z2, u0, u1, u2, v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2):
    """:func:`max_cos_in_box` with the frame (u, v, z) of :func:`orthonormal_frame` given: a receiver
    computes the frames of its normal and mirror direction once for all the clusters it bounds."""
    _, mz_hi = _extent(z0, z1, z2, lo0, lo1, lo2, hi0, hi1, hi2)
    if mz_hi == 0.0:
        return 0.0
    mx_lo, mx_hi = _extent(u0, u1, u2, lo0, lo1, lo2, hi0, hi1, hi2)
    my_lo, my_hi = _extent(v0, v1, v2, lo0, lo1, lo2, hi0, hi1, hi2)
    if mz_hi > 0.0:
        tx2 = 0.0 if mx_lo <= 0.0 <= mx_hi else min(mx_lo * mx_lo, mx_hi * mx_hi)
        ty2 = 0.0 if my_lo <= 0.0 <= my_hi else min(my_lo * my_lo, my_hi * my_hi)
        return min(1.0, mz_hi / np.sqrt(tx2 + ty2 + mz_hi * mz_hi))
    tx2 = max(mx_lo * mx_lo, mx_hi * mx_hi)
    ty2 = max(my_lo * my_lo, my_hi * my_hi)
    return max(-1.0, mz_hi / np.sqrt(tx2 + ty2 + mz_hi * mz_hi))


@njit(cache=True, error_model="numpy")
def cone_cos_bound(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos):
    """Upper bound of max(0, n . (x - y)/|x - y|) for every y in [lo, hi] and every unit n in the cone
    with axis a and cos(half-angle) ``cone_cos`` (<= -1: full sphere -> 1)."""
    if cone_cos <= -1.0:
        return 1.0
    # Vectors x - y for y in the box form the box [x - hi, x - lo].
    c_lo = max_cos_in_box(a0, a1, a2, x0 - hi0, x1 - hi1, x2 - hi2, x0 - lo0, x1 - lo1, x2 - lo2)
    if c_lo >= cone_cos:  # theta_lo <= beta: some normal of the cone may point straight at x
        return 1.0
    # Here theta_lo > beta; both angles are in [0, pi], so both sines are >= 0.
    s_lo = np.sqrt(max(0.0, 1.0 - c_lo * c_lo))
    s_beta = np.sqrt(max(0.0, 1.0 - cone_cos * cone_cos))
    return max(0.0, min(1.0, c_lo * cone_cos + s_lo * s_beta))  # cos(theta_lo - beta)


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def receiver_frames(n0, n1, n2, r0, r1, r2):
    """The tangents of :func:`orthonormal_frame` about N and about R, as one 12-tuple
    ``(tn1, tn2, tr1, tr2)``: computed once per receiver, used by every cluster bound there."""
    a, b = orthonormal_frame(n0, n1, n2)
    c, d = orthonormal_frame(r0, r1, r2)
    return a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]


@njit(cache=True, error_model="numpy")
def material_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                          lo0, lo1, lo2, hi0, hi1, hi2, directional):
    """:func:`material_bound` with the receiver's frames ``fr`` (:func:`receiver_frames`) given."""
    if not directional:
        lo0, lo1, lo2 = lo0 - x0, lo1 - x1, lo2 - x2
        hi0, hi1, hi2 = hi0 - x0, hi1 - x1, hi2 - x2
    # Every wi below the horizon (the common case for clusters behind the surface): no frame needed.
    if _extent(n0, n1, n2, lo0, lo1, lo2, hi0, hi1, hi2)[1] <= 0.0:
        return 0.0, 0.0, 0.0
    cos_n = max_cos_in_frame(n0, n1, n2, fr[0], fr[1], fr[2], fr[3], fr[4], fr[5], lo0, lo1, lo2, hi0, hi1, hi2)
    lobe = 0.0
    if rs0 > 0.0 or rs1 > 0.0 or rs2 > 0.0:
        cos_r = max(0.0, max_cos_in_frame(r0, r1, r2, fr[6], fr[7], fr[8], fr[9], fr[10], fr[11],
                                          lo0, lo1, lo2, hi0, hi1, hi2))
        lobe = (exponent + 2.0) / (2.0 * np.pi) * cos_r ** exponent
    return ((rd0 / np.pi + rs0 * lobe) * cos_n, (rd1 / np.pi + rs1 * lobe) * cos_n,
            (rd2 / np.pi + rs2 * lobe) * cos_n)


@njit(cache=True, error_model="numpy")
def geometric_bound(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, clamp_d2):
    """Upper bound of G over every light the box (and cone) can hold; inf when x is inside the box.

    light_type : OMNI, ORIENTED or DIRECTIONAL; a, cone_cos : the normal cone; clamp_d2 : squared
    clamping distance when every light of the cluster is indirect and clamping is on, else 0.
    """
    if light_type == DIRECTIONAL:
        return 1.0
    d2 = max(box_distance2(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2), clamp_d2)
    if d2 <= 0.0:
        return np.inf
    if light_type == ORIENTED:
        return cone_cos_bound(x0, x1, x2, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos) / d2
    return 1.0 / d2


@njit(cache=True, error_model="numpy")
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
                                      i0, i1, i2, clamp_d2)


@njit(cache=True, error_model="numpy")
def cluster_error_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                               light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, i0, i1, i2, clamp_d2):
    """:func:`cluster_error_bound` with the receiver's frames ``fr`` (:func:`receiver_frames`) given:
    the same arithmetic, so the same bits. The lightcut calls this once per cluster it considers."""
    m0, m1, m2 = material_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                                       exponent, lo0, lo1, lo2, hi0, hi1, hi2, light_type == DIRECTIONAL)
    if m0 <= 0.0 and m1 <= 0.0 and m2 <= 0.0:
        return 0.0, 0.0, 0.0
    g = geometric_bound(x0, x1, x2, light_type, lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos,
                        clamp_d2) * BOUND_SLACK
    return _scaled(i0 * m0, g), _scaled(i1 * m1, g), _scaled(i2 * m2, g)


@njit(cache=True, error_model="numpy")
def _scaled(a, g):
    """a * g for a, g >= 0, with 0 * inf = 0 (a channel without intensity or reflectance)."""
    return a * g if a > 0.0 and g > 0.0 else 0.0
