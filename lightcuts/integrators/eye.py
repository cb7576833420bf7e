r"""The start of every eye path: what an eye ray sees before any light is gathered.

One device function shared by the lightcut kernel (lightcuts.integrators.lightcut), the gather points of
multidimensional lightcuts (lightcuts.integrators.multidim.gather) and the path tracer
(lightcuts.integrators.path), so all three agree on the first hit: a miss shows the environment map's
radiance (black without one); the front of an emitter shows its emitted radiance and is shaded like
any surface (it reflects light too); its back is black and ends the path (emitters are one-sided and
absorb, as in lightcuts.lights.indirect); any other hit is shaded. Surfaces are two-sided.

numba caches the kernels that call this keyed on their own modules' files: after editing it, delete
``lightcuts/integrators/**/__pycache__/*.nb[ic]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import intersect
from lightcuts.lights.environment import envmap_radiance


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def eye_hit(cdata, buf, o0, o1, o2, d0, d1, d2, face_normal, emission, env_pixels, env_rotation, env_scale):
    """Cast the eye ray from (o0, o1, o2) along the unit (d0, d1, d2): ``(t, prim, r, g, b)``.

    cdata, buf : the kernel caster's data and scratch (lightcuts.accel.kernel_api); face_normal,
    emission : the scene's (F, 3) per-triangle arrays; env_pixels, env_rotation, env_scale : the
    environment map (env_pixels (0, 0, 3): none). ``prim`` is the triangle to shade at distance
    ``t``, or -1 when there is none (a miss, or the back of an emitter); ``(r, g, b)`` is the
    radiance the ray sees directly (the environment's on a miss, an emitter front's own emission,
    else 0), to be added to the eye ray's estimate before any shading.
    """
    t, prim = intersect(cdata, buf, o0, o1, o2, d0, d1, d2, 0.0, np.inf)
    if prim < 0:
        if env_pixels.shape[0] > 0:
            e0, e1, e2 = envmap_radiance(env_pixels, env_rotation, env_scale, d0, d1, d2)
            return t, -1, e0, e1, e2
        return t, -1, 0.0, 0.0, 0.0
    e0, e1, e2 = emission[prim, 0], emission[prim, 1], emission[prim, 2]
    if e0 > 0.0 or e1 > 0.0 or e2 > 0.0:
        if face_normal[prim, 0] * d0 + face_normal[prim, 1] * d1 + face_normal[prim, 2] * d2 >= 0.0:
            return t, -1, 0.0, 0.0, 0.0  # the back of an emitter is black (it absorbs)
        return t, prim, e0, e1, e2
    return t, prim, 0.0, 0.0, 0.0
