r"""The ``saoh`` builder: top-down splits by the surface-area-orientation heuristic.

Conty Estevez and Kulla 2018 ("Importance sampling of many lights with adaptive tree splitting"),
as pbrt-v4's BVHLightSampler applies it. Each node's lights are binned by position into
``BUCKETS = 12`` equal slices of the node's box along each axis; each of the 11 boundaries between
slices, on each axis of nonzero extent, is a candidate split (lights in slices ``<= i`` go left).
A candidate costs

    Kr * (C(left) + C(right)),   C(side) = phi * M_Omega(theta_o, theta_e) * SA(box),
    Kr = max extent of the node's box / its extent along the split axis,

with phi the side's summed luminance, SA the surface area of the box of its positions, and

    theta_w = min(theta_o + theta_e, pi),
    M_Omega = 2 pi (1 - cos theta_o)
              + pi/2 (2 theta_w sin theta_o - cos(theta_o - 2 theta_w) - 2 theta_o sin theta_o + cos theta_o).

Oriented lights emit over a hemisphere around the normal, theta_e = pi/2, and theta_o is the
half-angle of the side's normal cone taken from the box of its unit normals
(:func:`~lightcuts.cluster.cones.cone_from_box`), the cone ``build_tree`` gives the node, so the
heuristic judges the bound the render will use (M_Omega in its reduced form, :func:`m_omega`).
Omni lights have theta_o = pi, so M_Omega = 4 pi for every side. Directional lights are
clustered by direction (their ``position`` is the unit direction, as for every builder) and have
no orientation term either: M_Omega = 4 pi.

The least cost wins; ties go to the lowest axis, then the lowest boundary. A candidate that leaves
a side empty is not a split and is not considered. The longest axis has Kr = 1 and, within
lightcuts.limits, finite costs, so a node whose lights are not all at one point
always has a candidate; a thin axis's Kr can overflow (a subnormal extent), and its infinite costs
are never chosen. A node whose lights share one position is split evenly by index, so the tree is
binary with single-light leaves and 2N-1 nodes for any input. Lights with the same position are
separated only by that fallback. Collinear lights make every box flat in two axes, so every
candidate costs 0 and the first valid boundary wins.

The stack loop, the depth-first node ids and the threads are the top-down driver's
(:mod:`lightcuts.trees.topdown`, shared with the divisive builders): a node over rows s..e-1 split at
row m has children ``node + 1`` and ``node + 2 (m - s)``, so subtrees below the top levels are built
on the numba threads with the same result as on one. Each node reads its lights once per axis to
bin them and once to partition them: O(N) per tree level.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import EMPTY_HI, EMPTY_LO, box_grow, points_box, row3
from lightcuts.cluster.cones import cone_from_box
from lightcuts.trees.registry import BUILDERS
from lightcuts.trees.topdown import register_split, split_subtrees, top_down

#: Slices per axis; BUCKETS - 1 candidate boundaries per axis.
BUCKETS = 12
# Below this many lights the build runs on one thread (thread start-up would cost more).
_PARALLEL_MIN = 20000
# Columns of a slice's statistics: count, phi, position box (lo, hi), normal box (lo, hi).
_FIELDS = 14


@njit(cache=True)
def m_omega(cos_o):
    """M_Omega of a cone of normals with ``cos(theta_o) = cos_o`` for cosine emitters (theta_e = pi/2).

    The general formula with theta_w = min(theta_o + pi/2, pi) reduces to
    ``2 pi - pi cos_o + pi^2 / 2 sin_o`` for theta_o <= pi/2 and to
    ``2 pi (1 - cos_o) + pi sin_o (pi - theta_o)`` beyond (docs/math.md, "SAOH builder"):
    pi for a single normal, 4 pi for the full sphere, no arccos below 90 degrees.
    """
    c = min(1.0, max(-1.0, cos_o))
    sin_o = np.sqrt(max(0.0, 1.0 - c * c))
    if c >= 0.0:
        return 2.0 * np.pi - np.pi * c + 0.5 * np.pi * np.pi * sin_o
    return 2.0 * np.pi * (1.0 - c) + np.pi * sin_o * (np.pi - np.arccos(c))


@njit(cache=True)
def _bucket(p, lo, ext):
    """Slice of coordinate p in [lo, lo + ext], ext > 0: 0..BUCKETS-1 (p = lo + ext is in the last).
    (p - lo) / ext <= 1 exactly, so no overflow for any finite ext."""
    return min(int(BUCKETS * ((p - lo) / ext)), BUCKETS - 1)


@njit(cache=True)
def _side_cost(st, oriented):
    """C = phi * M_Omega * SA of one side's statistics row ``st`` (see _FIELDS)."""
    dx = st[5] - st[2]
    dy = st[6] - st[3]
    dz = st[7] - st[4]
    area = 2.0 * (dx * dy + dy * dz + dz * dx)
    if not oriented:
        return st[1] * (4.0 * np.pi) * area
    if area == 0.0 or st[1] == 0.0:
        return 0.0
    cos_o = cone_from_box(st[8], st[9], st[10], st[11], st[12], st[13])[3]
    return st[1] * m_omega(cos_o) * area


@njit(cache=True)
def _merge(acc, st):
    """acc <- acc u st (statistics rows)."""
    acc[0] += st[0]
    acc[1] += st[1]
    for d in range(3):
        acc[2 + d] = min(acc[2 + d], st[2 + d])
        acc[5 + d] = max(acc[5 + d], st[5 + d])
        acc[8 + d] = min(acc[8 + d], st[8 + d])
        acc[11 + d] = max(acc[11 + d], st[11 + d])


@njit(cache=True)
def _clear(st):
    """The empty statistics row: no lights, empty boxes."""
    st[0] = 0.0
    st[1] = 0.0
    for d in range(3):
        st[2 + d] = np.inf
        st[5 + d] = -np.inf
        st[8 + d] = np.inf
        st[11 + d] = -np.inf


@njit(cache=True)
def _bin(pos, nrm, lum, s, e, a, lo, ext, oriented, stats):
    """Statistics rows ``stats`` (BUCKETS, _FIELDS) of the slices of rows s..e-1 along axis a
    (lower end lo, extent ext > 0); one pass per axis."""
    for b in range(BUCKETS):
        _clear(stats[b])
    for t in range(s, e):
        b = _bucket(pos[t, a], lo, ext)
        stats[b, 0] += 1.0
        stats[b, 1] += lum[t]
        for d in range(3):
            stats[b, 2 + d] = min(stats[b, 2 + d], pos[t, d])
            stats[b, 5 + d] = max(stats[b, 5 + d], pos[t, d])
        if oriented:
            for d in range(3):
                stats[b, 8 + d] = min(stats[b, 8 + d], nrm[t, d])
                stats[b, 11 + d] = max(stats[b, 11 + d], nrm[t, d])


@njit(cache=True)
def _costs(pos, nrm, lum, s, e, lo, hi, oriented, stats, acc, sides, costs):
    """Fill ``costs`` (3, BUCKETS - 1) with the cost of every candidate split of rows s..e-1 (box
    lo, hi): inf for an axis of zero extent or a boundary with an empty side.

    stats : (3, BUCKETS, _FIELDS), acc : (2, _FIELDS), sides : (2, BUCKETS - 1) scratch
    Returns (axis, boundary) of the least finite cost (first on ties), or (-1, -1) if none.
    """
    ext = (hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
    for a in range(3):
        if ext[a] > 0.0:
            _bin(pos, nrm, lum, s, e, a, lo[a], ext[a], oriented, stats[a])
    max_ext = max(ext[0], max(ext[1], ext[2]))
    best = np.inf
    best_axis = -1
    best_bound = -1
    for a in range(3):
        for i in range(BUCKETS - 1):
            costs[a, i] = np.inf
        if not ext[a] > 0.0:
            continue
        kr = max_ext / ext[a]
        # Forward scan: each boundary's left count and cost into sides; backward scan: the right
        # side's. A side's cost is computed again only when an occupied slice joins it.
        _clear(acc[0])
        c = 0.0
        for i in range(BUCKETS - 1):
            if stats[a, i, 0] > 0.0:
                _merge(acc[0], stats[a, i])
                c = _side_cost(acc[0], oriented)
            sides[0, i] = acc[0, 0]
            sides[1, i] = c
        _clear(acc[1])
        c = 0.0
        for i in range(BUCKETS - 1, 0, -1):
            if stats[a, i, 0] > 0.0:
                _merge(acc[1], stats[a, i])
                c = _side_cost(acc[1], oriented)
            if sides[0, i - 1] > 0.0 and acc[1, 0] > 0.0:
                costs[a, i - 1] = kr * (sides[1, i - 1] + c)
        for i in range(BUCKETS - 1):
            if costs[a, i] < best:
                best = costs[a, i]
                best_axis = a
                best_bound = i
    return best_axis, best_bound


@njit(cache=True)
def _swap(pos, nrm, lum, perm, i, t):
    """Exchange rows i and t of every per-light array (nrm has no rows but for oriented lights)."""
    for d in range(3):
        q = pos[t, d]
        pos[t, d] = pos[i, d]
        pos[i, d] = q
    if nrm.shape[0] > 0:
        for d in range(3):
            q = nrm[t, d]
            nrm[t, d] = nrm[i, d]
            nrm[i, d] = q
    q = lum[t]
    lum[t] = lum[i]
    lum[i] = q
    k = perm[t]
    perm[t] = perm[i]
    perm[i] = k


@njit(cache=True)
def _split(pos, nrm, lum, perm, s, e, lo, hi, oriented, stats, acc, sides, costs):
    """Split rows s..e-1 (box lo, hi) at the least-cost candidate, or evenly by index if there is
    none. Returns the split row m and the position boxes of rows s..m-1 and m..e-1."""
    axis, bound = _costs(pos, nrm, lum, s, e, lo, hi, oriented, stats, acc, sides, costs)
    if axis < 0:
        m = s + (e - s) // 2
        llo, lhi = points_box(pos, s, m)
        rlo, rhi = points_box(pos, m, e)
        return m, llo, lhi, rlo, rhi
    ext = hi[axis] - lo[axis]
    llo = rlo = EMPTY_LO
    lhi = rhi = EMPTY_HI
    i = s
    for t in range(s, e):
        p = row3(pos, t, 0)
        if _bucket(p[axis], lo[axis], ext) <= bound:
            _swap(pos, nrm, lum, perm, i, t)
            i += 1
            llo, lhi = box_grow(llo, lhi, p)
        else:
            rlo, rhi = box_grow(rlo, rhi, p)
    return i, llo, lhi, rlo, rhi


@njit(cache=True)
def _box_row(b, j):
    """Row j of a (M, 6) box array as (lo, hi) 3-tuples."""
    return row3(b, j, 0), row3(b, j, 3)


class _Rows(NamedTuple):
    """What :func:`_split` reads besides (perm, s, e, lo, hi): the lights' arrays, then the oriented
    flag and the scratch."""
    head: tuple
    tail: tuple


register_split(_Rows, _split, _box_row)


@njit(cache=True, nogil=True)
def _subtrees(pos, nrm, lum, perm, oriented, tasks, boxes, cut, left, right, light):
    """The subtrees of ``tasks`` over rows of the lights' arrays, split by :func:`_split`
    (:func:`~lightcuts.trees.topdown.split_subtrees`), with this call's scratch."""
    stats = np.empty((3, BUCKETS, _FIELDS))
    acc = np.empty((2, _FIELDS))
    sides = np.empty((2, BUCKETS - 1))
    costs = np.empty((3, BUCKETS - 1))
    return split_subtrees(_Rows((pos, nrm, lum), (oriented, stats, acc, sides, costs)), perm, tasks, boxes, cut,
                          left, right, light)


def _arrays(position, normal, luminance, light_type):
    """Working copies (rows are permuted in place) and the oriented flag."""
    oriented = light_type == "oriented"
    pos = np.array(position, np.float64, order="C").reshape(-1, 3)
    nrm = np.array(normal, np.float64, order="C").reshape(-1, 3) if oriented else np.zeros((0, 3))
    lum = np.array(luminance, np.float64).reshape(-1)
    return pos, nrm, lum, oriented


def split_costs(position, normal, luminance, light_type: str) -> np.ndarray:
    """(3, BUCKETS - 1) float64: the cost of every candidate split of the whole light set, as the
    root's split compares them (inf: an axis of zero extent or a boundary with an empty side).

    position, normal : (N, 3) float64 (normals read for oriented lights only); luminance : (N,)
    """
    pos, nrm, lum, oriented = _arrays(position, normal, luminance, light_type)
    lo, hi = points_box(pos, 0, len(pos))
    costs = np.empty((3, BUCKETS - 1))
    _costs(pos, nrm, lum, 0, len(pos), lo, hi, oriented, np.empty((3, BUCKETS, _FIELDS)),
           np.empty((2, _FIELDS)), np.empty((2, BUCKETS - 1)), costs)
    return costs


@BUILDERS.register("saoh", reads=(), compare_row=5)
def saoh(position, normal, luminance, light_type, metric, c, seed):
    """Top-down splits by the surface-area-orientation heuristic (Conty Estevez and Kulla 2018)."""
    pos, nrm, lum, oriented = _arrays(position, normal, luminance, light_type)
    n = len(pos)
    perm = np.arange(n, dtype=np.int32)
    lo, hi = points_box(pos, 0, n)
    box = np.array([lo + hi], np.float64)
    left, right, light = top_down(n, lambda *a: _subtrees(pos, nrm, lum, perm, oriented, *a), box, _PARALLEL_MIN)
    return left, right, light, 0
