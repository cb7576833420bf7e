"""References for the tests of the clustering engine (``lightcuts/cluster/``): random clusters, their
tracked bounds through merges, the engine's pair cost over all pairs (the brute force a kd-tree
search must equal), the numpy formulas of the dissimilarities and cones (docs/math.md, "Light
trees"), written independently of the engine, and readers of the kd-tree's storage."""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_search import _pair_d
from lightcuts.cluster.kd_tree import (I_ACTIVE, I_FIRST_LEAF, N_EMIN, N_HMIN, N_IMIN, N_LMAX, NE_MIN, NH_MIN, NL_MAX,
                                       S_HI, S_I, S_LO, S_NHI, S_NLO)

from conftest import unit

WALTER2008, WALTER2005, SURFACE_AREA = 0, 1, 2
#: (metric id, has_cone) of the searches: the light metrics with and without a cone, the surface area.
METRIC_CASES = [(WALTER2008, True), (WALTER2008, False), (WALTER2005, True), (WALTER2005, False),
                (SURFACE_AREA, False)]
#: Cone-term scale of the tests: the cone term weighs about as much as the boxes' spread.
C = 0.3


def random_items(n, rng, kind="random", spread=0.05):
    """(lo, hi, normal, intensity) of n items: boxes with centres in the unit cube and half-sizes up to
    ``spread`` (0: points), unit normals of a few perturbed faces, intensities in [0.05, 1.05).

    kind "random": continuous values (no ties, almost surely); "duplicates": every item twice;
    "grid": positions, sizes, normals and intensities on coarse grids (duplicates and ties everywhere).
    """
    m = (n + 1) // 2 if kind == "duplicates" else n
    centre = rng.random((m, 3))
    half = spread * rng.random((m, 3))
    faces = np.array([[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1.0]])
    normal = unit(faces[rng.integers(0, len(faces), m)] + 0.3 * rng.normal(size=(m, 3)))
    intensity = 0.05 + rng.random(m)
    if kind == "grid":
        centre = np.round(centre * 2) / 2
        half = np.round(half / spread * 2) * spread / 2 if spread else half
        normal = unit(np.round(normal))
        intensity = np.round(intensity * 2) / 2 + 0.5
    lo, hi = centre - half, centre + half
    if kind == "duplicates":
        lo, hi, normal, intensity = (np.repeat(x, 2, axis=0)[:n] for x in (lo, hi, normal, intensity))
    return lo, hi, normal, intensity


class Clusters:
    """The active clusters' bounds, tracked from the items through merges, independently of the
    kd-tree: box ``[lo, hi]``, box of normals ``[nlo, nhi]``, summed intensity; cluster i < N is item
    ``order[i]``, merge m makes cluster N + m. Items are single normals, or boxes of normals
    ``[normal, normal_hi]`` (clusters made elsewhere)."""

    def __init__(self, lo, hi, normal, intensity, order=None, normal_hi=None):
        n = len(lo)
        order = np.arange(n) if order is None else np.asarray(order)
        k = 2 * n - 1
        self.n = n
        self.lo, self.hi = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
        self.nlo, self.nhi = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
        self.inten = np.full(k, np.nan)
        self.lo[:n], self.hi[:n] = lo[order], hi[order]
        self.nlo[:n], self.nhi[:n] = normal[order], (normal if normal_hi is None else normal_hi)[order]
        self.inten[:n] = intensity[order]
        self.alive = list(range(n))
        self.next = n

    def merge(self, a, b):
        """Record the merge of active clusters a and b; returns the new cluster's id."""
        new = self.next
        self.lo[new], self.hi[new] = np.minimum(self.lo[a], self.lo[b]), np.maximum(self.hi[a], self.hi[b])
        self.nlo[new], self.nhi[new] = np.minimum(self.nlo[a], self.nlo[b]), np.maximum(self.nhi[a], self.nhi[b])
        self.inten[new] = self.inten[a] + self.inten[b]
        self.alive = [c for c in self.alive if c not in (a, b)] + [new]
        self.next += 1
        return new

    def random_pair(self, rng):
        i, j = rng.choice(len(self.alive), 2, replace=False)
        return self.alive[i], self.alive[j]

    def costs(self, ids, metric_id, has_cone, c=C):
        """(K, K) d(A u B) of the clusters ``ids`` as the engine defines it, inf on the diagonal."""
        ids = np.asarray(ids, np.int64)
        return pair_costs(self.lo[ids], self.hi[ids], self.nlo[ids], self.nhi[ids], self.inten[ids], metric_id,
                          has_cone, uses_cone(metric_id, has_cone), c)

    def fresh_kd(self, ids, leafsize):
        """A kd-tree built afresh over the clusters ``ids`` (its cluster j is ``ids[j]``)."""
        ids = np.asarray(ids, np.int64)
        kd, work = kd_new(self.lo[ids], self.hi[ids], self.nlo[ids], self.inten[ids], np.arange(len(ids)), leafsize)
        # kd_new starts from single items (a point of normals); a cluster's box of normals goes in
        # the documented slot columns before the build.
        kd.slot_f[:len(ids), S_NLO:S_NLO + 3] = self.nlo[ids]
        kd.slot_f[:len(ids), S_NHI:S_NHI + 3] = self.nhi[ids]
        kd_build(kd, work)
        return kd, work


def uses_cone(metric_id, has_cone):
    """Whether a search computes the union's cone (the builders' rule: oriented items, a cone metric)."""
    return bool(has_cone and metric_id != SURFACE_AREA)


@njit(cache=True)
def pair_costs(lo, hi, nlo, nhi, inten, metric_id, has_cone, use_cone, c):
    """(K, K) float64: d(A u B) for every pair of the K clusters by the engine's pair cost (union box,
    cone of the union's box of normals, summed intensity), inf on the diagonal: the brute force that
    findBestMatch through the kd-tree must equal exactly."""
    k = lo.shape[0]
    out = np.full((k, k), np.inf)
    for i in range(k):
        for j in range(k):
            if i != j:
                out[i, j] = _pair_d(metric_id, has_cone and use_cone, c, (lo[i, 0], lo[i, 1], lo[i, 2]),
                                    (hi[i, 0], hi[i, 1], hi[i, 2]), (nlo[i, 0], nlo[i, 1], nlo[i, 2]),
                                    (nhi[i, 0], nhi[i, 1], nhi[i, 2]), inten[i], (lo[j, 0], lo[j, 1], lo[j, 2]),
                                    (hi[j, 0], hi[j, 1], hi[j, 2]), (nlo[j, 0], nlo[j, 1], nlo[j, 2]),
                                    (nhi[j, 0], nhi[j, 1], nhi[j, 2]), inten[j])
    return out


# ------------------------------------------------------------------------- the papers' formulas

def np_cone_cos(nlo, nhi):
    """cos(beta) of the cap of the box of normals' circumscribed sphere (Walter 2008, section 5),
    without the engine's rounding allowance; -1 for the full sphere. (..., 3) -> (...)."""
    m = 0.5 * (nlo + nhi)
    r2 = (0.25 * (nhi - nlo) ** 2).sum(-1)
    d = np.linalg.norm(m, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = (1.0 + d * d - r2) / (2.0 * d)
    return np.where(d > 0, np.clip(cos, -1.0, 1.0), -1.0)


def np_metric(metric_id, intensity, extent, cone_cos, has_cone, c):
    """d(C) from C's intensity, box extents (..., 3) and cone cosine (docs/math.md, "Clustering
    metrics"): walter2008 I (L^2 + c^2 S^2)^2 with S = sin(beta), 1 past 90 degrees; walter2005
    I (L^2 + c^2 (1 - cos beta)^2); the surface area 2 (xy + yz + zx). No cone term without a cone."""
    ex, ey, ez = np.moveaxis(np.asarray(extent, np.float64), -1, 0)
    l2 = ex * ex + ey * ey + ez * ez
    cone_cos = np.asarray(cone_cos, np.float64)
    if metric_id == WALTER2008:
        s = np.where(cone_cos <= 0, 1.0, np.sqrt(np.maximum(0.0, 1.0 - cone_cos ** 2)))
        return intensity * (l2 + (c * s) ** 2 * has_cone) ** 2
    if metric_id == WALTER2005:
        return intensity * (l2 + (c * (1.0 - cone_cos)) ** 2 * has_cone)
    return 2.0 * (ex * ey + ey * ez + ez * ex)


# ------------------------------------------------------------------------------ kd-tree storage

def leaves(kd):
    """[(leaf node, first slot, active count)] of the current tree."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    return [(first_leaf + j, int(kd.leaf_start[j]), int(kd.node_cnt[first_leaf + j])) for j in range(first_leaf + 1)]


def node_leaves(kd, k):
    """The leaves under kd node k (the tree is implicit and balanced: they are contiguous)."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    span = (first_leaf + 1).bit_length() - (k + 1).bit_length()
    leaf0 = ((k + 1) << span) - 1
    return range(leaf0, leaf0 + (1 << span))


def node_clusters(kd, k):
    """(M,) int64 the active clusters under kd node k, read from its leaves' active slots."""
    first_leaf = int(kd.info[I_FIRST_LEAF])
    out = [kd.slot_id[int(kd.leaf_start[leaf - first_leaf]):][:int(kd.node_cnt[leaf])] for leaf in node_leaves(kd, k)]
    return np.concatenate(out).astype(np.int64)


def active(kd):
    """(K,) int64 the active cluster ids, ascending."""
    return np.flatnonzero(kd.slot_of >= 0)


def check_storage(kd, cl):
    """The kd-tree holds exactly the active clusters of ``cl``, each in one leaf, in that leaf's first
    slots (dense leaves), with their bounds as tracked; the inverse maps and counts agree."""
    seen = []
    first_leaf = int(kd.info[I_FIRST_LEAF])
    for leaf, s0, cnt in leaves(kd):
        s1 = int(kd.leaf_start[leaf - first_leaf + 1])
        assert s0 + cnt <= s1, leaf
        assert (kd.slot_id[s0:s0 + cnt] >= 0).all() and (kd.slot_id[s0 + cnt:s1] == -1).all(), leaf
        for s in range(s0, s0 + cnt):
            c = int(kd.slot_id[s])
            seen.append(c)
            assert kd.slot_of[c] == s and kd.slot_leaf[s] == leaf, (c, s)
            for col, ref in ((S_LO, cl.lo), (S_HI, cl.hi), (S_NLO, cl.nlo), (S_NHI, cl.nhi)):
                np.testing.assert_array_equal(kd.slot_f[s, col:col + 3], ref[c])
            assert kd.slot_f[s, S_I] == cl.inten[c]
    assert sorted(seen) == sorted(cl.alive), "every active cluster in exactly one leaf"
    assert list(active(kd)) == sorted(cl.alive) and int(kd.info[I_ACTIVE]) == len(seen)
    for k in range(first_leaf):
        assert kd.node_cnt[k] == kd.node_cnt[2 * k + 1] + kd.node_cnt[2 * k + 2], k


def down32(x):
    """The largest float32 <= x (numpy, elementwise)."""
    f = np.asarray(x, np.float64).astype(np.float32)
    return np.where(f > x, np.nextafter(f, np.float32(-np.inf)), f)


def up32(x):
    """The smallest float32 >= x."""
    f = np.asarray(x, np.float64).astype(np.float32)
    return np.where(f < x, np.nextafter(f, np.float32(np.inf)), f)


def check_node_bounds(kd, cl, exact):
    """Every node's stored bounds hold for every active cluster under it: smallest upper end hmin,
    largest lower end lmax, smallest extent emin (boxes and boxes of normals), smallest intensity
    imin. ``exact`` (right after a (re)build): they equal those of the node's clusters, rounded
    outwards to float32."""
    for k in range(2 * int(kd.info[I_FIRST_LEAF]) + 1):
        if kd.node_cnt[k] == 0:
            continue
        m = node_clusters(kd, k)
        row = kd.node_s[k, :N_IMIN + 1].astype(np.float64)
        nrow = kd.node_n[k].astype(np.float64)
        for (lo, hi), r, h, l, e in (((cl.lo, cl.hi), row, N_HMIN, N_LMAX, N_EMIN),
                                     ((cl.nlo, cl.nhi), nrow, NH_MIN, NL_MAX, NE_MIN)):
            want = hi[m].min(0), lo[m].max(0), (hi[m] - lo[m]).min(0)
            got = r[h:h + 3], r[l:l + 3], r[e:e + 3]
            assert (got[0] <= want[0]).all() and (got[1] >= want[1]).all() and (got[2] <= want[2]).all(), k
            if exact:
                for g, w, rnd in zip(got, want, (down32, up32, down32)):
                    np.testing.assert_array_equal(g, rnd(w), err_msg=str(k))
        assert row[N_IMIN] <= cl.inten[m].min()
        if exact:
            assert row[N_IMIN] == down32(cl.inten[m].min())
