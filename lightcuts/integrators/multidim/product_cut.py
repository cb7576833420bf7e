r"""The multidimensional cut of one pixel: refining (gather node, light node) pairs by their bounds.

The pixel's reflected radiance is the sum over gather points i and lights j of
``w_i M_ij G_ij V_ij I_j``. A pair (G, L) of a gather node and a light node stands for all its
(i, j); its estimate is ``W_G I_L (M G V)(g, j)`` with g the representative gather point of G in
the pair's column (``greps[G, c]``; the columns are stratified over G's points, and sibling pairs
take different ones: :func:`sibling_column`) and the representative light j of L chosen for g
(multiple representatives: ``lreps[L, g % R]``), and its bound is
lightcuts.integrators.multidim.pair_bounds'. The cut starts at (gather root, each light tree's root)
and replaces the pair with the largest bound by its two children on the gather or the light side
(:func:`refine_gather`) until every bound is <= eps times the pixel's total (luminance) or the cut
holds max_cut pairs; then the gather nodes of the cut are checked for points that see a light
differently (lightcuts.integrators.multidim.gather_check), and the pairs of those that do are split
on the gather side. A child pair with the parent's (g, j) reuses its M G V: no new shadow ray. New
shadow rays wait in packets of the caster's width (lightcuts.accel.packets) and are cast together
without changing the cut (docs/math.md, "Multidimensional lightcuts").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.integrators.camera import hash_uniform
from lightcuts.accel.kernel_api import packet_occluded
from lightcuts.accel.packets import lane_occluded, packet_set_ray
from lightcuts.integrators.cut import luminance
from lightcuts.integrators.bounds import DIRECTIONAL
from lightcuts.integrators.forest import NB_HI, NB_I, NB_LEFT, NB_LO, NB_REP, NF_I, NK_LEFT, NK_REP, NK_RIGHT, REP_BITS
from lightcuts.integrators.heap import SLOT_MASK, entry_bound, heap_entry, heap_push, replace_top
from lightcuts.integrators.multidim.gather import GP_EXP, GP_NRM, GP_POS, GP_RD, GP_REFL, GP_RS, GP_W
from lightcuts.integrators.multidim.gather_tree import GK_LEFT, GN_ANG, GN_HI, GN_LO, GN_W
from lightcuts.integrators.multidim.gather_check import (GC_STATE, SK_COL, SK_DEPTH, SK_FORCE, SK_G, SK_L, SK_REP,
                                                          check_gather_nodes)
from lightcuts.integrators.multidim.pair_bounds import pair_bound
from lightcuts.integrators.multidim.pair_estimate import pair_mg
from lightcuts.integrators.reference import all_lights


@njit(cache=True, nogil=True)
def light_representatives(node_f, node_k, r_count, seed, lreps):
    """lreps ((K, R) int64): R representatives per light node. Column 0 is the tree's own; column r
    is built like it, bottom up: a parent takes its left child's column-r representative with
    probability I_left / I (luminance), else the right one's (seeded by node and column), so each is
    a light of the node drawn with probability proportional to its intensity, and a parent's is
    always one of its children's."""
    for k in range(node_f.shape[0] - 1, -1, -1):
        a = node_k[k, NK_LEFT]
        if a < 0:
            for r in range(r_count):
                lreps[k, r] = node_k[k, NK_REP]
            continue
        b = node_k[k, NK_RIGHT]
        la = luminance(node_f[a, NF_I], node_f[a, NF_I + 1], node_f[a, NF_I + 2])
        lb = luminance(node_f[b, NF_I], node_f[b, NF_I + 1], node_f[b, NF_I + 2])
        lreps[k, 0] = node_k[k, NK_REP]
        for r in range(1, r_count):
            u = hash_uniform(seed, k, r, 3)
            lreps[k, r] = lreps[a, r] if u * (la + lb) < la else lreps[b, r]


@njit(cache=True, error_model="numpy", forceinline=True)
def refine_gather(gn, gk, g, node_b, node_bi, k):
    """True to split the pair (g, k) on the gather side: the side that is not a leaf, else the one of
    larger size. Sizes in world units: a light node's box diagonal; a gather node's box diagonal plus
    its normal cone's half-angle times the distance between the two boxes' centres (a spread of
    normals matters as much as a spread of positions seen from there). For directional lights,
    angles: the gather cone's half-angle against the light's box diagonal (a box of directions)."""
    if gk[g, GK_LEFT] < 0:
        return False
    if node_bi[k, NB_LEFT] < 0:
        return True
    lsize = 0.0
    gsize = 0.0
    dist2 = 0.0
    for c in range(3):
        lo, hi = np.float64(node_b[k, NB_LO + c]), np.float64(node_b[k, NB_HI + c])
        lsize += (hi - lo) ** 2
        gsize += (gn[g, GN_HI + c] - gn[g, GN_LO + c]) ** 2
        dist2 += (0.5 * (lo + hi - gn[g, GN_LO + c] - gn[g, GN_HI + c])) ** 2
    if (node_bi[k, NB_REP] >> REP_BITS) >> 1 == DIRECTIONAL:
        return gn[g, GN_ANG] > np.sqrt(lsize)
    return np.sqrt(gsize) + gn[g, GN_ANG] * np.sqrt(dist2) > np.sqrt(lsize)


@njit(cache=True, nogil=True, error_model="numpy")
def _flush(cdata, buf, width, pk, lanes, lane_slot, gn, slot_k, slot_mgv, slot_ratio, slot_vis, node_b, t0, t1, t2):
    """Cast the waiting shadow rays (lanes 0..lanes-1 of the packet pk, lane r for the pair in slot
    lane_slot[r]) and zero the estimate of each pair whose ray is occluded. Returns the running
    total t less the estimates so removed."""
    packet_occluded(cdata, buf, pk, width, lanes)
    for r in range(lanes):
        if lane_occluded(pk, width, r):
            q = lane_slot[r]
            k = slot_k[q, SK_L]
            w = gn[slot_k[q, SK_G], GN_W]
            t0 -= w * slot_mgv[q, 0] * node_b[k, NB_I]
            t1 -= w * slot_mgv[q, 1] * node_b[k, NB_I + 1]
            t2 -= w * slot_mgv[q, 2] * node_b[k, NB_I + 2]
            slot_mgv[q, 0] = 0.0
            slot_mgv[q, 1] = 0.0
            slot_mgv[q, 2] = 0.0
            slot_ratio[q] = 1.0
            slot_vis[q] = False
    return t0, t1, t2


@njit(cache=True, error_model="numpy", forceinline=True)
def sibling_column(col, depth, g_count):
    """The gather-representative column of the light-side child that does not keep its parent's
    representative light: the parent's column ``col`` with bit ``depth mod b`` flipped (2^b the
    largest power of two <= g_count; the column itself if that is out of range), so the pairs of a
    subtree refined b levels below a pair use every column of [0, 2^b) once."""
    bits = 0
    while (2 << bits) <= g_count:
        bits += 1
    if bits == 0:
        return col
    c = col ^ (np.int64(1) << (depth % bits))
    return c if c < g_count else col


@njit(cache=True, error_model="numpy")
def product_cut(gp, gn, gk, gidx, greps, groot, node_b, node_bi, roots, light_f, lreps, eps, max_cut, clamp_d2,
                ray_offset, visibility, cdata, buf, width, pk, lane_slot, heap, slot_k, slot_mgv, slot_ratio, slot_vis,
                gcheck):
    """Reflected radiance of the pixel whose gather tree is (gp, gn, gk, groot), gidx the points in
    the tree's order (lightcuts.integrators.multidim.gather_tree), greps its representatives (R_G columns).

    node_b, node_bi, roots, light_f : the forest (lightcuts.integrators.forest); lreps : (K, R)
    :func:`light_representatives`; eps, max_cut : the stop test; clamp_d2, ray_offset, visibility,
    cdata, buf : as lightcuts.integrators.cut.light_mgv; width, pk, lane_slot ((width,) int64) : the
    caster's packet width, the packet (lightcuts.accel.packets.new_ray_packet) and the slot of each
    waiting shadow ray; heap (uint64), slot_k ((cap, SK_WIDTH) int64: gather node, light node, light
    representative, column, depth, forced: lightcuts.integrators.multidim.gather_check), slot_mgv
    (cap, 3), slot_ratio, slot_vis (bool: the pair's shadow ray is unoccluded, or still waiting) :
    scratch for max(max_cut, roots) + 2 pairs; gcheck : the gather nodes' check scratch (gather_check).
    Returns ``(L_r, L_g, L_b, pairs, shadow_rays, clamp_lost)`` like lightcuts.integrators.cut.lightcut,
    pairs = pairs in the final cut.

    Shadow rays wait in the packet as the lightcut's do (docs/math.md, "Deferred visibility"): a
    waiting ray counts as visible, so the running total is the upper end of the true one; a top
    bound above eps times it is refined without the rays' answers, and a top bound at or below it
    casts them and takes the test again. A waiting ray follows its pair's (g, j) into the child that
    keeps it. When the bounds are met, the
    gather nodes of the cut are checked (gather_check.check_gather_nodes) and the pairs of those
    that disagree refined on the gather side, until none is found or the cut is full.
    """
    r_count = lreps.shape[1]
    g_count = greps.shape[1]
    n = groot if groot > 0 else 1
    for g in range(n, 2 * n - 1):
        gcheck[g, GC_STATE] = 0
    # int64 zeros, not literals (one specialisation of the helpers they reach).
    n_slots = np.int64(0)
    size = np.int64(0)
    lanes = np.int64(0)
    rays = 0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for t in range(roots.shape[0]):
        k = roots[t]
        col = t % g_count
        grep = greps[groot, col]
        j = lreps[k, grep % r_count]
        m0, m1, m2, ratio, nr, o0, o1, o2, d0, d1, d2, tfar = pair_mg(gp, gn, gk, gidx, groot, grep, j, light_f,
                                                                       clamp_d2, ray_offset, visibility)
        rays += nr
        slot_vis[n_slots] = nr == 0 or m0 > 0.0 or m1 > 0.0 or m2 > 0.0
        w = gn[groot, GN_W]
        slot_k[n_slots, SK_G], slot_k[n_slots, SK_L], slot_k[n_slots, SK_REP] = groot, k, j
        slot_k[n_slots, SK_COL], slot_k[n_slots, SK_DEPTH], slot_k[n_slots, SK_FORCE] = col, 0, 0
        slot_mgv[n_slots, 0], slot_mgv[n_slots, 1], slot_mgv[n_slots, 2] = m0, m1, m2
        slot_ratio[n_slots] = ratio
        t0 += w * m0 * node_b[k, NB_I]
        t1 += w * m1 * node_b[k, NB_I + 1]
        t2 += w * m2 * node_b[k, NB_I + 2]
        if nr > 0 and tfar > 0.0:
            packet_set_ray(pk, width, lanes, o0, o1, o2, d0, d1, d2, 0.0, tfar)
            lane_slot[lanes] = n_slots
            lanes += 1
            if lanes == width:
                t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, gn, slot_k, slot_mgv, slot_ratio,
                                    slot_vis, node_b, t0, t1, t2)
                lanes = 0
        b0, b1, b2 = pair_bound(gp, gn, gk, groot, node_b, node_bi, k, node_bi[k, NB_LEFT] < 0, clamp_d2)
        b = luminance(b0, b1, b2)
        if b > 0.0:
            size = heap_push(heap, size, heap_entry(b, n_slots))
        n_slots += 1
    heap[size] = 0
    while True:
        while size > 0 and n_slots < max_cut:
            if entry_bound(heap[0]) <= eps * luminance(t0, t1, t2):
                if lanes == 0:
                    break
                t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, gn, slot_k, slot_mgv, slot_ratio,
                                    slot_vis, node_b, t0, t1, t2)
                lanes = 0
                continue
            s = np.int64(heap[0] & SLOT_MASK)
            g, k, pj = slot_k[s, SK_G], slot_k[s, SK_L], slot_k[s, SK_REP]
            pcol, depth = slot_k[s, SK_COL], slot_k[s, SK_DEPTH]
            pg = greps[g, pcol]
            split_g = slot_k[s, SK_FORCE] == 1 or refine_gather(gn, gk, g, node_b, node_bi, k)
            # The children (left in s's slot, right in a new one), their bounds and which of them keeps
            # s's representative pair (g, j) and so its shadow ray: on the gather side the one that
            # holds g, on the light side the one that holds j (one always does: both kinds of
            # representatives nest, and the column stays).
            keep = np.int64(0)
            bl = 0.0
            br = 0.0
            for side in range(2):
                cg = gk[g, GK_LEFT + side] if split_g else g
                ck = k if split_g else np.int64(node_bi[k, NB_LEFT]) + side
                rg = greps[cg, pcol]
                if rg == pg and lreps[ck, rg % r_count] == pj:
                    keep = side
                b0, b1, b2 = pair_bound(gp, gn, gk, cg, node_b, node_bi, ck, node_bi[ck, NB_LEFT] < 0, clamp_d2)
                b = luminance(b0, b1, b2)
                if b > 0.0 and cg >= n and gcheck[cg, GC_STATE] == 2:
                    b = np.inf  # a gather node found to disagree: refined on the gather side first
                if side == 0:
                    bl = b
                else:
                    br = b
            # The heap first (it needs the bounds only).
            size = replace_top(heap, size, bl, s, br, n_slots)
            # s's waiting ray, if any, moves to the child that keeps (g, j).
            for r in range(lanes):
                if lane_slot[r] == s:
                    lane_slot[r] = s if keep == 0 else n_slots
                    break
            w = gn[g, GN_W]
            t0 -= w * slot_mgv[s, 0] * node_b[k, NB_I]
            t1 -= w * slot_mgv[s, 1] * node_b[k, NB_I + 1]
            t2 -= w * slot_mgv[s, 2] * node_b[k, NB_I + 2]
            pm0, pm1, pm2, pratio, pvis = slot_mgv[s, 0], slot_mgv[s, 1], slot_mgv[s, 2], slot_ratio[s], slot_vis[s]
            # The child that keeps s's ray first: its slot is written before a full packet is cast.
            for step in range(2):
                side = step if keep != 1 else 1 - step
                cg = gk[g, GK_LEFT + side] if split_g else g
                ck = k if split_g else np.int64(node_bi[k, NB_LEFT]) + side
                cs = s if side == 0 else n_slots
                # Gather-side children keep the column; on the light side the child without j takes
                # the sibling column (docs/math.md, "Gather representatives").
                col = pcol if split_g or side == keep else sibling_column(pcol, depth, g_count)
                rg = greps[cg, col]
                j = lreps[ck, rg % r_count]
                vis = pvis
                nr = 0
                o0, o1, o2, d0, d1, d2, tfar = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
                if side == keep and not split_g:
                    m0, m1, m2, ratio = pm0, pm1, pm2, pratio
                else:
                    # The kept pair on the gather side: the parent's shadow ray, the child's own points'
                    # materials.
                    m0, m1, m2, ratio, nr, o0, o1, o2, d0, d1, d2, tfar = pair_mg(
                        gp, gn, gk, gidx, cg, rg, j, light_f, clamp_d2, ray_offset, visibility and side != keep)
                    if side == keep:
                        if not vis:
                            m0, m1, m2 = 0.0, 0.0, 0.0
                    else:
                        rays += nr
                        vis = nr == 0 or m0 > 0.0 or m1 > 0.0 or m2 > 0.0
                slot_vis[cs] = vis
                w = gn[cg, GN_W]
                slot_k[cs, SK_G], slot_k[cs, SK_L], slot_k[cs, SK_REP] = cg, ck, j
                slot_k[cs, SK_COL], slot_k[cs, SK_DEPTH] = col, depth + (0 if split_g else 1)
                slot_k[cs, SK_FORCE] = 1 if cg >= n and gcheck[cg, GC_STATE] == 2 else 0
                slot_mgv[cs, 0], slot_mgv[cs, 1], slot_mgv[cs, 2] = m0, m1, m2
                slot_ratio[cs] = ratio
                t0 += w * m0 * node_b[ck, NB_I]
                t1 += w * m1 * node_b[ck, NB_I + 1]
                t2 += w * m2 * node_b[ck, NB_I + 2]
                if side != keep and nr > 0 and tfar > 0.0:
                    packet_set_ray(pk, width, lanes, o0, o1, o2, d0, d1, d2, 0.0, tfar)
                    lane_slot[lanes] = cs
                    lanes += 1
                    if lanes == width:
                        t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, gn, slot_k, slot_mgv,
                                            slot_ratio, slot_vis, node_b, t0, t1, t2)
                        lanes = 0
            n_slots += 1
        if lanes > 0:
            t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, gn, slot_k, slot_mgv, slot_ratio, slot_vis,
                                node_b, t0, t1, t2)
            lanes = 0
        if not visibility or n < 2 or n_slots >= max_cut:
            break
        marked, nr = check_gather_nodes(gp, gn, gk, gidx, greps, n, light_f, clamp_d2, ray_offset, visibility, cdata,
                                        buf, heap, size, slot_k, slot_mgv, slot_vis, gcheck)
        rays += nr
        if not marked:
            break
    # The final sum again, from the cut itself: the running total drifts by cancellation.
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    for s in range(n_slots):
        k = slot_k[s, SK_L]
        w = gn[slot_k[s, SK_G], GN_W]
        e0 = w * slot_mgv[s, 0] * node_b[k, NB_I]
        e1 = w * slot_mgv[s, 1] * node_b[k, NB_I + 1]
        e2 = w * slot_mgv[s, 2] * node_b[k, NB_I + 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (slot_ratio[s] - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, n_slots, rays, lost


@njit(cache=True, error_model="numpy")
def all_pairs(gp, n, light_f, light_i, clamp_d2, ray_offset, visibility, cdata, buf):
    """The brute-force sum over every gather point (gp's first n rows) and every light: the pixel's
    reflected radiance the product cut approximates. Returns ``(L_r, L_g, L_b, pairs, shadow_rays,
    clamp_lost)``."""
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    rays = 0
    for i in range(n):
        r = all_lights(gp[i, GP_POS], gp[i, GP_POS + 1], gp[i, GP_POS + 2], gp[i, GP_NRM], gp[i, GP_NRM + 1],
                       gp[i, GP_NRM + 2], gp[i, GP_REFL], gp[i, GP_REFL + 1], gp[i, GP_REFL + 2], gp[i, GP_RD],
                       gp[i, GP_RD + 1], gp[i, GP_RD + 2], gp[i, GP_RS], gp[i, GP_RS + 1], gp[i, GP_RS + 2],
                       gp[i, GP_EXP], light_f, light_i, clamp_d2, ray_offset, visibility, cdata, buf)
        w = gp[i, GP_W]
        t0 += w * r[0]
        t1 += w * r[1]
        t2 += w * r[2]
        rays += r[4]
        lost += w * r[5]
    return t0, t1, t2, n * light_f.shape[0], rays, lost
