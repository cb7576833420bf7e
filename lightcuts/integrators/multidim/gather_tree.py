r"""The gather tree of one pixel: a divisive binary tree over its gather points, in scratch arrays.

Leaves are the gather points themselves (node i = point i, i < n); inner nodes are n .. 2n - 2,
the root is node n (node 0 when n = 1), and a child always has a larger id than its parent, so
bounds are filled by one pass from the last node to the root. A node is split at the middle of the
longest axis of its 6D box (position, and normal scaled by the root box's diagonal, as the
divisive-6d light-tree builder does); points on one spot are split evenly by index. Per node
(``GN_*`` columns of ``gn``, (2 spp, GN_WIDTH) float64): position box, box of normals and its cone,
box of mirror directions and its cone, per-channel maximum rho_d and rho_s, exponent range, summed
weight, the half-angle of the normal cone (the refinement rule's size) and whether its points differ
in normal or rho_d (1.0) or not (0.0: the pair estimate may shade them all as one); ``gk`` ((2 spp, GK_WIDTH)
int64): children, the representative gather point and, for an inner node, the range
``idx[first:last]`` of the build's ``idx`` that lists its points (the pair estimate sums their
materials); chosen as lightcuts chooses light
representatives (the left child's with probability W_left / W, else the right one's), seeded per
pixel and node. Cones come from boxes of unit vectors (docs/math.md, "Normal cones from a box of
normals"), so each holds every normal of its points.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.camera import hash_uniform
from lightcuts.integrators.multidim.gather import GP_EXP, GP_NRM, GP_POS, GP_RD, GP_REFL, GP_RS, GP_W

(GN_LO, GN_HI, GN_NLO, GN_NHI, GN_RLO, GN_RHI, GN_NAX, GN_NCOS, GN_RAX, GN_RCOS, GN_RD, GN_RS, GN_EMIN,
 GN_EMAX, GN_W, GN_ANG, GN_MIXED, GN_WIDTH) = 0, 3, 6, 9, 12, 15, 18, 21, 22, 25, 26, 29, 32, 33, 34, 35, 36, 37
GK_LEFT, GK_RIGHT, GK_REP, GK_FIRST, GK_LAST, GK_WIDTH = 0, 1, 2, 3, 4, 5
#: Seed offset of the representatives' random numbers (the eye rays use the run seed itself).
REP_SEED = 0x5EED


@njit(cache=True, error_model="numpy")
def box_cone(lo0, lo1, lo2, hi0, hi1, hi2):
    """(axis, cos(half-angle)) of a cone holding every unit vector in the box [lo, hi]; cos = -1:
    the whole sphere. Rounded outwards by 1e-12 in cos."""
    m0, m1, m2 = 0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2)
    r2 = 0.25 * ((hi0 - lo0) ** 2 + (hi1 - lo1) ** 2 + (hi2 - lo2) ** 2)
    d = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    if d <= 0.0:
        return 0.0, 0.0, 1.0, -1.0
    c = (1.0 + d * d - r2) / (2.0 * d)
    if r2 == 0.0:
        c = 1.0
    c = min(1.0, c - 1e-12)
    if c <= -1.0:
        return m0 / d, m1 / d, m2 / d, -1.0
    return m0 / d, m1 / d, m2 / d, c


@njit(cache=True, error_model="numpy")
def _split(gp, idx, s, e, scale):
    """Partition idx[s:e] at the middle of the longest axis of its 6D box; returns the cut m."""
    best = -1.0
    axis = 0
    mid = 0.0
    for a in range(6):
        col = GP_POS + a if a < 3 else GP_NRM + a - 3
        f = 1.0 if a < 3 else scale
        lo = np.inf
        hi = -np.inf
        for t in range(s, e):
            v = gp[idx[t], col] * f
            lo = min(lo, v)
            hi = max(hi, v)
        if hi - lo > best:
            best = hi - lo
            axis = a
            mid = 0.5 * (lo + hi)
    m = s
    if best > 0.0:
        col = GP_POS + axis if axis < 3 else GP_NRM + axis - 3
        f = 1.0 if axis < 3 else scale
        for t in range(s, e):
            if gp[idx[t], col] * f < mid:
                idx[t], idx[m] = idx[m], idx[t]
                m += 1
    if m == s or m == e:
        m = (s + e) // 2
    return m


@njit(cache=True, error_model="numpy")
def _leaf(gp, gn, gk, i):
    for c in range(3):
        gn[i, GN_LO + c] = gp[i, GP_POS + c]
        gn[i, GN_HI + c] = gp[i, GP_POS + c]
        gn[i, GN_NLO + c] = gp[i, GP_NRM + c]
        gn[i, GN_NHI + c] = gp[i, GP_NRM + c]
        gn[i, GN_RLO + c] = gp[i, GP_REFL + c]
        gn[i, GN_RHI + c] = gp[i, GP_REFL + c]
        gn[i, GN_NAX + c] = gp[i, GP_NRM + c]
        gn[i, GN_RAX + c] = gp[i, GP_REFL + c]
        gn[i, GN_RD + c] = gp[i, GP_RD + c]
        gn[i, GN_RS + c] = gp[i, GP_RS + c]
    gn[i, GN_NCOS] = 1.0
    gn[i, GN_RCOS] = 1.0
    gn[i, GN_EMIN] = gp[i, GP_EXP]
    gn[i, GN_EMAX] = gp[i, GP_EXP]
    gn[i, GN_W] = gp[i, GP_W]
    gn[i, GN_ANG] = 0.0
    gn[i, GN_MIXED] = 0.0
    gk[i, GK_LEFT] = -1
    gk[i, GK_RIGHT] = -1
    gk[i, GK_REP] = i
    gk[i, GK_FIRST] = -1
    gk[i, GK_LAST] = -1


@njit(cache=True, error_model="numpy")
def _union(gp, gn, gk, k, a, b, seed, pixel):
    for c in range(3):
        for lo, hi in ((GN_LO, GN_HI), (GN_NLO, GN_NHI), (GN_RLO, GN_RHI)):
            gn[k, lo + c] = min(gn[a, lo + c], gn[b, lo + c])
            gn[k, hi + c] = max(gn[a, hi + c], gn[b, hi + c])
        gn[k, GN_RD + c] = max(gn[a, GN_RD + c], gn[b, GN_RD + c])
        gn[k, GN_RS + c] = max(gn[a, GN_RS + c], gn[b, GN_RS + c])
    for lo, ax, cs in ((GN_NLO, GN_NAX, GN_NCOS), (GN_RLO, GN_RAX, GN_RCOS)):
        hi = lo + 3
        x0, x1, x2, cc = box_cone(gn[k, lo], gn[k, lo + 1], gn[k, lo + 2], gn[k, hi], gn[k, hi + 1], gn[k, hi + 2])
        gn[k, ax], gn[k, ax + 1], gn[k, ax + 2], gn[k, cs] = x0, x1, x2, cc
    gn[k, GN_EMIN] = min(gn[a, GN_EMIN], gn[b, GN_EMIN])
    gn[k, GN_EMAX] = max(gn[a, GN_EMAX], gn[b, GN_EMAX])
    wa, wb = gn[a, GN_W], gn[b, GN_W]
    gn[k, GN_W] = wa + wb
    gn[k, GN_ANG] = np.arccos(max(-1.0, min(1.0, gn[k, GN_NCOS])))
    gk[k, GK_LEFT] = a
    gk[k, GK_RIGHT] = b
    # Both children uniform and their representatives alike: so are all the points.
    mixed = gn[a, GN_MIXED] > 0.0 or gn[b, GN_MIXED] > 0.0
    ra, rb = gk[a, GK_REP], gk[b, GK_REP]
    for c in range(3):
        mixed = mixed or gp[ra, GP_NRM + c] != gp[rb, GP_NRM + c] or gp[ra, GP_RD + c] != gp[rb, GP_RD + c]
    gn[k, GN_MIXED] = 1.0 if mixed else 0.0
    u = hash_uniform(seed + REP_SEED, pixel, k, 0)
    gk[k, GK_REP] = gk[a, GK_REP] if u * (wa + wb) < wa else gk[b, GK_REP]


@njit(cache=True, error_model="numpy")
def build_gather_tree(gp, n, gn, gk, idx, stack, seed, pixel):
    """Build the tree over gp's first n rows (n >= 1) into gn, gk; returns the root's id.

    idx : (>= n,) int64, the points in the tree's order on return (an inner node's are
    ``idx[gk[k, GK_FIRST]:gk[k, GK_LAST]]``); stack : (>= 2 n, 3) int64 scratch; seed, pixel : the run seed and
    the pixel's index in the full image (the representatives' random numbers).
    """
    for i in range(n):
        _leaf(gp, gn, gk, i)
        idx[i] = i
    if n == 1:
        return 0
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(n):
        for c in range(3):
            lo[c] = min(lo[c], gp[i, GP_POS + c])
            hi[c] = max(hi[c], gp[i, GP_POS + c])
    scale = np.sqrt(((hi - lo) ** 2).sum())
    if not scale > 0.0:
        scale = 1.0
    nxt = n + 1
    top = 1
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, n, n
    while top > 0:
        top -= 1
        s, e, k = stack[top, 0], stack[top, 1], stack[top, 2]
        m = _split(gp, idx, s, e, scale)
        gk[k, GK_FIRST], gk[k, GK_LAST] = s, e
        for side in range(2):
            a, b = (s, m) if side == 0 else (m, e)
            if b - a == 1:
                child = idx[a]
            else:
                child = nxt
                nxt += 1
                stack[top, 0], stack[top, 1], stack[top, 2] = a, b, child
                top += 1
            gk[k, GK_LEFT + side] = child
    for k in range(2 * n - 2, n - 1, -1):
        _union(gp, gn, gk, k, gk[k, GK_LEFT], gk[k, GK_RIGHT], seed, pixel)
    return n


@njit(cache=True, error_model="numpy")
def gather_representatives(gn, gk, idx, n, seed, pixel, greps):
    """greps ((>= 2n - 1, R) int64): R representative gather points (columns) per node of the tree
    over n points, stratified and nested (docs/math.md, "Gather representatives").

    The root's columns go round its points in the tree's order (``idx``, as returned by
    :func:`build_gather_tree`) from its own representative (GK_REP, column 0), so each point holds
    R / n of them (one each when R = n). A child keeps every column whose point it holds (so a
    parent's representative is always one of its children's) and gives each other column to its
    own points in turn, from a point drawn by (seed, pixel, node): every point of a node holds about
    R / (its points) of the node's columns, and each of them at least one when R >= n.
    """
    r_count = greps.shape[1]
    for i in range(n):
        for r in range(r_count):
            greps[i, r] = i
    if n == 1:
        return
    pos = np.empty(n, np.int64)
    for t in range(n):
        pos[idx[t]] = t
    p0 = pos[gk[n, GK_REP]]
    for r in range(r_count):
        greps[n, r] = idx[(p0 + r) % n]
    # Parents before children: an inner child has a larger id than its parent.
    for k in range(n, 2 * n - 1):
        for side in range(2):
            c = gk[k, GK_LEFT + side]
            if c < n:
                continue
            first, last = gk[c, GK_FIRST], gk[c, GK_LAST]
            count = last - first
            t = np.int64(hash_uniform(seed + REP_SEED, pixel, c, 0) * count)
            for r in range(r_count):
                p = greps[k, r]
                if first <= pos[p] < last:
                    greps[c, r] = p
                else:
                    greps[c, r] = idx[first + t % count]
                    t += 1
