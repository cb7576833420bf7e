r"""The spacing of a set of indirect VPLs: the radius of the surface patch each one stands for.

A particle tracer leaves VPLs on the surfaces it lights with a local density ``n`` (VPLs per unit
area); each VPL carries the light of about ``1 / n`` of surface around it, a disc of radius
``s = 1 / sqrt(pi n)``. Within a few ``s`` of a receiver the point-light estimate ``1 / d^2`` is
no longer an estimate of that patch's light (a Lambertian disc of radius ``s`` gives
``1 / (d^2 + s^2)`` on its axis), so ``s`` is the length the clamp radius is measured in
(docs/math.md, "Clamping"). ``n`` is estimated at a VPL as the photon map does (Jensen 1996): the
``k`` nearest other VPLs lie within ``d_k``, so ``n = k / (pi d_k^2)`` and ``s = d_k / sqrt(k)``.

:func:`vpl_spacing` is the median of ``s`` over up to ``QUERIES`` VPLs taken at a fixed stride
(their order is the particle tracer's, random in space): one number per light set, in the scene's
units, scaling with the scene and falling as ``1 / sqrt(N)`` with the VPL count in the same area.
Each query scans all N VPLs (brute force, ``QUERIES * N`` distances), so it costs about 0.1 s per
million VPLs on two cores.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: The neighbours of the density estimate.
NEIGHBOURS = 16
#: VPLs whose spacing is measured; the median's relative standard error is about 1.25 / sqrt(QUERIES)
#: times the spread of s.
QUERIES = 512


@njit(cache=True, parallel=True)
def kth_neighbour_distance(points, queries, k, out):
    """out[q] = distance from points[queries[q]] to its k-th nearest other point (the query itself
    left out by index, so duplicates count as distance 0). points : (N, 3) float64; queries : (M,)
    int64 rows of points; k : 1 to N - 1; out : (M,) float64."""
    n = points.shape[0]
    for q in prange(queries.shape[0]):
        i = queries[q]
        best = np.full(k, np.inf)  # sorted ascending squared distances
        x0, x1, x2 = points[i, 0], points[i, 1], points[i, 2]
        for j in range(n):
            if j == i:
                continue
            d0 = points[j, 0] - x0
            d1 = points[j, 1] - x1
            d2 = points[j, 2] - x2
            d = d0 * d0 + d1 * d1 + d2 * d2
            if d < best[k - 1]:
                m = k - 1
                while m > 0 and best[m - 1] > d:
                    best[m] = best[m - 1]
                    m -= 1
                best[m] = d
        out[q] = np.sqrt(best[k - 1])


def vpl_spacing(positions: np.ndarray, neighbours: int = NEIGHBOURS, queries: int = QUERIES) -> float:
    """The median spacing ``s = d_k / sqrt(k)`` of the VPLs at ``positions`` ((N, 3), world units;
    module docstring), with k = min(neighbours, N - 1); 0 for fewer than 2 VPLs (nothing to measure
    against). Deterministic: the measured VPLs are rows ``floor(j N / M)``, j < M = min(queries, N)."""
    p = np.ascontiguousarray(positions, np.float64).reshape(-1, 3)
    n = len(p)
    if n < 2:
        return 0.0
    k = min(int(neighbours), n - 1)
    m = min(int(queries), n)
    rows = (np.arange(m, dtype=np.int64) * n) // m
    d = np.empty(m)
    kth_neighbour_distance(p, rows, k, d)
    return float(np.median(d)) / float(np.sqrt(k))


def indirect_spacing(lights: dict) -> float:
    """:func:`vpl_spacing` of the indirect VPLs of every set of ``lights`` ({type: LightSet}) together."""
    parts = [ls.position[ls.indirect] for ls in lights.values() if len(ls) and ls.indirect.any()]
    return vpl_spacing(np.concatenate(parts)) if parts else 0.0
