"""Grid casters (grid, recursive-grid, octree, hug): hits equal brute force on random, voxel-face and
cluster-grazing rays; Isolate and Cluster3d against brute-force components; references equal box
overlaps; Fig. 9's nesting; coplanar piles terminate; saved grids load; stats."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from lightcuts.accel import RAY_CASTERS, make_caster
from lightcuts.accel.grids.grid_caster import GridCaster
from lightcuts.accel.grids.grid_kernels import GRID_DEVICE
from lightcuts.accel.grids.grids import GridForest
from lightcuts.accel.grids.hug import cluster3d, isolate, length_filter
from lightcuts.accel.triangles import ray_frame, triangle_boxes, watertight_t
from lightcuts.errors import LightcutsError

from brute import brute

#: The registered grid casters (those whose device functions are the grid kernels'), and their aliases.
GRID_CASTERS = [n for n in RAY_CASTERS.names() if RAY_CASTERS.entry(n).trait("device") is GRID_DEVICE]
GRID_ALIASES = [a for a, n in RAY_CASTERS.aliases().items() if n in GRID_CASTERS]
# Small MAXP and depth limits, so that the tests' small scenes nest several levels.
DEEP = [("recursive-grid", dict(maxp=4, max_depth=4)), ("octree", dict(maxp=4, max_depth=8)), ("hug", {})]


def multiscale_scene(seed=3):
    """Spheres of several sizes (clusters), a large floor, clumps of small and scattered medium triangles."""
    rng = np.random.default_rng(seed)
    parts = [trimesh.Trimesh([[-6, -6, -3], [6, -6, -3], [6, 6, -3], [-6, 6, -3]], [[0, 1, 2], [0, 2, 3]])]
    for r in (0.3, 0.6, 1.2):
        for _ in range(2):
            m = trimesh.creation.icosphere(subdivisions=2, radius=r)
            m.apply_translation(rng.uniform(-4, 4, 3))
            parts.append(m)
    mesh = trimesh.util.concatenate(parts)
    v, f = [mesh.vertices], [mesh.faces]
    off = len(mesh.vertices)
    for centre, size, count in ((rng.uniform(-4, 4, 3), 0.05, 150), (rng.uniform(-4, 4, 3), 0.05, 150),
                                (np.zeros(3), 1.0, 60)):
        c = centre + rng.uniform(-1, 1, (count, 1, 3)) * (4 if size == 1.0 else 0.3)
        tris = (c + size * rng.standard_normal((count, 3, 3))).reshape(-1, 3)
        v.append(tris)
        f.append(off + np.arange(3 * count).reshape(count, 3))
        off += 3 * count
    return np.concatenate(v).astype(np.float32).astype(np.float64), np.concatenate(f)


def special_rays(forest: GridForest, rng, n):
    """Rays lying in voxel faces (of every kind of grid) and along grid (cluster) box faces, and rays
    aimed at grid box corners: origins (n, 3), directions (n, 3)."""
    org, dirs = [], []
    ext = forest.hi - forest.lo
    for _ in range(n):
        g = int(rng.integers(forest.n_grids))
        a = int(rng.integers(3))
        kind = rng.integers(3)
        p = forest.lo[g] + rng.random(3) * ext[g]
        d = rng.standard_normal(3)
        if kind == 0:      # in a voxel face of grid g
            i = int(rng.integers(forest.res[g, a] + 1))
            p[a] = forest.lo[g, a] + i * (ext[g, a] / forest.res[g, a])
            d[a] = 0.0
        elif kind == 1:    # along a face of grid g's box, from outside it
            p[a] = forest.lo[g, a] if rng.random() < 0.5 else forest.hi[g, a]
            d[a] = 0.0
            b = (a + 1) % 3
            p[b] = forest.lo[g, b] - 0.5 * ext[g, b] - 0.1
            d[b] = abs(d[b]) + 0.1
        else:              # at a corner of grid g's box
            corner = np.where(rng.random(3) < 0.5, forest.lo[g], forest.hi[g])
            p = corner + 3 * rng.standard_normal(3)
            d = corner - p
        org.append(p)
        dirs.append(d)
    return np.array(org), np.array(dirs)


@pytest.fixture(scope="module")
def scene():
    return multiscale_scene()


@pytest.fixture(scope="module", params=[*GRID_CASTERS, *[k for k, _ in DEEP[:2]]])
def caster(request, scene):
    v, f = scene
    if request.param in GRID_CASTERS:
        return make_caster((v, f), request.param)
    return make_caster((v, f), {"type": request.param, **dict(DEEP)[request.param]})


def test_hits_equal_brute_force(caster, scene):
    """Closest hit and occlusion equal brute force: random rays (many starting inside grids), random
    [tnear, tfar] segments, voxel-face, box-face and box-corner rays."""
    v, f = scene
    rng = np.random.default_rng(11)
    n = 2500
    lo, hi = v.min(axis=0), v.max(axis=0)
    o1 = lo + rng.random((n, 3)) * (hi - lo) * 1.2 - 0.1 * (hi - lo)
    d1 = rng.standard_normal((n, 3))
    o2, d2 = special_rays(caster.forest, rng, 2500)
    org, dirs = np.concatenate([o1, o2]), np.concatenate([d1, d2])
    tnear = np.where(rng.random(len(org)) < 0.3, rng.random(len(org)) * 2, 0.0)
    tfar = np.where(rng.random(len(org)) < 0.3, tnear + rng.random(len(org)) * 4, np.inf)
    t_ref, p_ref, tri = brute(v, f, org, dirs, tnear, tfar)
    assert (p_ref >= 0).mean() > 0.15
    t, p = caster.intersect(org, dirs, tnear, tfar)
    np.testing.assert_array_equal(t, t_ref)
    hit = p >= 0
    np.testing.assert_array_equal(hit, p_ref >= 0)
    # Ties (same t) may name another triangle; the one named must give that t.
    same = p[hit] == p_ref[hit]
    for i in np.flatnonzero(hit)[~same]:
        assert watertight_t(tri, p[i], *org[i], *ray_frame(*dirs[i])) == t_ref[i]
    np.testing.assert_array_equal(caster.occluded(org, dirs, tnear, tfar), p_ref >= 0)
    # Segments that end before the first hit are not occluded.
    short = np.where(np.isfinite(t_ref), 0.5 * (t_ref + tnear), tnear + 1.0)
    _, p_short, _ = brute(v, f, org, dirs, tnear, short)
    np.testing.assert_array_equal(caster.occluded(org, dirs, tnear, short), p_short >= 0)


# ------------------------------------------------------------------------------ Isolate, Cluster3d

def _components(lo, hi, delta):
    """Brute-force connected components of segments: i ~ j when their distance is < delta."""
    n = len(lo)
    label = np.arange(n)

    def find(i):
        while label[i] != i:
            label[i] = label[label[i]]
            i = label[i]
        return i

    for i in range(n):
        for j in range(n):
            if max(0.0, lo[j] - hi[i], lo[i] - hi[j]) < delta:
                label[find(i)] = find(j)
    return np.array([find(i) for i in range(n)])


def _same_partition(a, b):
    # Two labellings are the same partition when each pair of labels maps one to one.
    pairs = set(zip(a.tolist(), b.tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 60), st.integers(0, 6)), min_size=1, max_size=40), st.integers(1, 5))
def test_isolate_splits_where_gaps_reach_delta(segs, delta):
    """Isolate's pieces are the connected components of 'distance < delta' (integer ends: gaps
    exactly equal to delta occur)."""
    lo = np.array([s[0] for s in segs], float)
    hi = lo + np.array([s[1] for s in segs], float)
    assert _same_partition(isolate(lo, hi, float(delta)), _components(lo, hi, delta))


def test_isolate_gap_equal_to_delta_splits():
    assert len(set(isolate(np.array([0.0, 3.0]), np.array([1.0, 4.0]), 2.0))) == 2
    assert len(set(isolate(np.array([0.0, 2.9]), np.array([1.0, 4.0]), 2.0))) == 1


@pytest.mark.parametrize("seed", range(4))
def test_cluster3d_partitions_into_connected_clusters(seed):
    """Clusters partition the level, and each is one component along x, y and z."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 10, (6, 3))
    lo = (centres[rng.integers(6, size=300)] + rng.standard_normal((300, 3)) * rng.uniform(0.05, 1.0, (300, 1)))
    hi = lo + rng.uniform(0, 0.3, (300, 3))
    idx = np.arange(300, dtype=np.int64)
    starts, ends, work = cluster3d(idx, lo, hi, 0.05)
    assert np.array_equal(np.sort(idx), np.arange(300))
    sizes = ends - starts
    assert sizes.sum() == 300 and (sizes > 0).all()
    order = np.argsort(starts)
    assert starts[order[0]] == 0 and np.array_equal(starts[order[1:]], ends[order[:-1]])
    for s, e in zip(starts, ends):
        members = idx[s:e]
        for a in range(3):
            assert len(set(_components(lo[members, a], hi[members, a], 0.05))) == 1
    assert 1 < len(starts) < 300 and work > 0


def test_filter_equal_counts():
    lengths = np.random.default_rng(0).lognormal(size=3000)
    f, lev = length_filter(lengths, 3)
    assert len(f) == 4 and (np.diff(f) > 0).all()
    assert f[0] <= lengths.min() and lengths.max() < f[-1]
    assert np.array_equal(lev, np.searchsorted(f, lengths, side="right") - 1)
    assert np.abs(np.bincount(lev) - 1000).max() <= 1
    f1, lev1 = length_filter(np.ones(10), 3)      # ties merge slices
    assert len(f1) == 2 and (lev1 == 0).all()


# ------------------------------------------------------------------------------ references

def _overlapped(forest, g, lo, hi, eps):
    """Voxels of grid g that the box [lo - eps, hi + eps] overlaps (closed boxes)."""
    vlo, vhi = forest.voxel_boxes(g)
    return set((forest.voxel0[g] + np.flatnonzero(((vlo <= hi + eps) & (vhi >= lo - eps)).all(axis=1))).tolist())


def _structures(scene):
    v, f = scene
    out = [(k, GridCaster(v, f, kind=k).forest) for k in ("grid", "recursive-grid", "octree", "hug")]
    return out + [(k, GridCaster(v, f, kind=k, **p).forest) for k, p in DEEP[:2]]


@pytest.fixture(scope="module")
def structures(scene):
    return _structures(scene)


def test_objects_referenced_by_exactly_the_voxels_their_box_overlaps(structures, scene):
    blo, bhi = triangle_boxes(*scene)
    eps = 1e-8 * np.abs(scene[0]).max()
    for kind, forest in structures:
        owner = forest.grid_of_voxels()
        vox = np.repeat(np.arange(forest.n_voxels), np.diff(forest.vox_items))
        by_grid_item = {}
        for vv, it in zip(vox.tolist(), forest.item_refs.tolist()):
            by_grid_item.setdefault((int(owner[vv]), it), set()).add(vv)
        split = np.diff(forest.vox_subs) > 0
        for (g, it), voxels in by_grid_item.items():
            inner = _overlapped(forest, g, blo[it], bhi[it], -eps)
            outer = _overlapped(forest, g, blo[it], bhi[it], eps)
            if kind != "hug":   # a subdivided voxel hands its items to its sub-grid
                inner = {x for x in inner if not split[x]}
            assert inner <= voxels <= outer, (kind, g, it)
        if kind == "hug":   # each triangle lives in exactly one grid, which contains its box
            grids = {}
            for (g, it) in by_grid_item:
                grids.setdefault(it, []).append(g)
            assert sorted(grids) == list(range(len(blo))) and all(len(x) == 1 for x in grids.values())
            g_of = np.array([grids[i][0] for i in range(len(blo))])
            assert (forest.lo[g_of] <= blo).all() and (bhi <= forest.hi[g_of]).all()


def test_subgrids_referenced_by_every_parent_voxel_they_overlap(structures):
    for kind, forest in structures:
        owner = forest.grid_of_voxels()
        vox = np.repeat(np.arange(forest.n_voxels), np.diff(forest.vox_subs))
        refs = {}
        for vv, c in zip(vox.tolist(), forest.sub_refs.tolist()):
            refs.setdefault(c, set()).add(vv)
        assert sorted(refs) == list(range(1, forest.n_grids)), kind   # every grid but the top is nested
        for c, voxels in refs.items():
            parents = {int(owner[x]) for x in voxels}
            assert len(parents) == 1, (kind, c)
            P = parents.pop()
            eps = 1e-8 * (np.abs(forest.hi[0]).max() + 1)
            assert (forest.lo[P] - eps <= forest.lo[c]).all() and (forest.hi[c] <= forest.hi[P] + eps).all()
            inner = _overlapped(forest, P, forest.lo[c], forest.hi[c], -eps)
            outer = _overlapped(forest, P, forest.lo[c], forest.hi[c], eps)
            assert inner <= voxels <= outer, (kind, c)
        if kind in ("recursive-grid", "octree"):   # a sub-grid is exactly its voxel
            assert all(len(x) == 1 for x in refs.values())
    assert max(f.depth for k, f in structures if k in ("recursive-grid", "octree")) >= 3


def test_hug_nests_each_grid_in_the_finest_grid_that_contains_it(structures):
    forest = dict(structures)["hug"]
    par = forest.parents()
    contains = lambda a, b: (forest.lo[a] <= forest.lo[b]).all() and (forest.hi[b] <= forest.hi[a]).all()
    for c in range(1, forest.n_grids):
        # No grid placed before c inside its parent (a sibling of c) contains c.
        siblings = [s for s in range(1, c) if par[s] == par[c]]
        assert not any(contains(s, c) for s in siblings), c
        assert forest.level[c] <= forest.level[par[c]]
    assert forest.n_grids > 3 and forest.depth >= 2


# ------------------------------------------------------------------------------ termination, files, stats

def test_coplanar_piles_terminate_for_every_structure():
    """200 identical triangles and 300 overlapping ones in one plane: every structure builds with a
    bounded size and still equals brute force."""
    rng = np.random.default_rng(2)
    same = np.tile([[0.1, 0.1, 0.37], [0.9, 0.2, 0.37], [0.3, 0.8, 0.37]], (200, 1))
    pts = rng.random((300, 3, 3)) * [1, 1, 0] + [0, 0, 0.37]
    v = np.concatenate([same, pts.reshape(-1, 3)])
    f = np.arange(len(v)).reshape(-1, 3)
    org = rng.random((400, 3)) * [1, 1, 2] - [0, 0, 0.5]
    dirs = rng.standard_normal((400, 3))
    t_ref, _, _ = brute(v, f, org, dirs, 0.0, np.inf)
    # Every voxel that the pile's box covers holds the 200 identical triangles: refs against the grid's.
    grid_refs = make_caster((v, f), "grid").stats()["refs_per_item"]
    deep = [{"type": n, "maxp": 2, "max_depth": 30} for n in GRID_CASTERS if "maxp" in RAY_CASTERS.entry(n).params]
    assert len(deep) == 2 and len(GRID_ALIASES) == 6
    for spec in [*GRID_CASTERS, *GRID_ALIASES, *deep]:
        c = make_caster((v, f), spec)
        s = c.stats()
        assert s["voxels"] < 50 * len(f) and s["refs_per_item"] < 20 * grid_refs, (spec, s)
        np.testing.assert_array_equal(c.intersect(org, dirs)[0], t_ref)


def test_saved_grids_load_and_cast_the_same(tmp_path, scene):
    v, f = scene
    c = make_caster((v, f), "hug")
    c.save(tmp_path / "g.npz")
    d = GridCaster.load(tmp_path / "g.npz", v, f)
    rng = np.random.default_rng(0)
    org, dirs = rng.standard_normal((300, 3)), rng.standard_normal((300, 3))
    assert np.array_equal(c.intersect(org, dirs)[1], d.intersect(org, dirs)[1])
    with pytest.raises(LightcutsError, match="indexes|grids index"):
        GridCaster.load(tmp_path / "g.npz", v, f[:-1])
    z = dict(np.load(tmp_path / "g.npz"))
    z["item_refs"] = z["item_refs"] + len(f)
    np.savez(tmp_path / "bad.npz", **z)
    with pytest.raises(LightcutsError, match="bad.npz: grid file: vox_items references outside"):
        GridCaster.load(tmp_path / "bad.npz", v, f)


def test_stats(structures, scene):
    v, f = scene
    for name in GRID_CASTERS:
        s = make_caster((v, f), name).stats()
        for k in ("build_s", "memory_bytes", "voxels", "items", "nu_1", "depth", "refs_per_item"):
            assert k in s
        assert s["items"] == len(f) and s["nu_1"] == s["voxels"] / s["items"]
        assert s["memory_bytes"] == s["structure_bytes"] + 72 * len(f) and s["structure_bytes"] > 0
        assert s["refs_per_item"] >= 1.0
    h = make_caster((v, f), "hug").stats()
    assert sum(h["grids_per_level"]) == h["grids"] and h["levels"] == 3 and h["clustering_ratio"] > 0
    # Cube-root criterion: about n voxels for n triangles.
    assert make_caster((v, f), "grid").stats()["voxels"] == pytest.approx(len(f), rel=0.5)


def test_builds_are_deterministic(scene):
    v, f = scene
    for kind, params in (("grid", {}), *DEEP):
        a, b = GridCaster(v, f, kind=kind, **params).forest, GridCaster(v, f, kind=kind, **params).forest
        for k in ("lo", "hi", "res", "voxel0", "vox_items", "item_refs", "vox_subs", "sub_refs"):
            assert getattr(a, k).tobytes() == getattr(b, k).tobytes(), (kind, k)


def test_empty_mesh():
    for name in GRID_CASTERS:
        c = make_caster((np.zeros((0, 3)), np.zeros((0, 3), int)), name)
        t, p = c.intersect(np.zeros((2, 3)), np.ones((2, 3)))
        assert np.isinf(t).all() and (p == -1).all() and not c.occluded(np.zeros((2, 3)), np.ones((2, 3))).any()


@pytest.mark.parametrize("name", GRID_CASTERS)
def test_no_ray_slips_through_a_closed_mesh(name):
    """Rays from inside an icosphere through its vertices and edge midpoints all hit it, through the
    grids as through the watertight test alone."""
    mesh = trimesh.creation.icosphere(subdivisions=3)
    v, f = mesh.vertices.astype(np.float32).astype(np.float64), mesh.faces
    caster = make_caster((v, f), name)
    targets = np.concatenate([v, 0.5 * (v[mesh.edges_unique[:, 0]] + v[mesh.edges_unique[:, 1]])])
    rng = np.random.default_rng(4)
    org = np.concatenate([np.zeros((len(targets), 3)), 0.3 * rng.standard_normal((len(targets), 3))])
    dirs = np.concatenate([targets, targets]) - org
    t, p = caster.intersect(org, dirs, 0.0, np.inf)
    assert (p >= 0).all(), f"{(p < 0).sum()} rays slipped through"
    assert caster.occluded(org, dirs, 0.0, np.inf).all()


def test_declared_parameters_reach_the_build(scene):
    """An alias, the mapping with the same values and (for MAXP 50) the bare name build the same
    forest; another value builds another one, and the stats report what was used."""
    v, f = scene
    arrays = ("lo", "hi", "res", "vox_items", "item_refs", "vox_subs", "sub_refs")

    def forest(spec):
        return make_caster((v, f), spec).forest

    for kind in ("recursive-grid", "octree"):
        fifty = [forest(s) for s in (kind, f"{kind}-50", {"type": kind, "maxp": 50})]
        assert all(getattr(x, k).tobytes() == getattr(fifty[0], k).tobytes() for x in fifty[1:] for k in arrays)
        c = make_caster((v, f), {"type": kind, "maxp": 4, "max_depth": 4})
        assert c.stats()["maxp"] == 4 and c.stats()["max_depth"] == 4
        assert c.forest.n_grids > fifty[0].n_grids
        assert forest(f"{kind}-150").item_refs.tobytes() == forest({"type": kind, "maxp": 150}).item_refs.tobytes()
    a, b = make_caster((v, f), "hug"), make_caster((v, f), {"type": "hug", "alpha": 0.5, "levels": 2})
    assert a.stats()["alpha"] == 0.01 and b.stats()["alpha"] == 0.5 and b.stats()["levels"] == 2
    assert a.stats()["levels"] == 3 and sum(b.stats()["clusters_per_level"]) < sum(a.stats()["clusters_per_level"])
    with pytest.raises(LightcutsError, match=r"^ray caster.maxp: ray caster 'hug' has no parameter 'maxp'"):
        make_caster((v, f), {"type": "hug", "maxp": 3})
    with pytest.raises(LightcutsError, match=r"^ray caster.maxp: 0 is below the minimum 1"):
        make_caster((v, f), {"type": "octree", "maxp": 0})
