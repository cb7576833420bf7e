r"""The brute-force reference: every light at every receiver, one shadow ray per light.

The same shading as the lightcut (lightcuts.integrators.shading, the same shadow rays, clamping and eye
rays): only the sum over lights differs. ``render_reference`` (lightcuts.integrators.lightcut) runs this
instead of the cut, so a lightcuts image and its reference differ only by the cut's approximation.
"""

from __future__ import annotations

from numba import njit

from lightcuts.integrators.cut import light_mgv, luminance


@njit(cache=True, error_model="numpy")
def all_lights(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, light_f, light_i,
               clamp_d2, ray_offset, visibility, cdata, buf):
    """Radiance reflected at x towards the viewer: the sum of ``M G V I`` over every light.

    Arguments as lightcuts.integrators.cut.light_mgv, plus light_i : (L, 3) the lights' RGB intensities.
    Returns ``(L_r, L_g, L_b, n_lights, shadow_rays, clamp_lost)`` like lightcuts.integrators.cut.lightcut
    (clamp_lost exact here: the luminance that clamping removed).
    """
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    rays = 0
    for j in range(light_f.shape[0]):
        m0, m1, m2, ratio, nr = light_mgv(j, light_f, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2,
                                          rs0, rs1, rs2, exponent, clamp_d2, ray_offset, visibility,
                                          cdata, buf)
        rays += nr
        e0 = m0 * light_i[j, 0]
        e1 = m1 * light_i[j, 1]
        e2 = m2 * light_i[j, 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (ratio - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, light_f.shape[0], rays, lost
