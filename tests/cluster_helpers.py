"""Diagnostics of the clustering engine's kd-tree search for the tests: the node bound of one cluster
against one kd node, and every active cluster's best match after a sequence of merges (one search
per cluster or the grouped search), which the tests compare with a brute-force scan."""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import row3
from lightcuts.cluster.kd_build import kd_build, kd_new
from lightcuts.cluster.kd_group_search import kd_group_by_leaf, kd_search_range
from lightcuts.cluster.kd_merge import kd_merge
from lightcuts.cluster.kd_search import _node_bound, kd_best_match
from lightcuts.cluster.kd_tree import LEAF_SIZE, S_HI, S_I, S_LO, S_NHI, S_NLO


@njit(cache=True)
def kd_node_bound(kd, a, k, metric_id, has_cone, use_cone, c):
    """The lower bound :func:`kd_best_match` uses for active cluster a against kd node k (with its
    cone part), as a float64: a diagnostic for the tests' check that it never exceeds d(A u B)."""
    sa = kd.slot_of[a]
    return _node_bound(kd.node_s, kd.node_n, k, row3(kd.slot_f, sa, S_LO), row3(kd.slot_f, sa, S_HI),
                       row3(kd.slot_f, sa, S_NLO), row3(kd.slot_f, sa, S_NHI), kd.slot_f[sa, S_I], metric_id,
                       has_cone, use_cone, c, np.inf)


@njit(cache=True)
def _best_matches_after(position, normal, luminance, merges, metric_id, has_cone, use_cone, c, leafsize, grouped):
    n = position.shape[0]
    kd, work = kd_new(position, position, normal, luminance, np.arange(position.shape[0]), leafsize)
    kd_build(kd, work)
    for m in range(merges.shape[0]):
        kd_merge(kd, work, merges[m, 0], merges[m, 1], n + m, True)
    active = np.flatnonzero(kd.slot_of >= 0)
    best = np.empty(active.shape[0], np.int64)
    best_d = np.empty(active.shape[0])
    if grouped:
        todo = active.copy()
        kd_group_by_leaf(kd, todo, todo.shape[0], np.empty(todo.shape[0], np.int64))
        by_id = np.full(2 * n - 1, -1, np.int32)
        by_id_d = np.empty(2 * n - 1)
        kd_search_range(kd, todo, todo.shape[0], by_id, by_id_d, metric_id, has_cone, use_cone, c, 64,
                        np.zeros(1, np.int64))
        for i in range(active.shape[0]):
            best[i] = by_id[active[i]]
            best_d[i] = by_id_d[active[i]]
        return active, best, best_d
    for i in range(active.shape[0]):
        best[i], best_d[i] = kd_best_match(kd, active[i], metric_id, has_cone, use_cone, c)
    return active, best, best_d


def best_matches_after_merges(position, normal, luminance, has_cone: bool, metric, c: float,
                              merges=None, leafsize: int = LEAF_SIZE, grouped: bool = False):
    """findBestMatch through the kd-tree for every active cluster after a sequence of merges.

    A diagnostic of the search (the tests compare it with a brute-force scan).
    position, normal : (N, 3) float64; luminance : (N,) float64
    has_cone : True for oriented lights; metric : a built-in Metric; c : cone-term scale
    merges : (M, 2) int cluster ids merged in order; merge m creates cluster N + m
    leafsize : clusters per kd leaf
    grouped : search the clusters of each leaf together (:func:`kd_search_range`), as the
        locally-ordered builder does, instead of one by one (:func:`kd_best_match`)
    Returns ``(active, best, d)``: (K,) int64 active cluster ids, their best matches and the metric values.
    """
    position = np.ascontiguousarray(position, np.float64)
    merges = np.zeros((0, 2), np.int64) if merges is None else np.ascontiguousarray(merges, np.int64)
    return _best_matches_after(position, np.ascontiguousarray(normal, np.float64),
                               np.ascontiguousarray(luminance, np.float64), merges, int(metric.id), bool(has_cone),
                               bool(has_cone and metric.uses_cone), float(c), int(leafsize), bool(grouped))
