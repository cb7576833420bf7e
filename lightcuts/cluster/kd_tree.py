r"""The kd-tree over the active clusters of the agglomerative builders: its storage and layout.

findBestMatch(A) (Walter, Bala, Kulkarni, Pingali 2008, section 3.1) asks for the active cluster B
that minimises the metric d(A u B) (:mod:`lightcuts.cluster.dissimilarity`). The kd-tree's points are the
clusters' box centres, and every node keeps enough to bound d(A u B) from below for every B under
it, which lets a branch-and-bound search skip most of the tree (the bound: docs/math.md,
"The kd-tree's lower bound"). Building it: :mod:`lightcuts.cluster.kd_build`; searching it:
:mod:`lightcuts.cluster.kd_search` (one cluster) and :mod:`lightcuts.cluster.kd_group_search` (the
clusters of a kd leaf together); merging clusters in it: :mod:`lightcuts.cluster.kd_merge`.

Shape: implicit and balanced, the children of node k are 2k+1 and 2k+2 and all leaves lie at one
depth; each node splits at the median of its clusters' centres along the longest side of its cell.
A "slot" holds one active cluster; a leaf owns a contiguous run of slots whose first ones hold its
active clusters (dense leaves: a search never meets an empty slot). Node bounds are float32 rounded
outwards (minima down, maxima up): they stay valid at half the memory traffic, and a search is
bound by the latency of node and slot rows. Merges keep every bound valid without touching it
(:mod:`lightcuts.cluster.kd_merge`); a rebuild, when the active clusters have halved, makes them tight
again.

The tree is a :class:`KdTree` of flat arrays and its (re)build scratch a :class:`KdWork`: named
tuples, which numba compiles as plain tuples of arrays. A call that takes either costs an atomic
reference-count update per array, so kernels never take one inside a per-cluster loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# Slot row columns (float64): the cluster's spatial box lo, hi and scalar intensity in the first
# cache line (all that the first test of a pair reads), then its box of unit normals nlo, nhi.
S_LO, S_HI, S_I, S_NLO, S_NHI = 0, 3, 6, 7, 10
SLOT_DATA = 13
SLOT_WIDTH = 16
# Spatial node row columns (float32, one 64-byte line per node), per axis: the smallest upper end
# hmin, the largest lower end lmax and the smallest extent emin of the clusters' boxes; the smallest
# intensity imin; split value and axis (which only order the search).
N_HMIN, N_LMAX, N_EMIN, N_IMIN, N_SPLIT, N_AXIS = 0, 3, 6, 9, 10, 11
NODE_WIDTH = 16
# Normal node row columns (float32): the same three for the boxes of normals.
NH_MIN, NL_MAX, NE_MIN = 0, 3, 6
NORMAL_WIDTH = 9
# Entries of KdTree.info.
I_FIRST_LEAF, I_BUILT, I_LEAFSIZE, I_ACTIVE = 0, 1, 2, 3

# Default clusters per kd leaf (docs/performance.md, "Leaf size").
LEAF_SIZE = 32
# A (re)build splits this many levels on one thread, then hands the 2^TOP_LEVELS subtrees below to
# threads or does them in turn: the same tree either way. Merges within one of those subtrees run in
# parallel too (kd_merge.kd_merge_batch).
TOP_LEVELS = 3
KD_SUBTREES = 1 << TOP_LEVELS


class KdTree(NamedTuple):
    """The kd-tree's arrays; S slots (N, the clusters at the first build), M nodes, L leaves.

    slot_f : (S, SLOT_WIDTH) float64, rows aligned to 64 bytes: columns ``S_*``.
    slot_id : (S,) int32 the cluster in each slot, -1 for an empty slot.
    slot_of : (2N-1,) int32 cluster id -> slot, -1 when the cluster is not active.
    slot_leaf : (S,) int32 the kd leaf (node index) that owns each slot.
    node_s : (M, NODE_WIDTH) float32, rows aligned to 64 bytes: columns ``N_*``.
    node_n : (M, NORMAL_WIDTH) float32: columns ``NH_MIN, NL_MAX, NE_MIN``, read only when the
        spatial part of a bound does not prune.
    node_cnt : (M,) int32 active clusters under each node (0: skip it).
    leaf_start : (L+1,) int64 leaf ``first_leaf + j`` owns slots ``leaf_start[j] .. [j+1]-1``, of
        which the first ``node_cnt[first_leaf + j]`` hold its active clusters.
    info : (4,) int64 indexed by ``I_*``: the first leaf's node index, the clusters at the last
        (re)build, the leaf size, the active clusters.
    stack_node, stack_lb : (STACK,) int64, float64 a search's traversal stack (nodes and their
        bounds); dbuf : (leaf size,) float64 one leaf's metric values without the cone term. These
        three are a search's scratch: each search thread has its own (kd_search.kd_scratch).
    """

    slot_f: np.ndarray
    slot_id: np.ndarray
    slot_of: np.ndarray
    slot_leaf: np.ndarray
    node_s: np.ndarray
    node_n: np.ndarray
    node_cnt: np.ndarray
    leaf_start: np.ndarray
    info: np.ndarray
    stack_node: np.ndarray
    stack_lb: np.ndarray
    dbuf: np.ndarray


class KdWork(NamedTuple):
    """A (re)build's scratch, for N slots: keys (N, 3) float64 the centres being split, idx (N,)
    int32 the slot each key came from, slot_tmp (N, SLOT_WIDTH) float64 and id_tmp (N,) int32 the
    slot rows gathered in leaf order."""

    keys: np.ndarray
    idx: np.ndarray
    slot_tmp: np.ndarray
    id_tmp: np.ndarray
