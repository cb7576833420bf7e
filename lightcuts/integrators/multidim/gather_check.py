r"""The visibility check of a pixel's gather nodes: which of them see the pair's light differently at two
of their points (docs/math.md, "Gather nodes that disagree").

A pair (G, L) shades every point of G with the visibility of one representative point. Where G's
points see the lights differently (a contact shadow over part of the pixel, points on two objects),
that error has one sign in every pair that holds G and adds up over hundreds of pairs whose bounds
are each below eps. So once the cut has converged, each inner gather node of the cut is checked
once: its PROBES pairs with the largest bounds each get one probe ray, from the point of G's other
child in the pair's column to the pair's light, and the answer is compared with the pair's own ray
at its representative. A node where both points are lit by the light and one sees it and the other
does not disagrees: every pair that holds it is marked to be refined on the gather side next
(:func:`lightcuts.integrators.multidim.product_cut.product_cut` goes on refining). The probes are
a few rays per pixel, cast one by one.

``gcheck`` ((2 spp, GC_WIDTH) int64, scratch): per gather node its state (GC_STATE: 0 not checked,
1 checked, 2 disagrees: every pair that holds it, now or later, is refined on the gather side) and
the heap positions of its pairs to probe (GC_PAIRS.., -1 for none).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import occluded
from lightcuts.integrators.heap import SLOT_MASK, heap_entry, heap_push
from lightcuts.integrators.multidim.gather_tree import GK_LEFT, GK_RIGHT
from lightcuts.integrators.multidim.pair_estimate import pair_mg

#: Probe rays per checked gather node (its pairs with the largest bounds).
PROBES = 4
GC_STATE, GC_PAIRS, GC_WIDTH = 0, 1, 1 + PROBES
# Columns of a pair's integer row (slot_k, (cap, SK_WIDTH) int64): gather node, light node, light
# representative, column of the gather representatives, light-side refinements since its tree's
# root (the column's stratification), 1 if it must be refined on the gather side.
SK_G, SK_L, SK_REP, SK_COL, SK_DEPTH, SK_FORCE, SK_WIDTH = 0, 1, 2, 3, 4, 5, 6


@njit(cache=True, nogil=True, error_model="numpy")
def check_gather_nodes(gp, gn, gk, gidx, greps, n, light_f, clamp_d2, ray_offset, visibility, cdata, buf, heap, size,
                       slot_k, slot_mgv, slot_vis, gcheck):
    """Check the inner gather nodes of the cut not checked yet (module docstring) and mark the
    pairs of those that disagree: ``slot_k[q, SK_FORCE] = 1`` and the heap entry of bound inf (the
    heap is rebuilt). n : the tree's points; heap, size : the cut's max-heap (every pair with a
    bound > 0); the other arguments as product_cut's. Returns ``(marked, probe rays)``."""
    for g in range(n, 2 * n - 1):
        for c in range(PROBES):
            gcheck[g, GC_PAIRS + c] = -1
    # Each unchecked node's PROBES pairs with the largest bounds (entries order as their bounds).
    for t in range(size):
        g = slot_k[np.int64(heap[t] & SLOT_MASK), SK_G]
        if g < n or gcheck[g, GC_STATE] != 0:
            continue
        for c in range(PROBES):
            u = gcheck[g, GC_PAIRS + c]
            if u < 0 or heap[u] < heap[t]:
                for d in range(PROBES - 1, c, -1):
                    gcheck[g, GC_PAIRS + d] = gcheck[g, GC_PAIRS + d - 1]
                gcheck[g, GC_PAIRS + c] = t
                break
    rays = 0
    for g in range(n, 2 * n - 1):
        if gcheck[g, GC_STATE] != 0 or gcheck[g, GC_PAIRS] < 0:
            continue
        gcheck[g, GC_STATE] = 1
        for c in range(PROBES):
            u = gcheck[g, GC_PAIRS + c]
            if u < 0:
                break
            q = np.int64(heap[u] & SLOT_MASK)
            col, j = slot_k[q, SK_COL], slot_k[q, SK_REP]
            a = greps[g, col]
            # The pair's own answer is a's when a would cast the ray as a point of its own (lit by
            # j, so the pair's ray left from a) and a ray was cast: the estimate is not zero (seen)
            # or the pair is shadowed.
            seen = slot_mgv[q, 0] > 0.0 or slot_mgv[q, 1] > 0.0 or slot_mgv[q, 2] > 0.0
            if not (seen or not slot_vis[q]) or pair_mg(gp, gn, gk, gidx, a, a, j, light_f, clamp_d2, ray_offset,
                                                        visibility)[4] == 0:
                continue
            left = gk[g, GK_LEFT]
            b = greps[gk[g, GK_RIGHT], col] if greps[left, col] == a else greps[left, col]
            _, _, _, _, nr, o0, o1, o2, d0, d1, d2, tfar = pair_mg(gp, gn, gk, gidx, b, b, j, light_f, clamp_d2,
                                                                    ray_offset, visibility)
            if nr == 0:
                continue
            rays += 1
            # A light closer than the ray offset is seen.
            if seen == (tfar > 0.0 and occluded(cdata, buf, o0, o1, o2, d0, d1, d2, 0.0, tfar)):
                gcheck[g, GC_STATE] = 2
    marked = False
    for t in range(size):
        q = np.int64(heap[t] & SLOT_MASK)
        g = slot_k[q, SK_G]
        if g >= n and gcheck[g, GC_STATE] == 2:
            slot_k[q, SK_FORCE] = 1
            heap[t] = heap_entry(np.inf, q)
            marked = True
    if marked:
        # Rebuilt in place: the t-th push reads heap[t] first and writes positions <= t only.
        m = size
        size = np.int64(0)
        for t in range(m):
            size = heap_push(heap, size, heap[t])
        heap[size] = 0
    return marked, rays
