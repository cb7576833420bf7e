"""Cluster bounds (``lightcuts/cluster/bounds.py``) and the normal cone of a union
(``bounds.union_cone`` over ``cones.cone_from_box``, Walter 2008, section 5).

Properties:
- the union of two boxes contains both and is the smallest box that does (each face is one of
  theirs); a grown box contains the point; the box of points is their componentwise min and max;
  the empty box is inverted (inf, -inf); the centre is the mean of the corners;
- the cone of a union contains every normal of both clusters;
- it is no wider than its definition needs: it is the cap of the union box of normals'
  circumscribed sphere, so directions sampled just inside its rim lie in that sphere and those just
  outside do not; for two normals (whose box's sphere passes through both) it is their smallest
  cone, half the angle between them;
- degenerate cones as the code defines them: one normal twice gives that normal with cos 1; opposite
  normals and the six axes give the full sphere (axis 0, cos -1); a cone wider than a hemisphere is
  kept (cos in (-1, 0)).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.bounds import EMPTY_HI, EMPTY_LO, box_centre, box_grow, box_union, points_box, union_cone

from conftest import unit

FAST = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])

coords = st.floats(-1e6, 1e6, allow_nan=False)
corners = st.tuples(coords, coords, coords)
boxes = st.tuples(corners, corners).map(lambda t: (tuple(map(min, *t)), tuple(map(max, *t))))
unit_vectors = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
    lambda v: tuple(unit(v)))


@FAST
@given(boxes, boxes, corners)
def test_box_union_is_the_smallest_box_containing_both(a, b, p):
    lo, hi = box_union(*a, *b)
    for t in range(3):
        assert lo[t] <= min(a[0][t], b[0][t]) and hi[t] >= max(a[1][t], b[1][t])
        assert lo[t] in (a[0][t], b[0][t]) and hi[t] in (a[1][t], b[1][t])
    glo, ghi = box_grow(*a, p)
    assert (glo, ghi) == box_union(*a, p, p) and all(glo[t] <= p[t] <= ghi[t] for t in range(3))
    assert box_centre(*a) == tuple(0.5 * (a[0][t] + a[1][t]) for t in range(3))


@FAST
@given(st.lists(corners, min_size=0, max_size=20), st.data())
def test_points_box_is_the_min_and_max_of_its_rows(points, data):
    p = np.array(points, np.float64).reshape(-1, 3)
    s = data.draw(st.integers(0, len(p)))
    e = data.draw(st.integers(s, len(p)))
    lo, hi = points_box(p, s, e)
    if s == e:
        assert (lo, hi) == (EMPTY_LO, EMPTY_HI)
    else:
        assert lo == tuple(p[s:e].min(0)) and hi == tuple(p[s:e].max(0))


def union_of(na, nb):
    """union_cone of two clusters given by their normals (lists of unit vectors)."""
    na, nb = np.reshape(na, (-1, 3)), np.reshape(nb, (-1, 3))
    return union_cone(tuple(na.min(0)), tuple(na.max(0)), tuple(nb.min(0)), tuple(nb.max(0)))


@FAST
@given(st.lists(unit_vectors, min_size=1, max_size=8), st.lists(unit_vectors, min_size=1, max_size=8))
def test_the_union_cone_holds_every_normal_and_is_the_cap_of_the_box_sphere(na, nb):
    *axis, cos_half = union_of(na, nb)
    axis = np.array(axis)
    normals = np.r_[np.reshape(na, (-1, 3)), np.reshape(nb, (-1, 3))]
    assert -1.0 <= cos_half <= 1.0
    if cos_half == -1.0:
        assert (axis == 0).all()
        return
    assert abs(np.linalg.norm(axis) - 1) < 1e-12
    assert (normals @ axis >= cos_half - 1e-14).all()
    # Brute force over directions on circles just inside and just outside the cone's rim: inside the
    # union box's circumscribed sphere within, outside it beyond (the cone is that sphere's cap).
    nlo, nhi = normals.min(0), normals.max(0)
    m, r = 0.5 * (nlo + nhi), 0.5 * np.linalg.norm(nhi - nlo)
    if r < 1e-6:
        return
    u = unit(np.cross(axis, [1.0, 0, 0] if abs(axis[0]) < 0.9 else [0, 1.0, 0]))
    v = np.cross(axis, u)
    phi = np.linspace(0, 2 * np.pi, 64, endpoint=False)[:, None]
    beta = np.arccos(cos_half)
    for delta, inside in ((-1e-5, True), (1e-5, False)):
        if not 0 < beta + delta < np.pi:
            continue
        p = np.cos(beta + delta) * axis + np.sin(beta + delta) * (np.cos(phi) * u + np.sin(phi) * v)
        assert ((np.linalg.norm(p - m, axis=1) <= r) == inside).all(), (delta, beta)


@FAST
@given(unit_vectors, unit_vectors)
def test_the_cone_of_two_normals_is_their_smallest_cone(a, b):
    *axis, cos_half = union_of([a], [b])
    a, b = np.array(a), np.array(b)
    if np.linalg.norm(a + b) < 1e-6:
        return  # (nearly) opposite: the full sphere, below
    half = 0.5 * np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b)
    np.testing.assert_allclose(axis, unit(a + b), atol=1e-12)
    # Lowered by the engine's rounding allowance, a few ulps of (1 + d^2 + r^2) / (2 d), d = |a + b| / 2.
    assert cos_half <= np.cos(half) and cos_half == pytest.approx(np.cos(half), abs=1e-14 / np.linalg.norm(a + b))


@pytest.mark.parametrize("na,nb,want", [
    ([[0, 0.6, 0.8]], [[0, 0.6, 0.8]], "point"),
    ([[0, 0, 1]], [[0, 0, -1]], "sphere"),
    (np.eye(3), -np.eye(3), "sphere"),
    ([[-1, 0, 0], [1, 0, 0]], [[0, 1, 0], [0, -0.3, 0.95]], "wide"),
], ids=["one normal", "opposite", "six axes", "past a hemisphere"])
def test_degenerate_cones(na, nb, want):
    na, nb = unit(na), unit(nb)
    *axis, cos_half = union_of(na, nb)
    if want == "point":
        assert cos_half == 1.0 and axis == pytest.approx(list(na[0]), abs=1e-15)
    elif want == "sphere":
        assert cos_half == -1.0 and axis == [0.0, 0.0, 0.0]
    else:
        assert -1.0 < cos_half < 0.0
        assert (np.r_[na, nb] @ axis >= cos_half - 1e-14).all()
