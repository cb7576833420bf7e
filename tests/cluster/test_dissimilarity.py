"""The built-in dissimilarities (``lightcuts/cluster/dissimilarity.py``) and the pair cost d(A u B) the
kd-tree search and the loops compare (``kd_search._pair_d``).

Properties:
- each kernel equals its paper's formula, computed here in numpy (walter2008: eq. 2 read with S^2
  and S = 1 past 90 degrees; walter2005; the surface area of section 4), with and without a cone;
- each grows with every extent of the box, with the intensity and with the cone's width: the
  property that makes the kd-tree's bound a lower bound;
- the pair cost is the kernel of the union box, the union's box-of-normals cone and the summed
  intensity; it is symmetric, exactly;
- it is non-decreasing (eq. 1: d(A u B) <= d((A u C) u B)) for the surface area and for the light
  metrics without a cone;
- an unknown id is refused.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.dissimilarity import metric_eval
from lightcuts.cluster.kd_search import _pair_d

from cluster_oracles import C, METRIC_CASES, SURFACE_AREA, WALTER2005, WALTER2008, np_cone_cos, np_metric
from conftest import unit

METRICS = (WALTER2008, WALTER2005, SURFACE_AREA)
FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def random_box(rng, n):
    lo = rng.normal(size=(n, 3))
    return lo, lo + rng.exponential(size=(n, 3))


@pytest.mark.parametrize("metric_id", METRICS)
@pytest.mark.parametrize("has_cone", [False, True])
def test_kernels_equal_the_papers_formulas(metric_id, has_cone):
    rng = np.random.default_rng(metric_id + 3 * has_cone)
    lo, hi = random_box(rng, 400)
    intensity = rng.exponential(size=400)
    # Cones from a point (cos 1) to past a hemisphere (cos < 0) and the full sphere (cos -1).
    cone_cos = np.r_[1.0, 0.0, -1.0, rng.uniform(-1, 1, 397)]
    c = 0.7
    got = [metric_eval(metric_id, intensity[i], *lo[i], *hi[i], cone_cos[i], has_cone, c) for i in range(400)]
    want = np_metric(metric_id, intensity, hi - lo, cone_cos, has_cone, c)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=0)


@pytest.mark.parametrize("metric_id", METRICS)
def test_kernels_grow_with_extents_intensity_and_cone_width(metric_id):
    rng = np.random.default_rng(metric_id)
    lo, hi = random_box(rng, 300)
    intensity = rng.exponential(size=300)
    cone_cos = rng.uniform(-1, 1, 300)
    # Each input in turn moved the way a union moves it: a wider box, more intensity, a wider cone.
    grow = [lambda lo, hi, i, cc, t=t: (lo, hi + np.eye(3)[t] * rng.exponential(), i, cc) for t in range(3)]
    grow += [lambda lo, hi, i, cc: (lo - rng.exponential(size=3), hi, i, cc),
             lambda lo, hi, i, cc: (lo, hi, i + rng.exponential(), cc),
             lambda lo, hi, i, cc: (lo, hi, i, cc - rng.uniform(0, 1 + cc))]
    for k in range(300):
        base = metric_eval(metric_id, intensity[k], *lo[k], *hi[k], cone_cos[k], True, C)
        for g in grow:
            glo, ghi, gi, gc = g(lo[k], hi[k], intensity[k], cone_cos[k])
            assert metric_eval(metric_id, gi, *glo, *ghi, gc, True, C) >= base


def test_an_unknown_metric_id_is_refused():
    with pytest.raises(ValueError, match="metric id"):
        metric_eval(3, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, False, C)


def clusters(rng, k, spread):
    """k random clusters: box, box of normals (of 1 to 4 unit normals), intensity."""
    lo, hi = random_box(rng, k)
    lo, hi = lo * spread, hi * spread
    nlo, nhi = np.empty((k, 3)), np.empty((k, 3))
    for i in range(k):
        n = unit(rng.normal(size=(rng.integers(1, 5), 3)) + [0, 0, rng.uniform(0, 3)])
        nlo[i], nhi[i] = n.min(0), n.max(0)
    return lo, hi, nlo, nhi, rng.exponential(size=k)


def pair(metric_id, has_cone, a, b):
    """The engine's d(A u B) of two clusters given as (lo, hi, nlo, nhi, intensity)."""
    return _pair_d(metric_id, has_cone, C, *map(tuple, a[:4]), a[4], *map(tuple, b[:4]), b[4])


def row(cl, i):
    return tuple(x[i] for x in cl)


@FAST
@given(seed=st.integers(0, 2**32 - 1), case=st.sampled_from(METRIC_CASES))
def test_the_pair_cost_is_the_union_cluster_and_symmetric(seed, case):
    metric_id, has_cone = case
    cl = clusters(np.random.default_rng(seed), 2, 0.5)
    a, b = row(cl, 0), row(cl, 1)
    d = pair(metric_id, has_cone, a, b)
    assert d == pair(metric_id, has_cone, b, a)
    lo, hi = np.minimum(a[0], b[0]), np.maximum(a[1], b[1])
    cone_cos = np_cone_cos(np.minimum(a[2], b[2]), np.maximum(a[3], b[3]))
    want = np_metric(metric_id, a[4] + b[4], hi - lo, cone_cos, has_cone, C)
    # The engine's cone is lowered by a rounding allowance of a few ulps.
    assert d == pytest.approx(float(want), rel=1e-9)


@FAST
@given(seed=st.integers(0, 2**32 - 1), case=st.sampled_from([(SURFACE_AREA, True), (WALTER2008, False),
                                                             (WALTER2005, False)]))
def test_the_monotone_metrics_are_non_decreasing(seed, case):
    # Eq. 1: whatever C joins A, A's cost with B does not fall.
    metric_id, has_cone = case
    cl = clusters(np.random.default_rng(seed), 3, 1.0)
    a, b, c = row(cl, 0), row(cl, 1), row(cl, 2)
    ac = (np.minimum(a[0], c[0]), np.maximum(a[1], c[1]), np.minimum(a[2], c[2]), np.maximum(a[3], c[3]),
          a[4] + c[4])
    assert pair(metric_id, has_cone, a, b) <= pair(metric_id, has_cone, ac, b)
