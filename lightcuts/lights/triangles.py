"""The scene's emitting triangles as a light set that light trees sample (one light a triangle).

A triangle t of area ``A_t`` and one-sided radiance ``Le_t`` along its normal becomes an
``oriented`` light at its centroid with intensity ``I_t = Le_t * A_t`` (W/sr along the normal), so
its power ``pi * I_t`` is the triangle's and a builder clusters it by the same metric as a VPL.
A tree over these lights is only a way to *choose* a triangle: the estimator that draws one then
takes a uniform point on it (lightcuts.integrators.path), which makes direct light from area
emitters unbiased without pre-placed point lights. Because a triangle is not a point, its leaf's
box is the triangle's box (``lo``, ``hi``), not the centroid's, and the sampling forest refits
every node's box to them (lightcuts.integrators.light_sampler). Emission is constant per triangle in
lightcuts' scenes (no emission textures), so a triangle's power is exact.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from lightcuts.lights.lightset import LUMINANCE, LightSet


#: The light-set meta key whose value ``triangles`` says that the first ``count_direct`` lights of
#: the ``oriented`` set are :func:`triangle_lights` of the scene (lightcuts.lights.generate).
TRIANGLES_META = "direct_source"


def leading_triangles(lights: LightSet) -> int:
    """How many of the set's first lights are the scene's emitting triangles (0 unless its meta says
    so, as the lights stage writes it for ``lights.direct.source: triangles``)."""
    if lights.type != "oriented" or lights.meta.get(TRIANGLES_META) != "triangles":
        return 0
    return int(lights.meta.get("count_direct", 0))


class TriangleLights(NamedTuple):
    """lights : LightSet (``oriented``), one light per emitting triangle of non-zero power;
    tri : (N,) int64 the scene's triangle id of light i; lo, hi : (N, 3) float64 the triangle's box."""

    lights: LightSet
    tri: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def triangle_lights(scene) -> TriangleLights:
    """The emitting triangles of ``scene`` (a lightcuts.scene.Scene) with non-zero power, in the
    order of their triangle ids; an empty set if it has none."""
    tri = scene.emitters
    le = scene.emission[tri]
    area = scene.face_areas[tri]
    keep = area * (le @ LUMINANCE) > 0.0
    tri, le, area = tri[keep], le[keep], area[keep]
    corners = scene.triangles[tri]
    meta = {"scene": scene.name, "diagonal": float(scene.diagonal), "emitting_triangles": len(tri)}
    lights = LightSet(corners.mean(axis=1), scene.face_normals[tri], le * area[:, None], "oriented", meta=meta)
    return TriangleLights(lights, np.ascontiguousarray(tri, np.int64), corners.min(axis=1), corners.max(axis=1))
