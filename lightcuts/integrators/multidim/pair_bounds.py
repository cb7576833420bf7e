r"""Upper bound of a (gather cluster, light cluster) pair's contribution: numba device functions.

For every gather point i of the gather node G and every light j of the light node L, the pair
contributes ``w_i M_ij G_ij V_ij I_j`` (per RGB channel). The bound is
``W_G I_L F_ub C_ub G_ub BOUND_SLACK`` (V_ub = 1) with the terms bounded over both clusters at once
(docs/math.md, "Multidimensional lightcuts"): directions from any point of G's box to any point of
L's box lie in the Minkowski box ``D = [lo_L - hi_G, hi_L - lo_G]`` (directional lights: D is L's
box of directions), so the cosine bounds of lightcuts.integrators.bounds apply to D, widened by G's
normal and mirror-direction cones. A gather leaf uses lightcuts.integrators.bounds' point bound
(scaled by its weight), so a one-point gather tree gives exactly the lightcut's bounds.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.bounds import (BOUND_SLACK, DIRECTIONAL, ORIENTED, _cone_ratio, box_distance2,
                                     cluster_error_bound_framed, frame_coefficient, receiver_frames)
from lightcuts.integrators.forest import NB_AXIS, NB_COS, NB_FA, NB_HI, NB_I, NB_LO, NB_REP, REP_BITS
from lightcuts.integrators.multidim.gather import GP_EXP, GP_NRM, GP_POS, GP_RD, GP_REFL, GP_RS, GP_W
from lightcuts.integrators.multidim.gather_tree import (GK_LEFT, GN_EMAX, GN_EMIN, GN_HI, GN_LO, GN_NAX, GN_NCOS,
                                                   GN_RAX, GN_RCOS, GN_RD, GN_RS, GN_W)


@njit(cache=True, error_model="numpy", forceinline=True)
def cone_cos_over_box(a0, a1, a2, cone_cos, lo0, lo1, lo2, hi0, hi1, hi2):
    """Upper bound of max(0, n . v / |v|) over every unit n within the cone (axis a, cos(half-angle)
    cone_cos; <= -1: the sphere) and every non-zero v in the box [lo, hi]; in [0, 1]."""
    # bounds._cone_ratio bounds n . (x - y) over y in a box: with x = 0 and the box -[lo, hi], the
    # vectors x - y are exactly [lo, hi].
    num, qq = _cone_ratio(0.0, 0.0, 0.0, -hi0, -hi1, -hi2, -lo0, -lo1, -lo2, a0, a1, a2, cone_cos,
                          frame_coefficient(a0, a1, a2))
    return min(1.0, num / np.sqrt(qq))


@njit(cache=True, error_model="numpy", forceinline=True)
def pair_bound_rgb(gn, g, node_b, node_bi, k, clamp_d2):
    """Bound of the pair (gather node g of gn, light node k of the forest's records), per RGB channel.

    g must be an inner gather node (a leaf: :func:`pair_bound`); clamp_d2 : squared clamping
    distance (applied when every light of k is an indirect VPL). Inf where the two boxes can touch
    and the material and cosine bounds are not zero.
    """
    flags = node_bi[k, NB_REP] >> REP_BITS
    typ = np.int64(flags >> 1)
    c2 = clamp_d2 if flags & 1 else 0.0
    llo0, llo1, llo2 = np.float64(node_b[k, NB_LO]), np.float64(node_b[k, NB_LO + 1]), np.float64(node_b[k, NB_LO + 2])
    lhi0, lhi1, lhi2 = np.float64(node_b[k, NB_HI]), np.float64(node_b[k, NB_HI + 1]), np.float64(node_b[k, NB_HI + 2])
    if typ == DIRECTIONAL:
        d_lo0, d_lo1, d_lo2, d_hi0, d_hi1, d_hi2 = llo0, llo1, llo2, lhi0, lhi1, lhi2
    else:
        d_lo0, d_lo1, d_lo2 = llo0 - gn[g, GN_HI], llo1 - gn[g, GN_HI + 1], llo2 - gn[g, GN_HI + 2]
        d_hi0, d_hi1, d_hi2 = lhi0 - gn[g, GN_LO], lhi1 - gn[g, GN_LO + 1], lhi2 - gn[g, GN_LO + 2]
    cos_n = cone_cos_over_box(gn[g, GN_NAX], gn[g, GN_NAX + 1], gn[g, GN_NAX + 2], gn[g, GN_NCOS],
                              d_lo0, d_lo1, d_lo2, d_hi0, d_hi1, d_hi2)
    if cos_n <= 0.0:
        return 0.0, 0.0, 0.0
    geo = 1.0
    if typ != DIRECTIONAL:
        d2 = max(box_distance2(0.0, 0.0, 0.0, d_lo0, d_lo1, d_lo2, d_hi0, d_hi1, d_hi2), c2)
        cos_l = 1.0
        if typ == ORIENTED:
            # n_l . (x - y) for x in G's box, y in L's box: the vectors x - y form the box -D.
            num, qq = _cone_ratio(0.0, 0.0, 0.0, d_lo0, d_lo1, d_lo2, d_hi0, d_hi1, d_hi2,
                                  np.float64(node_b[k, NB_AXIS]), np.float64(node_b[k, NB_AXIS + 1]),
                                  np.float64(node_b[k, NB_AXIS + 2]), np.float64(node_b[k, NB_COS]),
                                  np.float64(node_b[k, NB_FA]))
            cos_l = min(1.0, num / np.sqrt(qq))
            if cos_l <= 0.0:
                return 0.0, 0.0, 0.0
        geo = np.inf if d2 <= 0.0 else cos_l / d2
    lobe = 0.0
    if gn[g, GN_RS] > 0.0 or gn[g, GN_RS + 1] > 0.0 or gn[g, GN_RS + 2] > 0.0:
        cos_r = cone_cos_over_box(gn[g, GN_RAX], gn[g, GN_RAX + 1], gn[g, GN_RAX + 2], gn[g, GN_RCOS],
                                  d_lo0, d_lo1, d_lo2, d_hi0, d_hi1, d_hi2)
        lobe = (gn[g, GN_EMAX] + 2.0) / (2.0 * np.pi) * cos_r ** gn[g, GN_EMIN]
    s = gn[g, GN_W] * cos_n * geo * BOUND_SLACK
    out0 = _times(np.float64(node_b[k, NB_I]) * (gn[g, GN_RD] / np.pi + gn[g, GN_RS] * lobe), s)
    out1 = _times(np.float64(node_b[k, NB_I + 1]) * (gn[g, GN_RD + 1] / np.pi + gn[g, GN_RS + 1] * lobe), s)
    out2 = _times(np.float64(node_b[k, NB_I + 2]) * (gn[g, GN_RD + 2] / np.pi + gn[g, GN_RS + 2] * lobe), s)
    return out0, out1, out2


@njit(cache=True, error_model="numpy", forceinline=True)
def _times(a, s):
    """a * s for a, s >= 0, with 0 * inf = 0."""
    return a * s if a > 0.0 and s > 0.0 else 0.0


@njit(cache=True, error_model="numpy", forceinline=True)
def point_bound_rgb(gp, i, node_b, node_bi, k, clamp_d2):
    """Bound of the pair (gather point i of gp, light node k): the lightcut's bound at the point
    (lightcuts.integrators.bounds.cluster_error_bound_framed) times the point's weight."""
    x0, x1, x2 = gp[i, GP_POS], gp[i, GP_POS + 1], gp[i, GP_POS + 2]
    n0, n1, n2 = gp[i, GP_NRM], gp[i, GP_NRM + 1], gp[i, GP_NRM + 2]
    r0, r1, r2 = gp[i, GP_REFL], gp[i, GP_REFL + 1], gp[i, GP_REFL + 2]
    fr = receiver_frames(n0, n1, n2, r0, r1, r2)
    flags = node_bi[k, NB_REP] >> REP_BITS
    c2 = clamp_d2 if flags & 1 else 0.0
    f = node_b
    b0, b1, b2 = cluster_error_bound_framed(
        x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, gp[i, GP_RD], gp[i, GP_RD + 1], gp[i, GP_RD + 2], gp[i, GP_RS],
        gp[i, GP_RS + 1], gp[i, GP_RS + 2], gp[i, GP_EXP], np.int64(flags >> 1), np.float64(f[k, NB_LO]),
        np.float64(f[k, NB_LO + 1]), np.float64(f[k, NB_LO + 2]), np.float64(f[k, NB_HI]),
        np.float64(f[k, NB_HI + 1]), np.float64(f[k, NB_HI + 2]), np.float64(f[k, NB_AXIS]),
        np.float64(f[k, NB_AXIS + 1]), np.float64(f[k, NB_AXIS + 2]), np.float64(f[k, NB_COS]),
        np.float64(f[k, NB_FA]), np.float64(f[k, NB_I]), np.float64(f[k, NB_I + 1]), np.float64(f[k, NB_I + 2]),
        c2)
    w = gp[i, GP_W]
    return _times(b0, w), _times(b1, w), _times(b2, w)


@njit(cache=True, error_model="numpy", forceinline=True)
def pair_bound(gp, gn, gk, g, node_b, node_bi, k, light_leaf, clamp_d2):
    """Bound of the pair (gather node g, light node k) in luminance-ready RGB: 0 for a pair of two
    leaves (its estimate is exact), else :func:`point_bound_rgb` for a gather leaf (g is then the
    point's row) or :func:`pair_bound_rgb`."""
    if gk[g, GK_LEFT] < 0:
        if light_leaf:
            return 0.0, 0.0, 0.0
        return point_bound_rgb(gp, g, node_b, node_bi, k, clamp_d2)
    return pair_bound_rgb(gn, g, node_b, node_bi, k, clamp_d2)
