r"""The built-in dissimilarities d(C) of the clustering engine: the cost of merging two clusters into
C = A u B (smaller merges first), dispatched on an integer id so that one compiled kd-tree search
and one set of clustering loops serve every one of them.

With I = C's scalar intensity, L = the diagonal of C's box, beta = C's cone half-angle and c = the
cone-term scale (world units):

==  ================  =====================================================================
id  kernel            d(C)
==  ================  =====================================================================
0   walter2008        I (L^2 + c^2 S^2)^2, S = sin(beta), 1 when beta >= 90 degrees
1   walter2005        I (L^2 + c^2 (1 - cos beta)^2)
2   surface_area      surface area of C's box (Walter et al. 2008, section 4: the BVH metric)
==  ================  =====================================================================

Without a cone (``has_cone`` False) walter2008 is I L^4 and walter2005 I L^2. Every kernel grows
with each extent of C's box, with I and with the cone's width (for these cones: docs/math.md), so
evaluated on the kd-tree's per-axis lower bounds of the union's extents (and lower bound of I and
of the cone) it bounds d(A u B) from below for every B under a kd node
(:func:`lightcuts.cluster.kd_search.kd_best_match`). A new dissimilarity with that property is a
new id here. The light-tree registry of metrics names them (``lightcuts.trees.metrics``).
"""

from __future__ import annotations

from numba import njit

from lightcuts.cluster.cones import cone_sine

WALTER2008 = 0
WALTER2005 = 1
SURFACE_AREA = 2


@njit(cache=True)
def walter2008(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
    """I (L^2 + c^2 S^2)^2, S = sin(beta) (1 past 90 degrees); no cone term without a cone."""
    dx = hi0 - lo0
    dy = hi1 - lo1
    dz = hi2 - lo2
    t = dx * dx + dy * dy + dz * dz
    if has_cone:
        s = cone_sine(cone_cos)
        t += c * c * s * s
    return intensity * t * t


@njit(cache=True)
def walter2005(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
    """I (L^2 + c^2 (1 - cos beta)^2); no cone term without a cone."""
    dx = hi0 - lo0
    dy = hi1 - lo1
    dz = hi2 - lo2
    t = dx * dx + dy * dy + dz * dz
    if has_cone:
        w = 1.0 - cone_cos
        t += c * c * w * w
    return intensity * t


@njit(cache=True)
def surface_area(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
    """Surface area of the box (intensity and cone unused)."""
    dx = hi0 - lo0
    dy = hi1 - lo1
    dz = hi2 - lo2
    return 2.0 * (dx * dy + dy * dz + dz * dx)


@njit(cache=True)
def metric_eval(metric_id, intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c):
    """Cost d(C) of the cluster C = A u B, for a built-in dissimilarity.

    metric_id : int, WALTER2008 (0), WALTER2005 (1) or SURFACE_AREA (2)
    intensity : C's scalar intensity (luminance of the summed RGB), >= 0
    lo0..hi2 : C's box (world units; directional lights: box over unit directions)
    cone_cos : cosine of C's cone half-angle (-1 for the full sphere)
    has_cone : False for clusters without normals (no cone term)
    c : cone-term scale, world units
    """
    if metric_id == WALTER2008:
        return walter2008(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)
    if metric_id == WALTER2005:
        return walter2005(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)
    if metric_id == SURFACE_AREA:
        return surface_area(intensity, lo0, lo1, lo2, hi0, hi1, hi2, cone_cos, has_cone, c)
    raise ValueError("metric_eval: not a built-in metric id")
