r"""Light-tree importance and the walk that draws a light with its exact probability: numba device
functions shared by every estimator that samples lights through a tree (tree next-event estimation
in lightcuts.integrators.path, stochastic lightcuts).

The importance of a node for a shading point p with normal n (pbrt-v4's ``CompactLightBounds``,
Conty Estevez and Kulla 2018; docs/math.md, "Sampling light trees") is a cheap estimate of the
node's contribution, an upper bound in its angular factors: ``phi * cos(theta') / d2 * cos(theta_i')``
with phi the node's power (luminance of its summed intensity), d2 the squared distance from p to the
box's centre (outside the box's bounding sphere of radius r; inside it, clamped below by (r/2)^2,
about the mean squared distance to lights spread through the sphere, instead of r^2, which starves
a large node that holds the lights nearest to p), theta' the smallest angle between the
emission cone (axis, half-angle theta_o) and the direction to p once the box's subtended half-angle
theta_b is taken off, and theta_i' the receiver's angle to the box less theta_b. A node whose
theta' reaches 90 degrees (one-sided cosine emitters: triangles and oriented VPLs) cannot light p:
importance 0, and then no light below it can, so a walk that never enters it loses nothing. Omni
lights (full-sphere cone) have no emission test; directional lights (boxes over unit directions)
have power and the receiver's factor alone.

A walk starts from a tree's root chosen in proportion to the roots' importances and at each node
takes a child in proportion to the two children's importances, one uniform number remapped at
every step; the light's probability is the product of the choices, and :func:`light_pmf` computes
the same product again from the leaf up (for multiple importance sampling), from the same
importances, so the two agree to rounding.

Record layout (lightcuts.integrators.light_sampler.LightSampler): ``rec`` (K, 8) float32 per node:
box lo, hi (rounded outwards), cos of the emission cone's half-angle (widened over the axis's
quantisation; -1: full sphere), power; ``axis`` (K,) uint32 the cone's axis, octahedral 2 x 16 bits;
``child`` (K,) int32: the left child (the right is left + 1), or ``-(light + 1)`` at a leaf;
``parent`` (K,) int32: the parent, or ``-(t + 1)`` at the root of tree t; ``leaf`` (L,) int32 the
leaf node of every light; ``roots`` (T,) int64 and ``root_type`` (T,) int64 per tree (a tree's nodes
are the rows from its root to the next root).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.bounds import DIRECTIONAL

REC_LO, REC_HI, REC_COS, REC_PHI, REC_WIDTH = 0, 3, 6, 7, 8
#: The largest float64 below 1: a remapped uniform number stays in [0, 1).
ONE_BELOW = 1.0 - 2.0 ** -53
# Cosine of the emission spread of one-sided cosine emitters (triangles, oriented VPLs): 90 degrees.
_COS_EMISSION = 0.0
# Floor of a node's squared distance, world units squared (a point light at the shading point would
# otherwise get an infinite importance).
_D2_FLOOR = 1e-30


@njit(cache=True, error_model="numpy")
def oct_decode(code):
    """The unit vector of an octahedral code (two 16-bit halves of a uint32)."""
    x = np.float64(code & np.uint32(0xFFFF)) / 65535.0 * 2.0 - 1.0
    y = np.float64(code >> np.uint32(16)) / 65535.0 * 2.0 - 1.0
    z = 1.0 - abs(x) - abs(y)
    if z < 0.0:
        x, y = (1.0 - abs(y)) * (1.0 if x >= 0.0 else -1.0), (1.0 - abs(x)) * (1.0 if y >= 0.0 else -1.0)
    s = 1.0 / np.sqrt(x * x + y * y + z * z)
    return x * s, y * s, z * s


@njit(cache=True, error_model="numpy")
def _cos_sub(sin_a, cos_a, sin_b, cos_b):
    """cos(max(0, a - b)) for angles a, b in [0, pi] given by their sines and cosines."""
    if cos_a >= cos_b:
        return 1.0
    return cos_a * cos_b + sin_a * sin_b


@njit(cache=True, error_model="numpy")
def _sin_sub(sin_a, cos_a, sin_b, cos_b):
    """sin(max(0, a - b)) for angles a, b in [0, pi]."""
    if cos_a >= cos_b:
        return 0.0
    return sin_a * cos_b - cos_a * sin_b


@njit(cache=True, error_model="numpy")
def importance(rec, axis, k, typ, p0, p1, p2, n0, n1, n2):
    """Importance (>= 0) of node k, of light type code ``typ``, for the point p with unit normal n
    (n = 0: no receiver factor, e.g. a point in a medium). Module docstring."""
    phi = np.float64(rec[k, REC_PHI])
    if phi <= 0.0:
        return 0.0
    lo0, lo1, lo2 = np.float64(rec[k, REC_LO]), np.float64(rec[k, REC_LO + 1]), np.float64(rec[k, REC_LO + 2])
    hi0, hi1, hi2 = np.float64(rec[k, REC_HI]), np.float64(rec[k, REC_HI + 1]), np.float64(rec[k, REC_HI + 2])
    c0, c1, c2 = 0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2)
    r2 = 0.25 * ((hi0 - lo0) ** 2 + (hi1 - lo1) ** 2 + (hi2 - lo2) ** 2)
    if typ == DIRECTIONAL:
        # the box bounds unit directions towards the lights: the cone of directions around its centre
        cl2 = c0 * c0 + c1 * c1 + c2 * c2
        if cl2 <= r2 or (n0 == 0.0 and n1 == 0.0 and n2 == 0.0):
            return phi
        cl = np.sqrt(cl2)
        cos_b = np.sqrt(max(0.0, 1.0 - r2 / cl2))
        sin_b = np.sqrt(max(0.0, 1.0 - cos_b * cos_b))
        cos_i = abs(n0 * c0 + n1 * c1 + n2 * c2) / cl
        sin_i = np.sqrt(max(0.0, 1.0 - cos_i * cos_i))
        return phi * max(0.0, _cos_sub(sin_i, cos_i, sin_b, cos_b))
    w0, w1, w2 = p0 - c0, p1 - c1, p2 - c2
    d2 = w0 * w0 + w1 * w1 + w2 * w2
    if d2 <= r2:  # p inside the box's bounding sphere: every direction is possible
        return phi / max(d2, 0.25 * r2, _D2_FLOOR)
    d = np.sqrt(d2)
    w0, w1, w2 = w0 / d, w1 / d, w2 / d
    cos_b = np.sqrt(max(0.0, 1.0 - r2 / d2))
    sin_b = np.sqrt(max(0.0, 1.0 - cos_b * cos_b))
    cos_t = 1.0
    cos_o = np.float64(rec[k, REC_COS])
    if cos_o > -1.0:
        a0, a1, a2 = oct_decode(axis[k])
        cos_w = a0 * w0 + a1 * w1 + a2 * w2
        sin_w = np.sqrt(max(0.0, 1.0 - cos_w * cos_w))
        sin_o = np.sqrt(max(0.0, 1.0 - cos_o * cos_o))
        cos_x = _cos_sub(sin_w, cos_w, sin_o, cos_o)
        sin_x = _sin_sub(sin_w, cos_w, sin_o, cos_o)
        cos_t = _cos_sub(sin_x, cos_x, sin_b, cos_b)
        if cos_t <= _COS_EMISSION:
            return 0.0
    out = phi * cos_t / max(d2, r2, _D2_FLOOR)
    if n0 != 0.0 or n1 != 0.0 or n2 != 0.0:
        cos_i = abs(w0 * n0 + w1 * n1 + w2 * n2)
        sin_i = np.sqrt(max(0.0, 1.0 - cos_i * cos_i))
        out *= max(0.0, _cos_sub(sin_i, cos_i, sin_b, cos_b))
    return out


@njit(cache=True, error_model="numpy")
def node_type(roots, root_type, k):
    """The light type code of node k: its tree's (a tree's rows start at its root)."""
    t = 0
    while t + 1 < roots.shape[0] and roots[t + 1] <= k:
        t += 1
    return root_type[t]


@njit(cache=True, error_model="numpy")
def sample_below(rec, axis, child, k, typ, p0, p1, p2, n0, n1, n2, u):
    """A light drawn below node k by the importance walk with the uniform number u in [0, 1):
    ``(light, probability relative to k)``; ``(-1, 0.0)`` where both children of a node have
    importance 0 (no light below it can light p)."""
    prob = 1.0
    while child[k] >= 0:
        left = np.int64(child[k])
        il = importance(rec, axis, left, typ, p0, p1, p2, n0, n1, n2)
        ir = importance(rec, axis, left + 1, typ, p0, p1, p2, n0, n1, n2)
        s = il + ir
        if not s > 0.0:
            return -1, 0.0
        pl = il / s
        if u < pl:
            k = left
            prob *= il / s
            u = min(u / pl, ONE_BELOW)
        else:
            k = left + 1
            prob *= ir / s
            u = min((u - pl) / (1.0 - pl), ONE_BELOW)
    return -(np.int64(child[k]) + 1), prob


@njit(cache=True, error_model="numpy")
def _root_weights_total(rec, axis, roots, root_type, p0, p1, p2, n0, n1, n2):
    total = 0.0
    for t in range(roots.shape[0]):
        total += importance(rec, axis, roots[t], root_type[t], p0, p1, p2, n0, n1, n2)
    return total


@njit(cache=True, error_model="numpy")
def sample_light(rec, axis, child, roots, root_type, p0, p1, p2, n0, n1, n2, u):
    """A light of the whole forest drawn for p, n with the uniform number u: ``(light, probability)``;
    ``(-1, 0.0)`` if no tree can light p."""
    total = _root_weights_total(rec, axis, roots, root_type, p0, p1, p2, n0, n1, n2)
    if not total > 0.0:
        return -1, 0.0
    acc = 0.0
    pick = -1
    for t in range(roots.shape[0]):
        w = importance(rec, axis, roots[t], root_type[t], p0, p1, p2, n0, n1, n2)
        if w <= 0.0:
            continue
        pick = t
        if u * total < acc + w:
            break
        acc += w
    w = importance(rec, axis, roots[pick], root_type[pick], p0, p1, p2, n0, n1, n2)
    v = min(max((u * total - acc) / w, 0.0), ONE_BELOW)
    light, prob = sample_below(rec, axis, child, roots[pick], root_type[pick], p0, p1, p2, n0, n1, n2, v)
    return light, prob * (w / total)


@njit(cache=True, error_model="numpy")
def light_pmf(rec, axis, child, parent, leaf, roots, root_type, light, p0, p1, p2, n0, n1, n2):
    """The probability that :func:`sample_light` draws ``light`` for p, n: the walk's choices
    recomputed from the light's leaf up to its root, times its root's share."""
    k = np.int64(leaf[light])
    while parent[k] >= 0:
        k = np.int64(parent[k])
    typ = root_type[-np.int64(parent[k]) - 1]
    k = np.int64(leaf[light])
    prob = 1.0
    while parent[k] >= 0:
        up = np.int64(parent[k])
        left = np.int64(child[up])
        il = importance(rec, axis, left, typ, p0, p1, p2, n0, n1, n2)
        ir = importance(rec, axis, left + 1, typ, p0, p1, p2, n0, n1, n2)
        s = il + ir
        if not s > 0.0:
            return 0.0
        prob *= (il if k == left else ir) / s
        k = up
    total = _root_weights_total(rec, axis, roots, root_type, p0, p1, p2, n0, n1, n2)
    if not total > 0.0:
        return 0.0
    return prob * (importance(rec, axis, k, typ, p0, p1, p2, n0, n1, n2) / total)
