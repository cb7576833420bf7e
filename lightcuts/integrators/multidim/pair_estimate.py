r"""The pair estimate's ``M G`` and shadow ray: what a (gather node, light) pair of the product cut shades
with (docs/math.md, "Pair estimate"), without casting the ray.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.cut import _light_mg
from lightcuts.integrators.forest import LF_INDIRECT, LF_NRM, LF_POS, LF_TYPE
from lightcuts.integrators.multidim.gather import GP_EXP, GP_NRM, GP_POS, GP_RD, GP_REFL, GP_RS, GP_W
from lightcuts.integrators.multidim.gather_tree import GK_FIRST, GK_LAST, GK_LEFT, GN_MIXED, GN_RS
from lightcuts.integrators.shading import light_geometry, material_term


@njit(cache=True, error_model="numpy")
def pair_mg(gp, gn, gk, gidx, node, g, j, light_f, clamp_d2, ray_offset, visibility):
    """M G (RGB) and clamp ratio of light j for gather node ``node`` at its representative point g, per
    unit weight of the node, and the shadow ray that decides V (not cast here).

    A leaf is lightcuts.integrators.cut's ``M G`` at its point; an inner node takes G (and the
    direction w) at g and the weighted mean over its points i of their own materials M_i(w) (normal,
    mirror direction, rho_d, rho_s, exponent), with the shadow ray from g (or, where g faces away
    from the light, from the first point that faces it): so a pixel over several materials or
    orientations is shaded with their mix. A diffuse node whose points share normal and rho_d is
    its leaf's case (the mean is g's own term).
    Returns ``(m_r, m_g, m_b, ratio, rays, o0, o1, o2, d0, d1, d2, tfar)``: rays = shadow rays
    counted (0: none needed, V = 1); with rays = 1, V is the answer of the ray from o along the
    unit d up to tfar when tfar > 0, else 1 if m > 0 (a light closer than ray_offset) and 0 if
    m = 0 (the ray's origin does not see the light).
    """
    if gk[node, GK_LEFT] < 0 or (gn[node, GN_MIXED] == 0.0 and gn[node, GN_RS] == 0.0
                                 and gn[node, GN_RS + 1] == 0.0 and gn[node, GN_RS + 2] == 0.0):
        c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
        m0, m1, m2, ratio, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
            np.int64(light_f[j, LF_TYPE]), light_f[j, LF_POS], light_f[j, LF_POS + 1], light_f[j, LF_POS + 2],
            light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2], c2, gp[g, GP_POS],
            gp[g, GP_POS + 1], gp[g, GP_POS + 2], gp[g, GP_NRM], gp[g, GP_NRM + 1], gp[g, GP_NRM + 2],
            gp[g, GP_REFL], gp[g, GP_REFL + 1], gp[g, GP_REFL + 2], gp[g, GP_RD], gp[g, GP_RD + 1], gp[g, GP_RD + 2],
            gp[g, GP_RS], gp[g, GP_RS + 1], gp[g, GP_RS + 2], gp[g, GP_EXP], ray_offset)
        if not lit:
            return 0.0, 0.0, 0.0, 1.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        return m0, m1, m2, ratio, 1 if visibility else 0, o0, o1, o2, d0, d1, d2, tfar
    typ = np.int64(light_f[j, LF_TYPE])
    c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
    p0, p1, p2 = light_f[j, LF_POS], light_f[j, LF_POS + 1], light_f[j, LF_POS + 2]
    l0, l1, l2 = light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2]
    w0, w1, w2, _, geo, ratio = light_geometry(typ, p0, p1, p2, l0, l1, l2, gp[g, GP_POS], gp[g, GP_POS + 1],
                                               gp[g, GP_POS + 2], c2)
    if geo <= 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    weight = 0.0
    s = g if gp[g, GP_NRM] * w0 + gp[g, GP_NRM + 1] * w1 + gp[g, GP_NRM + 2] * w2 > 0.0 else np.int64(-1)
    for t in range(gk[node, GK_FIRST], gk[node, GK_LAST]):
        i = gidx[t]
        a0, a1, a2 = material_term(gp[i, GP_NRM], gp[i, GP_NRM + 1], gp[i, GP_NRM + 2], gp[i, GP_REFL],
                                   gp[i, GP_REFL + 1], gp[i, GP_REFL + 2], gp[i, GP_RD], gp[i, GP_RD + 1],
                                   gp[i, GP_RD + 2], gp[i, GP_RS], gp[i, GP_RS + 1], gp[i, GP_RS + 2],
                                   gp[i, GP_EXP], w0, w1, w2)
        wi = gp[i, GP_W]
        weight += wi
        m0 += wi * a0
        m1 += wi * a1
        m2 += wi * a2
        if s < 0 and (a0 > 0.0 or a1 > 0.0 or a2 > 0.0):
            s = i
    if s < 0 or not (m0 > 0.0 or m1 > 0.0 or m2 > 0.0):
        return 0.0, 0.0, 0.0, 1.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    f = geo / weight
    m0, m1, m2 = m0 * f, m1 * f, m2 * f
    if not visibility:
        return m0, m1, m2, ratio, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # The shadow ray of light j from point s, as the leaf's (a unit diffuse material: lit wherever s
    # faces the light).
    _, _, _, _, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
        typ, p0, p1, p2, l0, l1, l2, c2, gp[s, GP_POS], gp[s, GP_POS + 1], gp[s, GP_POS + 2], gp[s, GP_NRM],
        gp[s, GP_NRM + 1], gp[s, GP_NRM + 2], gp[s, GP_REFL], gp[s, GP_REFL + 1], gp[s, GP_REFL + 2], 1.0, 1.0,
        1.0, 0.0, 0.0, 0.0, 0.0, ray_offset)
    if not lit:
        return 0.0, 0.0, 0.0, 1.0, 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return m0, m1, m2, ratio, 1, o0, o1, o2, d0, d1, d2, tfar
