r"""Merging clusters in the kd-tree (:mod:`lightcuts.cluster.kd_tree`).

Merging A and B into C = A u B writes C into the slot of whichever of A, B has its centre nearer
C's; the other slot is filled by the last active slot of its leaf (leaves stay dense), and the
active counts on its path drop by one. No node bound needs an update: C's upper ends, extents and
intensity are >= those of the cluster whose slot it takes and its lower ends <=, so the minima
``hmin``, ``emin``, ``imin`` and the maximum ``lmax`` still hold, as they do when a cluster is
removed; they only become loose. When the active clusters have fallen to half of those at the last
(re)build, the tree is rebuilt over them (:func:`kd_wants_rebuild`; amortised O(N log N) in all),
which makes the bounds tight again.

A batch of merges with distinct clusters (a round of the locally-ordered builder) does those whose
two clusters lie in one subtree below the top ``TOP_LEVELS`` levels on the threads, a subtree per
task (:func:`kd_merge_batch`): such merges touch only their subtree's slots and nodes. Then the
others, then the counts of the top levels (:func:`kd_merge_batch_finish`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import box_centre, box_union, row3, set_row3
from lightcuts.cluster.kd_build import kd_build
from lightcuts.cluster.kd_tree import (I_ACTIVE, I_BUILT, I_FIRST_LEAF, KD_SUBTREES, S_HI, S_I, S_LO, S_NHI, S_NLO,
                                       SLOT_DATA, TOP_LEVELS)

# The nodes of the top levels: their counts wait for kd_merge_batch_finish.
_BATCH_TOP = (1 << TOP_LEVELS) - 1


@njit(cache=True, nogil=True)
def _merge_rows(kd, left, right, first, n_pairs, new0, pair_sub, s, e, top):
    """:func:`kd_merge`'s slot work for the pairs ``left[first + p], right[first + p] -> new0 + p`` with
    ``s <= pair_sub[p] < e``, in order, and the active counts on the path from each emptied slot's
    leaf up to node ``top`` (0: the root; a first node of a level: to that level). One call for a
    whole batch: a call taking the KdTree costs a reference-count update per array, atomic
    operations that the two threads of a batch would contend for."""
    slot_f, slot_id, slot_of, slot_leaf = kd.slot_f, kd.slot_id, kd.slot_of, kd.slot_leaf
    node_cnt, leaf_start, info = kd.node_cnt, kd.leaf_start, kd.info
    for p in range(n_pairs):
        if not s <= pair_sub[p] < e:
            continue
        a = left[first + p]
        b = right[first + p]
        new_id = new0 + p
        sa = slot_of[a]
        sb = slot_of[b]
        lo_a, hi_a = row3(slot_f, sa, S_LO), row3(slot_f, sa, S_HI)
        lo_b, hi_b = row3(slot_f, sb, S_LO), row3(slot_f, sb, S_HI)
        lo, hi = box_union(lo_a, hi_a, lo_b, hi_b)
        nlo, nhi = box_union(row3(slot_f, sa, S_NLO), row3(slot_f, sa, S_NHI), row3(slot_f, sb, S_NLO),
                             row3(slot_f, sb, S_NHI))
        # C takes the slot of the one of A, B whose centre is nearer C's.
        ca = box_centre(lo_a, hi_a)
        cb = box_centre(lo_b, hi_b)
        cc = box_centre(lo, hi)
        da = 0.0
        db = 0.0
        for t in range(3):
            da += (ca[t] - cc[t]) ** 2
            db += (cb[t] - cc[t]) ** 2
        keep, drop = (sa, sb) if da <= db else (sb, sa)
        set_row3(slot_f, keep, S_LO, lo)
        set_row3(slot_f, keep, S_HI, hi)
        set_row3(slot_f, keep, S_NLO, nlo)
        set_row3(slot_f, keep, S_NHI, nhi)
        slot_f[keep, S_I] = slot_f[sa, S_I] + slot_f[sb, S_I]
        slot_id[keep] = new_id
        slot_of[a] = -1
        slot_of[b] = -1
        slot_of[new_id] = keep
        # Keep the leaf's active slots in front: its last active row fills the emptied slot, so a
        # search scans active slots only.
        leaf = slot_leaf[drop]
        last = leaf_start[leaf - info[I_FIRST_LEAF]] + node_cnt[leaf] - 1
        if last != drop:
            for t in range(SLOT_DATA):
                slot_f[drop, t] = slot_f[last, t]
            slot_id[drop] = slot_id[last]
            slot_of[slot_id[drop]] = drop
        slot_id[last] = -1
        k = leaf
        while k >= top:
            node_cnt[k] -= 1
            if k == 0:
                break
            k = (k - 1) >> 1


@njit(cache=True)
def kd_merge(kd, work, a, b, new_id, rebuild):
    """Replace active clusters a and b by their union ``new_id`` (see the module docstring); kd, work :
    the KdTree and KdWork of :func:`~lightcuts.cluster.kd_build.kd_new`.

    rebuild : rebuild the tree here when the active clusters have halved since the last build
    (False: the caller does, see :func:`kd_wants_rebuild`).
    """
    # The batch kernel with one pair (the same specialisation: int32 arrays).
    _merge_rows(kd, np.full(1, a, np.int32), np.full(1, b, np.int32), np.int64(0), np.int64(1), new_id,
                np.zeros(1, np.int32), np.int64(0), np.int64(1), np.int64(0))
    kd.info[I_ACTIVE] -= 1
    if rebuild and kd_wants_rebuild(kd):
        kd_build(kd, work)


@njit(cache=True)
def kd_subtree_starts(kd):
    """(KD_SUBTREES,) int64: the first slot of each subtree below the top levels (a subtree's leaves,
    hence its slots, are contiguous), or all -1 if the tree has no level below them. The subtree of
    active cluster a is then the number of t >= 1 with ``slot_of[a] >= starts[t]`` (-1 without
    levels): the caller counts it inline, since a call taking the KdTree costs a reference-count
    update per array (24 atomic operations), several times the count itself."""
    starts = np.full(KD_SUBTREES, -1, np.int64)
    first_leaf = kd.info[I_FIRST_LEAF]
    if first_leaf >= _BATCH_TOP:
        step = (first_leaf + 1) // KD_SUBTREES
        for t in range(KD_SUBTREES):
            starts[t] = kd.leaf_start[t * step]
    return starts


def kd_subtree(kd, a) -> int:
    """The subtree (0 .. KD_SUBTREES - 1) below the top levels that holds active cluster a, or -1 if
    the tree has no level below them: from Python (kernels count it inline, see
    :func:`kd_subtree_starts`)."""
    starts = kd_subtree_starts(kd)
    return -1 if starts[0] < 0 else int(np.count_nonzero(kd.slot_of[a] >= starts[1:]))


@njit(cache=True, nogil=True)
def kd_merge_batch(kd, left, right, new0, n_pairs, pair_sub, s, e):
    """Merges ``left[new0 + p], right[new0 + p] -> new0 + p`` of the batch's pairs p with
    ``pair_sub[p]`` in [s, e) (their subtree, :func:`kd_subtree`), in batch order; the counts of the
    top levels and ``info`` wait for :func:`kd_merge_batch_finish`."""
    _merge_rows(kd, left, right, new0, n_pairs, new0, pair_sub, s, e, np.int64(_BATCH_TOP))


@njit(cache=True)
def kd_merge_batch_finish(kd, left, right, new0, n_pairs, pair_sub):
    """After :func:`kd_merge_batch` over every subtree: the batch's other merges (pair_sub -1), in
    order, then the counts of the top levels and ``info``."""
    node_cnt = kd.node_cnt
    top = _BATCH_TOP if kd.info[I_FIRST_LEAF] >= _BATCH_TOP else 0
    _merge_rows(kd, left, right, new0, n_pairs, new0, pair_sub, np.int64(-1), np.int64(0), top)
    if top > 0:
        for k in range(top - 1, -1, -1):
            node_cnt[k] = node_cnt[2 * k + 1] + node_cnt[2 * k + 2]
    kd.info[I_ACTIVE] -= n_pairs


@njit(cache=True)
def kd_wants_rebuild(kd):
    """Whether the active clusters have halved since the last (re)build."""
    info = kd.info
    return 2 * info[I_ACTIVE] <= info[I_BUILT] and info[I_ACTIVE] > 1

