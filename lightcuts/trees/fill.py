r"""The node fill of ``build_tree``: every node's bounds, intensity and representative, bottom-up,
the same way for all builders:

- the spatial box of its lights' positions (directional lights: of their unit directions);
- the normal cone from the box of its lights' normals (Walter et al. 2008, section 5; oriented
  lights only, omni and directional lights get ``cone_cos = -1`` and a zero axis);
- the summed RGB intensity;
- the representative: a leaf's is its light; a parent takes the representative of one child with
  probability proportional to that child's scalar intensity (luminance), else the other's.

The fill runs on the numba threads, one subtree per task (:func:`fill_nodes`); every node's values
depend only on its children's, so the tree does not depend on the thread count.

The representative draw is a counter-based hash of ``(seed, cluster)``, where a cluster is named by
the smallest light index of each of its two children; so the draw does not depend on how a builder
numbers its nodes, and two builders that produce the same clusters get the same representatives.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import box_union, row3, set_row3
from lightcuts.cluster.cones import cone_from_box
from lightcuts.hashing import mix64 as _mix64
from lightcuts.parallel import balance, on_threads, run_all, threads_for

# Nodes per block of _fill_blocks: their rows (about 200 bytes a node) stay in the L2 cache.
_FILL_BLOCK = 4096
# Below this many nodes the fill runs on one thread (thread start-up would cost more).
_PARALLEL_MIN = 40000


@njit(cache=True)
def _uniform(seed, a, b):
    """A uniform float in [0, 1) from (seed, a, b), a < b light indices."""
    h = _mix64(seed + np.uint64(0x9E3779B97F4A7C15))
    h = _mix64(h ^ np.uint64(a))
    h = _mix64(h ^ np.uint64(b))
    return float(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _fill_tasks(order, size, cut):
    """Split the preorder ``order`` into subtrees of at most ``cut`` nodes and the nodes above them
    (``size`` : each node's subtree size).

    Returns ``(tasks, tops)``: (M, 2) int64 ranges ``[s, e)`` of ``order``, each a whole subtree, and
    the positions in ``order`` of the remaining nodes (parents before children).
    """
    k = order.shape[0]
    # Room for any tree (untouched memory costs nothing): a growing array's slice copy would cost
    # numba seconds of compilation for its shape-mismatch error path.
    tasks = np.empty((k, 2), np.int64)
    tops = np.empty(k, np.int64)
    n_tasks = 0
    n_tops = 0
    t = 0
    while t < k:
        m = size[order[t]]
        if m <= cut:
            tasks[n_tasks, 0] = t
            tasks[n_tasks, 1] = t + m
            n_tasks += 1
            t += m
        else:
            tops[n_tops] = t
            n_tops += 1
            t += 1
    return tasks[:n_tasks], tops[:n_tops]


@njit(cache=True, nogil=True)
def _fill_ranges(order, ranges, left, right, light, position, normal, intensity, luminance, seed,
                 bbox_min, bbox_max, nlo, nhi, node_intensity, lum, first, rep):
    """Boxes, boxes of normals, intensities, luminances and representatives of the nodes
    ``order[s:e]`` for each row ``(s, e)`` of ``ranges`` (M, 2), last row first; each range's
    children are in it or already done (``order`` lists parents first).

    The nodes of a range are taken in blocks of _FILL_BLOCK from the end: in each block first the
    leaves (gathers from the light arrays), then the internal nodes (merges). A node's children come after
    it in ``order``, so they are done in an earlier block or earlier in its own. Passes over one
    kind of node at a time avoid a branch per node (leaves and internal nodes alternate
    unpredictably) and let the CPU overlap the leaves' independent cache misses; blocks keep the
    nodes just written in cache. ``first`` : smallest light index of each cluster, which names it
    for the representative draw.
    """
    block = _FILL_BLOCK
    # The block's leaves and internal nodes, listed without a branch per node: one spare slot each
    # takes the writes meant for the other list.
    leaves = np.empty(block + 1, np.int32)
    internal = np.empty(block + 1, np.int32)
    buf = np.empty((block, 10))  # a block's leaves' position, normal, intensity, luminance
    for j in range(ranges.shape[0] - 1, -1, -1):
        _fill_blocks(order, ranges[j, 0], ranges[j, 1], leaves, internal, buf, left, right, light, position, normal,
                     intensity, luminance, seed, bbox_min, bbox_max, nlo, nhi, node_intensity, lum, first, rep)


@njit(cache=True)
def _fill_blocks(order, s, e, leaves, internal, buf, left, right, light, position, normal, intensity, luminance, seed,
                 bbox_min, bbox_max, nlo, nhi, node_intensity, lum, first, rep):
    """The nodes ``order[s:e]`` for :func:`_fill_ranges`, with its scratch ``leaves``, ``internal``, ``buf``."""
    block = buf.shape[0]
    for end in range(e, s, -block):
        n_leaves = 0
        n_internal = 0
        for t in range(end - 1, max(end - block, s) - 1, -1):
            node = order[t]
            leaves[n_leaves] = node
            internal[n_internal] = node
            leaf = left[node] < 0
            n_leaves += leaf
            n_internal += not leaf
        # Leaves: the gathers from the light arrays go to a small buffer first, in a loop with
        # nothing else to wait on, so the CPU has many of their cache misses in flight.
        for t in range(n_leaves):
            i = light[leaves[t]]
            for d in range(3):
                buf[t, d] = position[i, d]
                buf[t, 3 + d] = normal[i, d]
                buf[t, 6 + d] = intensity[i, d]
            buf[t, 9] = luminance[i]
        for t in range(n_leaves):
            node = leaves[t]
            i = light[node]
            for d in range(3):
                bbox_min[node, d] = buf[t, d]
                bbox_max[node, d] = buf[t, d]
                nlo[node, d] = buf[t, 3 + d]
                nhi[node, d] = buf[t, 3 + d]
                node_intensity[node, d] = buf[t, 6 + d]
            lum[node] = buf[t, 9]
            first[node] = i
            rep[node] = i
        for t in range(n_internal):
            node = internal[t]
            a = left[node]
            b = right[node]
            lo, hi = box_union(row3(bbox_min, a, 0), row3(bbox_max, a, 0), row3(bbox_min, b, 0),
                               row3(bbox_max, b, 0))
            set_row3(bbox_min, node, 0, lo)
            set_row3(bbox_max, node, 0, hi)
            lo, hi = box_union(row3(nlo, a, 0), row3(nhi, a, 0), row3(nlo, b, 0), row3(nhi, b, 0))
            set_row3(nlo, node, 0, lo)
            set_row3(nhi, node, 0, hi)
            for d in range(3):
                node_intensity[node, d] = node_intensity[a, d] + node_intensity[b, d]
            lum[node] = lum[a] + lum[b]
            # Draw between the children in the order of their smallest light, not of node ids.
            if first[b] < first[a]:
                a, b = b, a
            first[node] = first[a]
            u = _uniform(seed, first[a], first[b])
            total = lum[a] + lum[b]
            take_a = u < 0.5 if total <= 0.0 else u * total < lum[a]
            rep[node] = rep[a] if take_a else rep[b]


@njit(cache=True, nogil=True)
def _fill_cones(nlo, nhi, axis, cos_half, s, e):
    """Cones of nodes s..e-1 from their boxes of normals (``axis`` may be ``nlo`` itself)."""
    for node in range(s, e):
        ax, ay, az, cc = cone_from_box(nlo[node, 0], nlo[node, 1], nlo[node, 2], nhi[node, 0], nhi[node, 1],
                                       nhi[node, 2])
        axis[node, 0] = ax
        axis[node, 1] = ay
        axis[node, 2] = az
        cos_half[node] = cc


def fill_nodes(order, size, left, right, light, position, normal, intensity, luminance, oriented, seed):
    """``(bbox_min, bbox_max, cone_axis, cone_cos, intensity, rep)`` of every node, bottom-up.

    ``order``, ``size`` : the nodes in preorder and their subtree sizes
    (:func:`~lightcuts.trees.checks.check_topology`).
    Subtrees of about k / (8 threads) nodes (:func:`_fill_tasks`) are filled on all numba threads
    (Python threads; the kernels release the GIL, and a ``parallel=True`` kernel would add seconds
    of compilation), then the nodes above them, then every cone. Each node's values depend on its
    children's only, so the result does not depend on the thread count.
    """
    k = left.shape[0]
    bbox_min, bbox_max, cone_axis, node_intensity = (np.empty((k, 3)) for _ in range(4))
    cone_cos = np.empty(k)
    rep = np.empty(k, np.int32)
    # Until the cone pass, cone_axis holds the low corner of each node's box of normals and
    # cone_cos its luminance: outputs as scratch, as fresh memory costs a page fault per 4 KB.
    nlo, lum = cone_axis, cone_cos
    nhi = np.empty((k, 3))
    first = np.empty(k, np.int32)
    threads = threads_for(k, _PARALLEL_MIN)
    tasks, tops = _fill_tasks(order, size, max(k // (8 * threads), _FILL_BLOCK))
    args = (left, right, light, position, normal, intensity, luminance, seed, bbox_min, bbox_max, nlo, nhi,
            node_intensity, lum, first, rep)
    run_all(lambda g: _fill_ranges(order, tasks[g], *args), balance(tasks[:, 1] - tasks[:, 0], threads))
    _fill_ranges(order, np.stack([tops, tops + 1], axis=1), *args)
    if oriented:
        on_threads(_fill_cones, k, _PARALLEL_MIN, nlo, nhi, cone_axis, cone_cos)
    else:
        cone_axis[:] = 0.0
        cone_cos[:] = -1.0
    return bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep
