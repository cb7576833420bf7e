r"""Gather points of one pixel: the hits of its ``spp`` eye rays (pixel strata, thin lens).

A gather point is one eye-ray hit that reflects light: its row in ``gp`` ((spp, GP_WIDTH) float64
scratch) holds position, unit shading normal N (facing the eye), mirror direction R of wo,
RGB rho_d and rho_s, Phong exponent and weight 1 / spp (its share of the pixel). Each eye ray starts
as every integrator's does (lightcuts.integrators.eye): misses (the environment map) and the fronts of
emitters (their emitted radiance) add radiance directly; the front of an emitter is a gather point
too (it reflects light), its back is black and is none.
"""

from __future__ import annotations

from numba import njit

from lightcuts.integrators.camera import lens_ray
from lightcuts.integrators.eye import eye_hit
from lightcuts.integrators.shading import facing_normal, reflect
from lightcuts.scene.textures import albedo_at

# Columns of a gather point's row: position, normal, mirror direction, rho_d, rho_s, exponent, weight.
GP_POS, GP_NRM, GP_REFL, GP_RD, GP_RS, GP_EXP, GP_W, GP_WIDTH = 0, 3, 6, 9, 12, 15, 16, 17


@njit(cache=True, error_model="numpy")
def pixel_gather(cdata, buf, cam, seed, spp, sx, sy, px, py, aperture, focus, face_normal, albedo, tex,
                 specular, exponent, emission, env_pixels, env_rotation, env_scale, gp):
    """Cast pixel (px, py)'s eye rays and fill gp's first rows with its gather points.

    cam, seed, spp, sx, sy : as lightcuts.integrators.camera.eye_ray; aperture, focus : the thin lens
    (lightcuts.integrators.camera.lens_ray, 0: pinhole); face_normal, albedo, specular, exponent,
    emission : the scene's per-triangle arrays, tex its textures (lightcuts.scene.textures.albedo_at); env_* : the environment map ((0, 0, 3): none).
    Returns ``(n, r, g, b)``: the number of gather points and the radiance added directly, summed
    over the eye rays (not yet divided by spp).
    """
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    n = 0
    w = 1.0 / spp
    for s in range(spp):
        o0, o1, o2, d0, d1, d2 = lens_ray(cam, seed, px, py, s, sx, sy, aperture, focus)
        t, prim, e0, e1, e2 = eye_hit(cdata, buf, o0, o1, o2, d0, d1, d2, face_normal, emission, env_pixels,
                                      env_rotation, env_scale)
        a0 += e0
        a1 += e1
        a2 += e2
        if prim < 0:
            continue
        f0, f1, f2 = face_normal[prim, 0], face_normal[prim, 1], face_normal[prim, 2]
        n0, n1, n2 = facing_normal(f0, f1, f2, -d0, -d1, -d2)
        r0, r1, r2 = reflect(-d0, -d1, -d2, n0, n1, n2)
        row = gp[n]
        row[GP_POS], row[GP_POS + 1], row[GP_POS + 2] = o0 + t * d0, o1 + t * d1, o2 + t * d2
        row[GP_NRM], row[GP_NRM + 1], row[GP_NRM + 2] = n0, n1, n2
        row[GP_REFL], row[GP_REFL + 1], row[GP_REFL + 2] = r0, r1, r2
        row[GP_RD], row[GP_RD + 1], row[GP_RD + 2] = albedo_at(albedo, tex, prim, o0 + t * d0, o1 + t * d1,
                                                               o2 + t * d2)
        for c in range(3):
            row[GP_RS + c] = specular[prim, c]
        row[GP_EXP] = exponent[prim]
        row[GP_W] = w
        n += 1
    return n, a0, a1, a2
