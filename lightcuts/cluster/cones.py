r"""Normal cones from a box of unit normals (Walter, Bala, Kulkarni, Pingali 2008, section 5).

A cluster keeps the axis-aligned box ``[n_lo, n_hi]`` of its lights' unit normals; the union of two
clusters is the union of their boxes, so the cone costs O(1) per merge. Unit vectors inside the box
also lie inside the box's circumscribed sphere (centre ``m = (n_lo + n_hi) / 2``, radius
``r = |n_hi - n_lo| / 2``); on the unit sphere that region is the spherical cap

    p . m >= (1 + d^2 - r^2) / 2,   d = |m|,

i.e. the cone with axis ``a = m / d`` and ``cos(beta) = (1 + d^2 - r^2) / (2 d)``. Cones wider than
90 degrees (``cos(beta) < 0``) are kept as they are; ``d = 0`` or ``cos(beta) <= -1`` is the full
sphere, returned as axis ``(0, 0, 0)`` and ``cos(beta) = -1``.

The cone is a valid bound but not monotone under union: a larger box can give a narrower cone than
one of its parts' cones (docs/math.md, "Normal cones from a box of normals").
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Unit roundoff of float64.
_EPS = 2.0 ** -53


@njit(cache=True)
def cone_from_box(nlo0, nlo1, nlo2, nhi0, nhi1, nhi2):
    """Cone ``(ax, ay, az, cos_half)`` containing every unit vector in the box ``[nlo, nhi]``.

    A degenerate box (``nlo == nhi``, a single normal n) gives axis n and ``cos_half = 1`` exactly.
    Otherwise ``cos_half`` is lowered by a few ulps of its rounding error, which is only noticeable
    when the box centre nears the origin (``d -> 0``, where the formula divides by d): the cone then
    stays conservative instead of missing a normal by rounding. The full sphere is ``(0, 0, 0, -1)``.
    """
    m0 = 0.5 * (nlo0 + nhi0)
    m1 = 0.5 * (nlo1 + nhi1)
    m2 = 0.5 * (nlo2 + nhi2)
    d2 = m0 * m0 + m1 * m1 + m2 * m2
    if d2 <= 0.0:
        return 0.0, 0.0, 0.0, -1.0
    d = np.sqrt(d2)
    e0 = 0.5 * (nhi0 - nlo0)
    e1 = 0.5 * (nhi1 - nlo1)
    e2 = 0.5 * (nhi2 - nlo2)
    r2 = e0 * e0 + e1 * e1 + e2 * e2
    if r2 == 0.0:
        return m0 / d, m1 / d, m2 / d, 1.0
    cos_half = (1.0 + d2 - r2) / (2.0 * d) - 8.0 * _EPS * (1.0 + d2 + r2) / (2.0 * d)
    if cos_half <= -1.0:
        return 0.0, 0.0, 0.0, -1.0
    if cos_half > 1.0:
        cos_half = 1.0
    return m0 / d, m1 / d, m2 / d, cos_half


@njit(cache=True)
def cone_sine(cos_half):
    """``S = sin(beta)`` of a cone with ``cos(beta) = cos_half``; 1 at or past 90 degrees.

    The cone term of the 2008 metric: a cone wider than a hemisphere bounds the cosine no better
    than a hemisphere does, so S saturates at 1.
    """
    if cos_half <= 0.0:
        return 1.0
    s2 = 1.0 - cos_half * cos_half
    return np.sqrt(s2) if s2 > 0.0 else 0.0


@njit(cache=True)
def _cones_from_boxes(nlo, nhi, axis, cos_half):
    for k in range(nlo.shape[0]):
        ax, ay, az, c = cone_from_box(nlo[k, 0], nlo[k, 1], nlo[k, 2], nhi[k, 0], nhi[k, 1], nhi[k, 2])
        axis[k, 0] = ax
        axis[k, 1] = ay
        axis[k, 2] = az
        cos_half[k] = c


def cones_from_boxes(normal_lo: np.ndarray, normal_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`cone_from_box`.

    normal_lo, normal_hi : (K, 3) float64 boxes of unit normals
    returns axis (K, 3) float64 (unit, or zeros for the full sphere), cos_half (K,) float64 in [-1, 1]
    """
    nlo = np.ascontiguousarray(normal_lo, np.float64).reshape(-1, 3)
    nhi = np.ascontiguousarray(normal_hi, np.float64).reshape(-1, 3)
    if nlo.shape != nhi.shape:
        raise ValueError(f"normal box shapes differ: {nlo.shape} and {nhi.shape}")
    axis = np.empty_like(nlo)
    cos_half = np.empty(len(nlo))
    _cones_from_boxes(nlo, nhi, axis, cos_half)
    return axis, cos_half


def cone_contains(axis: np.ndarray, cos_half, directions: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """(M,) bool: whether each unit direction lies in its cone, up to ``tol`` radians.

    axis : (3,) or (M, 3) float64 unit axes (ignored for the full sphere, ``cos_half <= -1``)
    cos_half : scalar or (M,) cosines of the half-angles
    directions : (M, 3) float64 unit vectors
    The angle is atan2(|a x n|, a . n), accurate near 0 and 180 degrees (arccos of a dot product
    is not), compared with ``beta + tol``.
    """
    directions = np.asarray(directions, np.float64).reshape(-1, 3)
    axis = np.broadcast_to(np.asarray(axis, np.float64), directions.shape)
    cos_half = np.broadcast_to(np.asarray(cos_half, np.float64), directions.shape[:1])
    beta = np.arccos(np.clip(cos_half, -1.0, 1.0))
    angle = np.arctan2(np.linalg.norm(np.cross(directions, axis), axis=1), np.einsum("ij,ij->i", directions, axis))
    return (cos_half <= -1.0) | (angle <= beta + tol)
