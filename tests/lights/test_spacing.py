"""The VPLs' spacing (lightcuts.lights.spacing) that the default clamp radius is a multiple of."""

import numpy as np
import pytest

from lightcuts.lights.lightset import LightSet
from lightcuts.lights.spacing import NEIGHBOURS, indirect_spacing, kth_neighbour_distance, vpl_spacing


def _square(n: int, side: float = 1.0, seed: int = 0) -> np.ndarray:
    """n points uniform on the square [0, side]^2 in the plane y = 0."""
    p = np.random.default_rng(seed).uniform(0.0, side, (n, 2))
    return np.column_stack([p[:, 0], np.zeros(n), p[:, 1]])


def test_kth_neighbour_distance_is_the_sorted_distance():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(300, 3))
    p[7] = p[8]  # a duplicate counts as distance 0, the query itself does not
    q = np.array([0, 7, 150, 299], np.int64)
    for k in (1, 5, 16):
        out = np.empty(len(q))
        kth_neighbour_distance(p, q, k, out)
        for i, row in enumerate(q):
            d = np.sort(np.linalg.norm(np.delete(p, row, axis=0) - p[row], axis=1))
            assert out[i] == pytest.approx(d[k - 1], rel=1e-12, abs=0.0)
    one = np.empty(1)
    kth_neighbour_distance(p, np.array([7], np.int64), 1, one)
    assert one[0] == 0.0


def test_spacing_is_the_radius_of_a_vpls_share_of_the_area():
    # uniform points on area A: s = sqrt(A / (pi N)) (the median of the k-NN estimate is within ~10%)
    for n, side in ((20000, 1.0), (20000, 3.0), (5000, 1.0)):
        s = vpl_spacing(_square(n, side))
        assert s == pytest.approx(np.sqrt(side * side / (np.pi * n)), rel=0.1)


def test_spacing_scales_with_the_scene_and_falls_as_one_over_sqrt_n():
    p = _square(20000)
    s = vpl_spacing(p)
    for scale in (1e-3, 7.5, 400.0):
        assert vpl_spacing(p * scale) == pytest.approx(scale * s, rel=1e-12)
        assert vpl_spacing(p * scale + 1000.0 * scale) == pytest.approx(scale * s, rel=1e-9)  # translated
    # twice the VPLs on the same square: the spacing shrinks by sqrt(2)
    assert vpl_spacing(_square(40000, seed=1)) == pytest.approx(s / np.sqrt(2), rel=0.05)
    # empty space beside the VPLs (a far-away wall without light) changes nothing: not the scene's box
    far = np.vstack([p, [[5000.0, 0.0, 0.0]]])
    assert vpl_spacing(far) == pytest.approx(s, rel=0.02)


def test_spacing_of_few_vpls():
    assert vpl_spacing(np.zeros((0, 3))) == 0.0
    assert vpl_spacing(np.zeros((1, 3))) == 0.0
    # 3 points: k = 2, the median of the 2nd-nearest distances over sqrt(2)
    p = np.array([[0.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]])
    assert vpl_spacing(p) == pytest.approx(np.median([3.0, 2.0, 3.0]) / np.sqrt(2))
    assert NEIGHBOURS == 16


def test_indirect_spacing_measures_the_indirect_vpls_only():
    ind = _square(4000, seed=2)
    direct = _square(4000, 0.01, seed=3)  # dense direct lights: ignored
    ls = LightSet(np.vstack([ind, direct]), np.tile([0.0, 1.0, 0.0], (8000, 1)), np.ones((8000, 3)), "oriented",
                  np.r_[np.ones(4000, bool), np.zeros(4000, bool)])
    assert indirect_spacing({"oriented": ls}) == vpl_spacing(ind)
    assert indirect_spacing({"oriented": LightSet(direct, np.tile([0.0, 1.0, 0.0], (4000, 1)), np.ones((4000, 3)),
                                                  "oriented")}) == 0.0
