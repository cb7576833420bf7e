"""Morton order (``lightcuts/cluster/morton.py``).

Properties:
- the bit spread puts bit b of a 21-bit integer at bit 3b, and nothing else;
- each key is the bit interleave (x the most significant of each triple) of the coordinates
  quantised over the points' bounding box, shifted past the point's index, computed here bit by bit;
- the code never decreases when a point moves up along any axis;
- the order is a permutation, the keys sorted with the index breaking ties, at the most bits per
  axis that fit in 64 bits beside the index; the points of each cell of the quantisation grid at
  any level come out as one run (the locality the loops rely on);
- degenerate inputs (one point, all points equal, flat axes, a NaN) give a permutation.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from lightcuts.cluster.morton import _morton_keys, _spread3, morton_order

FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def quantised(p, bits):
    """(N, 3) Python ints: each coordinate scaled over the bounding box to [0, 2^bits - 1], truncated."""
    lo, hi = p.min(0), p.max(0)
    top = float((1 << bits) - 1)
    with np.errstate(divide="ignore"):
        scale = np.where(hi > lo, top / (hi - lo), 0.0)
    return [[int(min(x, top)) for x in row] for row in (p - lo) * scale]


def interleave(q, bits):
    """The Morton code of one quantised point, bit by bit: bit b of axis t goes to bit 3b + 2 - t."""
    return sum(((q[t] >> b) & 1) << (3 * b + 2 - t) for b in range(bits) for t in range(3))


def key_layout(n):
    """(bits per axis, index bits) as documented: the index in the low bits, at most 21 bits per axis."""
    index_bits = max(1, (n - 1).bit_length())
    return min(21, (64 - index_bits) // 3), index_bits


points = st.integers(1, 200).flatmap(lambda n: st.tuples(st.just(n), st.integers(0, 2**32 - 1), st.booleans()))


def on_point_sets(test):
    """Run ``test(case)`` on hypothesis' point sets ``(n, seed, grid)`` (see :func:`make`) and on two large ones."""
    return FAST(given(points)(example((700, 1, False))(example((700, 2, True))(test))))


def make(n, seed, grid):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3)) * [1.0, 1e-3, 50.0] + [0.0, 1e6, -3.0]
    return np.round(p * 2) / 2 if grid else p


@FAST
@given(st.lists(st.integers(0, 2**21 - 1), min_size=1, max_size=20))
def test_spread_moves_bit_b_to_bit_3b(values):
    for v in values:
        want = sum(((v >> b) & 1) << (3 * b) for b in range(21))
        assert int(_spread3(np.uint64(v))) == want
    # Only the low 21 bits are spread.
    assert int(_spread3(np.uint64(2**21 + 5))) == int(_spread3(np.uint64(5)))


@on_point_sets
def test_keys_are_the_bit_interleave_of_the_quantised_points(case):
    n, seed, grid = case
    p = make(n, seed, grid)
    bits, index_bits = key_layout(n)
    keys = _morton_keys(p, bits, index_bits)
    q = quantised(p, bits)
    assert [int(k) for k in keys] == [(interleave(q[i], bits) << index_bits) | i for i in range(n)]


@on_point_sets
def test_codes_never_decrease_along_an_axis(case):
    n, seed, grid = case
    p = make(n, seed, grid)
    bits, index_bits = key_layout(n)
    code = _morton_keys(p, bits, index_bits) >> np.uint64(index_bits)
    # Every pair of points ordered on all three axes (p_i <= p_j componentwise) is ordered by code.
    below = (p[:, None, :] <= p[None, :, :]).all(-1)
    i, j = np.nonzero(below)
    assert (code[i] <= code[j]).all()


@on_point_sets
def test_the_order_sorts_the_keys_and_keeps_cells_together(case):
    n, seed, grid = case
    p = make(n, seed, grid)
    order = morton_order(p)
    assert order.dtype == np.int64 and sorted(order) == list(range(n))
    bits, _ = key_layout(n)
    q = quantised(p, bits)
    codes = [interleave(q[i], bits) for i in range(n)]
    assert list(order) == sorted(range(n), key=lambda i: (codes[i], i))
    for level in (1, 2, 3):
        cells = [tuple(c >> (bits - level) for c in q[i]) for i in order]
        runs = [c for k, c in enumerate(cells) if k == 0 or c != cells[k - 1]]
        assert len(runs) == len(set(runs)), level


@pytest.mark.parametrize("p", [np.zeros((1, 3)), np.tile([[1.0, -2.0, 3.0]], (5, 1)),
                               np.c_[np.arange(6.0), np.zeros(6), np.ones(6)],
                               np.array([[0.0, 0, 0], [np.nan, 1, 0], [1, 1, 1], [0.5, 0.5, 0.5]])],
                         ids=["one", "equal", "flat", "nan"])
def test_degenerate_points_give_a_permutation(p):
    order = morton_order(p)
    assert sorted(order) == list(range(len(p)))
    if len(p) > 1 and np.isfinite(p).all() and (p == p[0]).all():
        assert list(order) == list(range(len(p)))  # all codes 0: the index order
