r"""Agglomerative BVH topologies (Walter, Bala, Kulkarni, Pingali 2008, section 4): ``bvh_agglomerative``
(locally-ordered clustering, Fig. 4) and ``bvh_agglomerative_heap`` (the heap-based version, Fig. 3).

Each triangle is a cluster with its bounding box; d(A, B) = the surface area of the box of A u B
(:data:`~lightcuts.cluster.dissimilarity.SURFACE_AREA`), non-decreasing under union (eq. 1), so
both build the greedy tree (Fig. 2, :func:`bvh_greedy_reference`) when no two candidate merges
tie. Both run the clustering engine that builds the agglomerative light trees
(:mod:`lightcuts.cluster.agglomerate`): its kd-tree over the clusters' box centres keeps, per node
and axis, the smallest upper end, the largest lower end and the smallest extent of its clusters'
boxes, and bounds the union's extent from them; that bound is at least section 4's (the separation
of A's centre from the node's box of centres plus half of A's size plus half the node's smallest
size; docs/math.md, "The kd-tree's lower bound"), so it prunes at least as much.

Topology arrays, over 2F-1 nodes: leaves 0..F-1 are triangles 0..F-1 (``left = right = -1``,
``prim`` = the triangle), merge m makes node F + m (``prim = -1``), the root is 2F - 2. Deterministic
and independent of the thread count.
"""

from __future__ import annotations

import numpy as np

from lightcuts.cluster.agglomerate import PARALLEL_MIN, agglomerate
from lightcuts.cluster.dissimilarity import SURFACE_AREA, surface_area
from lightcuts.cluster.greedy import greedy_cluster
from lightcuts.cluster.kd_tree import LEAF_SIZE
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_COORD


def _boxes(lo, hi, name: str):
    """lo, hi as C-contiguous float64 (F, 3), checked (one-line LightcutsError naming ``name``)."""
    lo = np.ascontiguousarray(lo, np.float64)
    hi = np.ascontiguousarray(hi, np.float64)
    if lo.ndim != 2 or lo.shape[1:] != (3,) or hi.shape != lo.shape:
        raise LightcutsError(f"{name}: box corners must be two (F, 3) arrays, got {lo.shape} and {hi.shape}")
    if not (np.all(np.abs(lo) <= MAX_COORD) and np.all(np.abs(hi) <= MAX_COORD)):
        raise LightcutsError(f"{name}: a box corner is not finite or exceeds {MAX_COORD:g} in magnitude")
    if np.any(lo > hi):
        raise LightcutsError(f"{name}: a box has lo > hi (triangle {int(np.flatnonzero((lo > hi).any(1))[0])})")
    return lo, hi


def bvh_agglomerative_stats(lo, hi, heap: bool = False, leafsize: int = LEAF_SIZE,
                            parallel_min: int = PARALLEL_MIN):
    """Either builder with its work counters: ``(left, right, prim, root, stats)``.

    lo, hi : (F, 3) float64 triangle box corners; heap : Fig. 3 instead of Fig. 4; leafsize,
    parallel_min : the engine's tuning knobs (:func:`~lightcuts.cluster.agglomerate.agglomerate`);
    stats : ``searches`` and ``rounds`` (locally ordered) or ``stale`` (heap).
    """
    name = "bvh-agglomerative-heap" if heap else "bvh-agglomerative"
    lo, hi = _boxes(lo, hi, name)
    n = len(lo)
    if n == 0:  # an empty scene: an empty topology, as the binned-SAH builder gives
        empty = np.zeros(0, np.int32)
        return empty, empty.copy(), empty.copy(), -1, {}
    return agglomerate(lo, hi, np.zeros((n, 3)), np.zeros(n), SURFACE_AREA, False, False, 0.0, heap=heap,
                       leafsize=leafsize, parallel_min=parallel_min,
                       what=(name, "check the triangles' coordinates"))


def bvh_agglomerative(lo, hi):
    """Locally-ordered agglomerative BVH (Fig. 4): ``(left, right, prim, root)``, int32 (2F-1,) arrays
    and the root's index, from (F, 3) float64 triangle box corners (see the module docstring)."""
    return bvh_agglomerative_stats(lo, hi)[:4]


def bvh_agglomerative_heap(lo, hi):
    """Heap-based agglomerative BVH (Fig. 3): the same arguments and result as :func:`bvh_agglomerative`."""
    return bvh_agglomerative_stats(lo, hi, heap=True)[:4]


def bvh_greedy_reference(lo, hi):
    """The greedy clustering (Fig. 2) of the clustering engine (:mod:`lightcuts.cluster.greedy`, the
    oracle the ``greedy`` light-tree builder runs too): repeatedly merge the two active clusters whose
    union box has the least surface area (the first pair in id order among ties). A reference for
    the tests, O(F^2) for typical inputs, for a few thousand triangles at most; the same result
    layout as :func:`bvh_agglomerative`."""
    lo, hi = _boxes(lo, hi, "bvh-greedy-reference")
    n = len(lo)
    left, right, prim = greedy_cluster(surface_area, False, 0.0, lo, hi, np.zeros((n, 3)), np.zeros(n))
    return left, right, prim, 2 * n - 2
