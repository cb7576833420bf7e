"""The numba BVH casters: valid hierarchies, .npz round trip, SAH statistics and builder, equality
with a brute-force test on random rays and on rays through shared edges and vertices of a closed mesh
(watertight: none slips through). The render against Embree's: tests/accel/test_casters.py."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from lightcuts.accel import RAY_CASTERS, make_caster
from lightcuts.accel.bvh.bvh import FlatBVH, from_topology
from lightcuts.accel.bvh.bvh_build import build_binned_sah
from lightcuts.accel.triangles import triangle_boxes
from lightcuts.errors import LightcutsError

from brute import brute as brute_hits

BVH_CASTERS = [n for n in RAY_CASTERS.names() if n.startswith("bvh-")]


def soup(n=400, seed=0):
    """n random triangles in the unit cube (float32 vertices)."""
    rng = np.random.default_rng(seed)
    centres = rng.random((n, 1, 3))
    v = (centres + 0.08 * rng.standard_normal((n, 3, 3))).reshape(-1, 3).astype(np.float32).astype(np.float64)
    return v, np.arange(3 * n).reshape(n, 3)


def sphere():
    """A closed mesh: an icosphere of radius 1 (320 triangles), float32 vertices."""
    m = trimesh.creation.icosphere(subdivisions=2)
    return np.asarray(m.vertices, np.float32).astype(np.float64), np.asarray(m.faces, np.int64)


def brute(vertices, faces, org, dirs, tnear, tfar):
    return brute_hits(vertices, faces, org, dirs, tnear, tfar)[:2]


def independent_check(bvh: FlatBVH):
    """Validity from the arrays, in numpy: each triangle in one leaf, children inside parents."""
    leaf = bvh.left < 0
    assert np.array_equal(np.sort(bvh.prim[leaf]), np.arange(bvh.n_faces))
    assert (bvh.prim[~leaf] == -1).all() and (bvh.right[leaf] == -1).all()
    inner = np.nonzero(~leaf)[0]
    assert (bvh.left[inner] == inner + 1).all()
    for child in (bvh.left[inner], bvh.right[inner]):
        assert (bvh.lo[child] >= bvh.lo[inner]).all() and (bvh.hi[child] <= bvh.hi[inner]).all()
    children = np.concatenate([bvh.left[inner], bvh.right[inner]])
    assert np.array_equal(np.sort(children), np.arange(1, bvh.n_nodes))   # every node but the root, once


@pytest.mark.parametrize("name", BVH_CASTERS)
@pytest.mark.parametrize("mesh", [soup, sphere])
def test_bvh_is_valid(name, mesh):
    v, f = mesh()
    caster = make_caster((v, f), name)
    bvh = caster.bvh
    assert bvh.n_nodes == 2 * len(f) - 1
    independent_check(bvh)
    lo, hi = triangle_boxes(v, f)
    leaf = bvh.prim >= 0
    assert np.array_equal(bvh.lo[leaf], lo[bvh.prim[leaf]]) and np.array_equal(bvh.hi[leaf], hi[bvh.prim[leaf]])


def test_check_rejects_broken_bvhs():
    v, f = soup(50)
    bvh = make_caster((v, f), "bvh-sah").bvh
    inner = np.nonzero(bvh.prim < 0)[0][3]
    lo = bvh.lo.copy()
    lo[inner + 1] -= 1.0     # a child sticking out of its parent
    with pytest.raises(LightcutsError, match="does not contain"):
        FlatBVH(lo, bvh.hi, bvh.left, bvh.right, bvh.prim, bvh.n_faces).check()
    prim = bvh.prim.copy()
    leaves = np.nonzero(prim >= 0)[0]
    prim[leaves[0]] = prim[leaves[1]]   # one triangle twice, another never
    with pytest.raises(LightcutsError, match="more than one leaf"):
        FlatBVH(bvh.lo, bvh.hi, bvh.left, bvh.right, prim, bvh.n_faces).check()
    left, right, p, root = build_binned_sah(*triangle_boxes(v, f))
    right = right.copy()
    right[root] = left[root]            # a child reached twice
    with pytest.raises(LightcutsError, match="not a binary tree"):
        from_topology(left, right, p, root, v, f)


def test_from_topology_takes_nodes_in_any_order():
    """A builder may number its 2F-1 nodes arbitrarily (the light-tree convention): renumbering a
    topology's nodes gives the same flat BVH."""
    v, f = soup(200)
    left, right, prim, root = build_binned_sah(*triangle_boxes(v, f))
    ref = from_topology(left, right, prim, root, v, f)
    perm = np.random.default_rng(4).permutation(len(prim))      # old id -> new id
    new_left, new_right, new_prim = (np.empty_like(a) for a in (left, right, prim))
    for arr, new in ((left, new_left), (right, new_right)):
        new[perm] = np.where(arr >= 0, perm[np.maximum(arr, 0)], -1)
    new_prim[perm] = prim
    got = from_topology(new_left, new_right, new_prim, perm[root], v, f)
    for k in ("lo", "hi", "left", "right", "prim"):
        assert getattr(got, k).tobytes() == getattr(ref, k).tobytes()


def test_save_load_round_trip(tmp_path):
    v, f = soup(120)
    caster = make_caster((v, f), "bvh-sah")
    path = tmp_path / "bvh.npz"
    caster.save(path)
    with np.load(path) as z:
        assert set(z.files) == {"lo", "hi", "left", "right", "prim", "n_faces", "builder"}
    loaded = FlatBVH.load(path)
    for k in ("lo", "hi", "left", "right", "prim"):
        assert getattr(loaded, k).tobytes() == getattr(caster.bvh, k).tobytes()
    assert loaded.n_faces == 120 and loaded.builder == "bvh-sah"
    from lightcuts.accel.bvh.bvh_caster import BVHCaster

    again = BVHCaster.load(path, v, f)
    rng = np.random.default_rng(1)
    org, dirs = rng.random((300, 3)), rng.standard_normal((300, 3))
    assert np.array_equal(again.intersect(org, dirs)[1], caster.intersect(org, dirs)[1])
    with pytest.raises(LightcutsError, match="triangles"):
        BVHCaster.load(path, *soup(60))
    np.savez(tmp_path / "bad.npz", lo=loaded.lo, hi=loaded.hi)
    with pytest.raises(LightcutsError, match="left: missing"):
        FlatBVH.load(tmp_path / "bad.npz")


def test_sah_statistics_by_hand():
    """Two flat triangles: boxes [0,1]x[0,1]x{0} and [2,3]x[0,1]x{0} (SA 2 each), root [0,3]x[0,1]x{0}
    (SA 6). The paper's Fig. 6: the root box, then both triangles: E(boxes) = 1, E(tris) = 2,
    E(cost) = 2.5. With a box per leaf: E(boxes) = (6 + 2 + 2) / 6, E(tris) = (2 + 2) / 6, E(cost) = 1.5."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 1, 0]], float)
    f = np.array([[0, 1, 2], [3, 4, 5]])
    s = make_caster((v, f), "bvh-sah").bvh.sah_stats()
    assert (s["E_boxes"], s["E_tris"], s["E_cost"]) == pytest.approx((1.0, 2.0, 2.5))
    assert s["E_boxes_leafbox"] == pytest.approx(10 / 6) and s["E_boxes_internal"] == pytest.approx(1.0)
    assert s["E_tris_leafbox"] == pytest.approx(4 / 6) and s["E_cost_leafbox"] == pytest.approx(1.5)
    assert s["nodes"] == 3 and s["depth"] == 1 and s["memory_bytes"] == 3 * (2 * 24 + 3 * 4)


def test_fig6_statistics_of_a_hand_built_bvh():
    """Root [0,4]x[0,1]^2 (SA 18) over node 1 = [0,2]x[0,1]^2 (SA 10, two leaves of SA 6) and a leaf
    (SA 6). Paper: boxes = root 1 + node 1 (parent root) 1 = 2; triangles = the right leaf (parent
    root) 1 + the two under node 1, 10/18 each = 1 + 20/18; cost = 0.5 * 2 + 38/18. Leaf boxes:
    boxes (18 + 10 + 6 + 6 + 6) / 18, triangles (6 + 6 + 6) / 18."""
    box = lambda x0, x1: ([x0, 0.0, 0.0], [x1, 1.0, 1.0])  # noqa: E731
    boxes = [box(0, 4), box(0, 2), box(0, 1), box(1, 2), box(3, 4)]
    bvh = FlatBVH(np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes]),
                  np.array([1, 2, -1, -1, -1], np.int32), np.array([4, 3, -1, -1, -1], np.int32),
                  np.array([-1, -1, 0, 1, 2], np.int32), 3)
    s = bvh.sah_stats()
    assert s["E_boxes"] == pytest.approx(2.0) and s["E_tris"] == pytest.approx(38 / 18)
    assert s["E_cost"] == pytest.approx(1.0 + 38 / 18)
    assert s["E_boxes_leafbox"] == pytest.approx(46 / 18) and s["E_tris_leafbox"] == pytest.approx(1.0)
    assert s["E_cost_leafbox"] == pytest.approx(23 / 18 + 1.0) and s["E_boxes_internal"] == pytest.approx(28 / 18)


def test_fig6_statistics_hold_for_every_bvh_caster():
    """On a random soup, for every BVH caster: E(cost) = 0.5 E(boxes) + E(tris) in both variants, each
    of the 2F - 2 non-root nodes is counted once at its parent's ratio (so E(boxes) + E(tris) = 1 +
    2 x the summed ratio of the internal nodes), and, unlike the leaf-box variant's, E(tris) differs
    between the builders (it depends on the parents' boxes, not on the triangles' own)."""
    v, f = soup(300, seed=4)
    tris = {}
    for name in ("bvh-sah", "bvh-agglomerative", "bvh-agglomerative-heap"):
        caster = make_caster((v, f), name)
        s = caster.stats()
        assert s["E_cost"] == pytest.approx(0.5 * s["E_boxes"] + s["E_tris"])
        assert s["E_cost_leafbox"] == pytest.approx(0.5 * s["E_boxes_leafbox"] + s["E_tris_leafbox"])
        assert s["E_boxes"] + s["E_tris"] == pytest.approx(1.0 + 2.0 * s["E_boxes_internal"])
        assert s["E_tris"] > s["E_tris_leafbox"]  # a parent's box holds its leaves' boxes
        tris[name] = (s["E_tris"], s["E_tris_leafbox"])
    assert tris["bvh-sah"][1] == pytest.approx(tris["bvh-agglomerative"][1])
    assert tris["bvh-sah"][0] != pytest.approx(tris["bvh-agglomerative"][0], rel=1e-3)


def test_sah_builder_picks_the_best_split():
    """Four triangles along x (centroids in bins 0, 5, 10, 15 of the longest axis); the first is
    large. Split costs SA(L) N(L) + SA(R) N(R): after the first 96 x 1 + 5.68 x 3 = 113.04, after the
    second 342.56, after the third 720.88: the best plane isolates the large triangle, which is
    neither the object median nor the centre of the centroid box."""
    v = []
    for x, h in zip([0.5, 3.5, 6.5, 9.5], [6.0, 0.2, 0.2, 0.2]):
        v += [(x - 0.5, 0, 0), (x + 0.5, 0, 0), (x, h, h)]
    v, f = np.array(v), np.arange(12).reshape(4, 3)
    left, right, prim, root = build_binned_sah(*triangle_boxes(v, f))
    assert prim[left[root]] == 0
    bvh = from_topology(left, right, prim, root, v, f)
    assert sorted(bvh.prim[bvh.right[0]:][bvh.prim[bvh.right[0]:] >= 0]) == [1, 2, 3]


@pytest.mark.parametrize("name", BVH_CASTERS)
def test_random_rays_equal_brute_force(name):
    """Thousands of random rays and segments: the same triangle and t as the brute-force test over all
    triangles (ties, t equal for two triangles, may name either), and occlusion = a hit in [tnear, tfar]."""
    v, f = soup(400)
    caster = make_caster((v, f), name)
    rng = np.random.default_rng(2)
    n = 4000
    org = rng.random((n, 3)) * 1.4 - 0.2
    dirs = rng.standard_normal((n, 3))
    tnear = np.where(rng.random(n) < 0.5, 0.0, rng.random(n) * 0.3)
    tfar = np.where(rng.random(n) < 0.3, np.inf, tnear + rng.random(n) * 1.5)
    t, p = caster.intersect(org, dirs, tnear, tfar)
    t_ref, p_ref = brute(v, f, org, dirs, tnear, tfar)
    assert (p_ref >= 0).mean() > 0.2
    assert np.array_equal(t, t_ref)
    assert ((p == p_ref) | (t == t_ref)).all() and (p == p_ref).mean() > 0.999
    assert np.array_equal(caster.occluded(org, dirs, tnear, tfar), p_ref >= 0)


def edge_and_vertex_rays(v, f, n, seed):
    """Rays from points inside the unit sphere through its vertices and through points on its edges."""
    rng = np.random.default_rng(seed)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    pick = edges[rng.integers(len(edges), size=n)]
    s = rng.random((n, 1))
    s[: n // 4] = 0.0                 # a quarter through vertices
    s[n // 4: n // 2] = 0.5           # a quarter through edge midpoints
    target = v[pick[:, 0]] + s * (v[pick[:, 1]] - v[pick[:, 0]])
    org = rng.standard_normal((n, 3)) * 0.2
    return org, target - org


@pytest.mark.parametrize("name", [*BVH_CASTERS, "embree"])
def test_no_ray_slips_through_shared_edges_and_vertices(name):
    v, f = sphere()
    caster = make_caster((v, f), name)
    org, dirs = edge_and_vertex_rays(v, f, 6000, seed=3)
    t, p = caster.intersect(org, dirs, 0.0, np.inf)
    assert (p >= 0).all(), f"{(p < 0).sum()} rays slipped through"
    assert caster.occluded(org, dirs, 0.0, np.inf).all()
    # The hit is where the ray meets the sphere: t = 1 (the target) up to float32 rounding.
    np.testing.assert_allclose(t, 1.0, atol=1e-5 if name == "embree" else 1e-12)
    if name != "embree":
        t_ref, p_ref = brute(v, f, org, dirs, 0.0, np.inf)
        assert np.array_equal(t, t_ref)
        # Grazing rays along an edge, in the plane of a triangle through the sphere's centre: none
        # slips out between the two triangles either (they leave through the sphere somewhere).
        mid = 0.5 * (v[f[:, 0]] + v[f[:, 1]])
        o = np.zeros((len(f), 3))
        t2, p2 = caster.intersect(o, mid - o, 0.0, np.inf)
        assert (p2 >= 0).all()
