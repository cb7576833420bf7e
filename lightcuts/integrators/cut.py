r"""The lightcut at one receiver (Walter et al. 2005, section 4): numba device functions over the forest.

A cut is a set of forest nodes (lightcuts.integrators.forest) that covers every light once; its value is
the sum of the nodes' estimates ``M_j G_j V_j I_C``, and an inner node's error bound is
``I_C M_ub G_ub`` (docs/math.md, "Cluster estimate" and "Error bound"). From the roots, the node
with the largest bound is replaced by its children until that bound is <= eps times the luminance
of the total, or the cut holds ``max_cut`` nodes (docs/math.md, "The cut and its stop test");
one max-heap over all trees (lightcuts.integrators.heap) picks the node. A child with its parent's
representative reuses the parent's ``M G V``, so a refinement casts one shadow ray at most; a node
with a zero bound never enters the heap. Shadow rays wait in packets of ``width`` (8, or 4 without
native 8-wide packets) without changing the cut (docs/math.md, "Deferred visibility").

Scratch, one set per thread, reused across receivers; ``cap = max(max_cut, n_roots) + 2`` (the heap
keeps a 0 sentinel after its last entry): ``heap (cap,) uint64``, ``slot_node (cap,) int64`` (the
node in each slot of the cut), ``slot_mgv (cap, 3) float64`` (its representative's RGB ``M G V``),
``slot_ratio (cap,) float64`` (unclamped over clamped G of the representative, 1 if not clamped),
``lane_slot (width,) int64`` (the slot of each waiting shadow ray, -1 for none) and the packet.

The refinement loop's device functions are ``forceinline`` and take scalars: a call that LLVM does
not inline passes its 15-40 arguments through the stack, cannot overlap with its neighbours, and
pays a reference-count update per array argument (docs/performance.md, "Renderer").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.kernel_api import occluded, packet_occluded
from lightcuts.hashing import mix64
from lightcuts.accel.packets import lane_occluded, packet_set_ray
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.integrators.bounds import DIRECTIONAL, cluster_error_bound_framed, receiver_frames
from lightcuts.integrators.forest import (LF_INDIRECT, LF_NRM, LF_POS, LF_TYPE, NB_AXIS, NB_COS, NB_FA, NB_HI, NB_I,
                                     NB_LEFT, NB_LO, NB_REP, REP_BITS, REP_MASK)
from lightcuts.integrators.heap import SLOT_MASK, entry_bound, heap_entry, heap_push, replace_top
from lightcuts.integrators.shading import light_geometry, material_term

LUM_R, LUM_G, LUM_B = (float(v) for v in LUMINANCE)


@njit(cache=True, error_model="numpy", forceinline=True)
def luminance(r, g, b):
    """Rec. 709 luminance of an RGB triple (inf stays inf)."""
    return LUM_R * r + LUM_G * g + LUM_B * b


@njit(cache=True, error_model="numpy", forceinline=True)
def _light_mg(typ, p0, p1, p2, nl0, nl1, nl2, c2, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2,
              rs0, rs1, rs2, exponent, ray_offset):
    """``M G`` of one light (its row's values as scalars) and the shadow ray that decides its V.

    Arguments as :func:`light_mgv`, with the light's type, position p, normal nl and its clamp c2.
    Returns ``(mg_r, mg_g, mg_b, ratio, lit, o0, o1, o2, d0, d1, d2, tfar)``: lit = M G > 0 in some
    channel (else the rest is meaningless); the shadow ray from o along the unit d up to tfar (no
    ray when tfar <= 0). Scalars only: a function taking arrays that LLVM does not inline costs a
    reference-count update per array and call.
    """
    w0, w1, w2, _, g, ratio = light_geometry(typ, p0, p1, p2, nl0, nl1, nl2, x0, x1, x2, c2)
    if g <= 0.0:
        return 0.0, 0.0, 0.0, 1.0, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    m0, m1, m2 = material_term(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, w0, w1, w2)
    if m0 <= 0.0 and m1 <= 0.0 and m2 <= 0.0:
        return 0.0, 0.0, 0.0, 1.0, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # The light is on the normal's side (M > 0), so the origin moves off the surface towards it.
    o0, o1, o2 = x0 + ray_offset * n0, x1 + ray_offset * n1, x2 + ray_offset * n2
    if typ == DIRECTIONAL:
        d0, d1, d2, tfar = w0, w1, w2, np.inf
    else:
        # Lights sit on surfaces: stop short of the light so its own surface does not shadow it.
        d0, d1, d2 = p0 - o0, p1 - o1, p2 - o2
        dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        inv = 1.0 / dist
        d0, d1, d2, tfar = d0 * inv, d1 * inv, d2 * inv, dist - ray_offset
    return m0 * g, m1 * g, m2 * g, ratio, True, o0, o1, o2, d0, d1, d2, tfar


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def light_mgv(j, light_f, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
              clamp_d2, ray_offset, visibility, cdata, buf):
    """``M G V`` per RGB channel of light j at the receiver x, with one shadow ray when M G > 0.

    light_f : the forest's light rows; x : receiver; n : unit shading normal (facing the viewer);
    r : mirror direction of wo; rd, rs, exponent : the receiver's material; clamp_d2 : squared
    clamping distance for indirect lights (0: off); ray_offset : shadow-ray origin offset along n and
    the gap left before the light, world units; visibility : False skips the shadow ray (V = 1:
    unshadowed shading, and timing without rays); cdata, buf : the caster's data and scratch
    (lightcuts.accel.kernel_api).
    Returns ``(mgv_r, mgv_g, mgv_b, ratio, rays)``: ratio = unclamped / clamped G (>= 1),
    rays = shadow rays counted (0 or 1; 1 also for a light closer than ray_offset, not cast).
    """
    c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
    m0, m1, m2, ratio, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
        np.int64(light_f[j, LF_TYPE]), light_f[j, LF_POS], light_f[j, LF_POS + 1], light_f[j, LF_POS + 2],
        light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2], c2, x0, x1, x2, n0, n1, n2,
        r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, ray_offset)
    if not lit:
        return 0.0, 0.0, 0.0, 1.0, 0
    if not visibility:
        return m0, m1, m2, ratio, 0
    if tfar > 0.0 and occluded(cdata, buf, o0, o1, o2, d0, d1, d2, 0.0, tfar):
        return 0.0, 0.0, 0.0, 1.0, 1
    return m0, m1, m2, ratio, 1


@njit(cache=True, error_model="numpy", forceinline=True)
def _record_bound(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, flags,
                  lo0, lo1, lo2, hi0, hi1, hi2, a0, a1, a2, cone_cos, cone_fa, i0, i1, i2):
    """Error bound in luminance of an inner node from its record's values (``NB_*``, as float64)."""
    c2 = clamp_d2 if flags & 1 else 0.0
    b0, b1, b2 = cluster_error_bound_framed(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                                            exponent, np.int64(flags >> 1), lo0, lo1, lo2, hi0, hi1, hi2,
                                            a0, a1, a2, cone_cos, cone_fa, i0, i1, i2, c2)
    return luminance(b0, b1, b2)


@njit(cache=True, error_model="numpy", forceinline=True)
def node_bound(k, node_b, node_bi, x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
               clamp_d2):
    """Error bound of node k in luminance; 0 for a leaf (its estimate is exact). fr : the receiver's
    frames (lightcuts.integrators.bounds.receiver_frames)."""
    if node_bi[k, NB_LEFT] < 0:
        return 0.0
    f = node_b
    # Explicit float64: float32 arguments would compile a second specialisation of the bound.
    return _record_bound(x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2,
                         node_bi[k, NB_REP] >> REP_BITS, np.float64(f[k, NB_LO]), np.float64(f[k, NB_LO + 1]),
                         np.float64(f[k, NB_LO + 2]), np.float64(f[k, NB_HI]), np.float64(f[k, NB_HI + 1]),
                         np.float64(f[k, NB_HI + 2]), np.float64(f[k, NB_AXIS]), np.float64(f[k, NB_AXIS + 1]),
                         np.float64(f[k, NB_AXIS + 2]), np.float64(f[k, NB_COS]), np.float64(f[k, NB_FA]),
                         np.float64(f[k, NB_I]),
                         np.float64(f[k, NB_I + 1]), np.float64(f[k, NB_I + 2]))



@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def _flush(cdata, buf, width, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio, node_b,
           t0, t1, t2):
    """Cast the waiting shadow rays (lanes 0..lanes-1 of the packet pk) and zero the estimate of
    each slot whose ray is occluded. Returns the cut's RGB total t less the estimates so removed."""
    packet_occluded(cdata, buf, pk, width, lanes)
    for r in range(lanes):
        q = lane_slot[r]
        if q >= 0 and lane_occluded(pk, width, r):
            k = slot_node[q]
            t0 -= slot_mgv[q, 0] * node_b[k, NB_I]
            t1 -= slot_mgv[q, 1] * node_b[k, NB_I + 1]
            t2 -= slot_mgv[q, 2] * node_b[k, NB_I + 2]
            slot_mgv[q, 0] = 0.0
            slot_mgv[q, 1] = 0.0
            slot_mgv[q, 2] = 0.0
            slot_ratio[q] = 1.0
    return t0, t1, t2


@njit(cache=True, error_model="numpy")
def lightcut(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
             node_b, node_bi, roots, light_f, eps, max_cut, clamp_d2, ray_offset, visibility, cdata, buf, width, pk,
             heap, slot_node, slot_mgv, slot_ratio, lane_slot, tol, skey):
    """Radiance reflected at x towards the viewer, by a lightcut through every tree of the forest.

    x, n, r, rd, rs, exponent : receiver as in :func:`light_mgv`; node_b, node_bi, roots, light_f :
    the forest; eps : relative error threshold; max_cut : cut size limit; width, pk :
    the caster's packet width (lightcuts.accel.base.KernelCaster) and the packet
    (lightcuts.accel.packets.new_ray_packet); the remaining arguments: see
    :func:`light_mgv` and the module docstring (scratch); tol : absolute floor of the stop test
    (luminance; 0 for the 2005 test alone): a node whose bound is <= max(eps * total, tol) is not
    refined; skey : 0 keeps the tree's representatives, else the hash key of this shading point's
    stochastic representatives (:func:`stochastic_estimate`).
    Returns ``(L_r, L_g, L_b, cut_size, shadow_rays, clamp_lost)``: clamp_lost = the cut's estimate
    of the luminance that clamping removed here.

    The refinement loop reads the node record and the light row itself and calls functions of
    scalars for the rest (and the two heap helpers).
    """
    fr = receiver_frames(n0, n1, n2, r0, r1, r2)
    # int64 zeros, not literals: typing would also compile the heap helpers, _flush and
    # packet_set_ray for a Literal[int](0) argument, a specialisation nothing calls.
    n_slots = np.int64(0)
    size = np.int64(0)
    rays = np.int64(0)  # int64 from the start: a literal 0 would compile stochastic_estimate twice
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for t in range(roots.shape[0]):
        k = roots[t]
        m0, m1, m2, ratio, nr = light_mgv(np.int64(node_bi[k, NB_REP] & REP_MASK), light_f, x0, x1, x2, n0, n1, n2,
                                          r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, ray_offset,
                                          visibility, cdata, buf)
        rays += nr
        slot_node[n_slots] = k
        slot_mgv[n_slots, 0] = m0
        slot_mgv[n_slots, 1] = m1
        slot_mgv[n_slots, 2] = m2
        slot_ratio[n_slots] = ratio
        t0 += m0 * node_b[k, NB_I]
        t1 += m1 * node_b[k, NB_I + 1]
        t2 += m2 * node_b[k, NB_I + 2]
        b = node_bound(k, node_b, node_bi, x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                       exponent, clamp_d2)
        if b > 0.0:
            size = heap_push(heap, size, heap_entry(b, n_slots))
        n_slots += 1
    heap[size] = 0

    # Shadow rays wait in the packet (lane r belongs to slot lane_slot[r], -1 for a ray nobody
    # needs any more) while t counts them as visible. t is then the upper end of the true total,
    # so a top bound > eps * t must be refined whatever the rays return; only a top bound
    # <= eps * t needs their answers (docs/math.md, "Deferred visibility").
    lanes = np.int64(0)
    while size > 0 and n_slots < max_cut:
        if entry_bound(heap[0]) <= max(eps * luminance(t0, t1, t2), tol):
            if lanes == 0:
                break
            t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, slot_node, slot_mgv,
                                slot_ratio, node_b, t0, t1, t2)
            lanes = 0
            continue
        # The top s leaves the heap; its first child with a bound takes its place (one sift down
        # instead of a pop and a push).
        s = np.int64(heap[0] & SLOT_MASK)
        k = slot_node[s]
        prep = node_bi[k, NB_REP] & REP_MASK
        left = np.int64(node_bi[k, NB_LEFT])  # siblings are side by side (build_forest)
        jl = np.int64(node_bi[left, NB_REP] & REP_MASK)
        jr = np.int64(node_bi[left + 1, NB_REP] & REP_MASK)
        if lanes + (jl != prep) + (jr != prep) > width:
            # Cast before s's estimate leaves t: a waiting ray of s may change that estimate.
            t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, slot_node, slot_mgv,
                                slot_ratio, node_b, t0, t1, t2)
            lanes = 0
        # s's waiting ray, if any, follows s's representative: it stays with the left child (which
        # takes s's slot) or moves to the right child's new slot, or nobody needs it any more.
        if jl != prep:
            for r in range(lanes):
                if lane_slot[r] == s:
                    lane_slot[r] = n_slots if jr == prep else -1
        pm0, pm1, pm2, pratio = slot_mgv[s, 0], slot_mgv[s, 1], slot_mgv[s, 2], slot_ratio[s]
        t0 -= pm0 * node_b[k, NB_I]
        t1 -= pm1 * node_b[k, NB_I + 1]
        t2 -= pm2 * node_b[k, NB_I + 2]
        # Both children's bounds first: pure arithmetic, independent of each other, so the
        # processor overlaps them.
        bl = node_bound(left, node_b, node_bi, x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1, rs2,
                        exponent, clamp_d2)
        br = node_bound(left + 1, node_b, node_bi, x0, x1, x2, n0, n1, n2, r0, r1, r2, fr, rd0, rd1, rd2, rs0, rs1,
                        rs2, exponent, clamp_d2)
        # The heap first (it needs the bounds only), then the children's lights and shadow ray.
        size = replace_top(heap, size, bl, s, br, n_slots)
        for side in range(2):
            c = left + side
            # The left child takes the parent's slot, the right child a new one.
            cs = s if side == 0 else n_slots
            j = jl if side == 0 else jr
            if j == prep:
                m0, m1, m2, ratio = pm0, pm1, pm2, pratio
            else:
                c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
                m0, m1, m2, ratio, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
                    np.int64(light_f[j, LF_TYPE]), light_f[j, LF_POS], light_f[j, LF_POS + 1],
                    light_f[j, LF_POS + 2], light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2],
                    c2, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, ray_offset)
                # As light_mgv: one shadow ray counted per light with M G > 0.
                if lit and visibility:
                    rays += 1
                    if tfar > 0.0:
                        packet_set_ray(pk, width, lanes, o0, o1, o2, d0, d1, d2, 0.0, tfar)
                        lane_slot[lanes] = cs
                        lanes += 1
            slot_node[cs] = c
            slot_mgv[cs, 0] = m0
            slot_mgv[cs, 1] = m1
            slot_mgv[cs, 2] = m2
            slot_ratio[cs] = ratio
            t0 += m0 * node_b[c, NB_I]
            t1 += m1 * node_b[c, NB_I + 1]
            t2 += m2 * node_b[c, NB_I + 2]
        n_slots += 1
        if lanes == width:
            t0, t1, t2 = _flush(cdata, buf, width, pk, lanes, lane_slot, slot_node, slot_mgv,
                                slot_ratio, node_b, t0, t1, t2)
            lanes = 0
    if lanes > 0:
        _flush(cdata, buf, width, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio, node_b,
               t0, t1, t2)

    if skey != 0:
        return stochastic_estimate(node_b, node_bi, light_f, n_slots, slot_node, slot_mgv, slot_ratio, x0, x1, x2,
                                   n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2,
                                   ray_offset, visibility, cdata, buf, width, pk, lane_slot, skey, rays)
    # The final sum again, from the cut itself: the running total above drifts by cancellation.
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    for s in range(n_slots):
        k = slot_node[s]
        e0 = slot_mgv[s, 0] * node_b[k, NB_I]
        e1 = slot_mgv[s, 1] * node_b[k, NB_I + 1]
        e2 = slot_mgv[s, 2] * node_b[k, NB_I + 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (slot_ratio[s] - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, n_slots, rays, lost


@njit(cache=True, error_model="numpy", forceinline=True)
def _u01(key, slot, level):
    """A uniform float64 in [0, 1) that depends only on (key, slot, level)."""
    h = mix64(key ^ mix64(np.uint64(slot) * np.uint64(64) + np.uint64(level)))
    return np.float64(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, error_model="numpy")
def draw_light(k, node_b, node_bi, key, slot):
    """A leaf below node k drawn by a walk down its subtree, each step choosing a child with
    probability proportional to its intensity's luminance (Yuksel 2019, with intensity as the
    importance): ``(leaf, p)``, p the product of the steps' probabilities (= the leaf's share of
    the node's luminance). Random numbers from (key, slot, depth)."""
    p = 1.0
    c = k
    level = np.int64(0)  # int64, not a literal: _u01 compiles once
    while node_bi[c, NB_LEFT] >= 0:
        left = np.int64(node_bi[c, NB_LEFT])
        wl = luminance(np.float64(node_b[left, NB_I]), np.float64(node_b[left, NB_I + 1]),
                       np.float64(node_b[left, NB_I + 2]))
        wr = luminance(np.float64(node_b[left + 1, NB_I]), np.float64(node_b[left + 1, NB_I + 1]),
                       np.float64(node_b[left + 1, NB_I + 2]))
        total = wl + wr
        if total <= 0.0:
            return c, 0.0
        if _u01(key, slot, level) * total < wl:
            c = left
            p *= wl / total
        else:
            c = left + 1
            p *= wr / total
        level += 1
    return c, p


@njit(cache=True, nogil=True, error_model="numpy")  # kernel_api's flags
def _cast_draws(cdata, buf, width, pk, lanes, lane_slot, slot_mgv):
    """Cast the draws' waiting shadow rays (lanes 0..lanes-1 of pk) and zero the estimate of each
    slot whose ray is occluded."""
    packet_occluded(cdata, buf, pk, width, lanes)
    for r in range(lanes):
        if lane_occluded(pk, width, r):
            q = lane_slot[r]
            slot_mgv[q, 0] = 0.0
            slot_mgv[q, 1] = 0.0
            slot_mgv[q, 2] = 0.0


@njit(cache=True, error_model="numpy")
def stochastic_estimate(node_b, node_bi, light_f, n_slots, slot_node, slot_mgv, slot_ratio, x0, x1, x2, n0, n1, n2,
                        r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, ray_offset, visibility, cdata,
                        buf, width, pk, lane_slot, key, rays):
    """The cut's value with stochastic representatives (docs/math.md, "Converging images"):
    a leaf of the cut is exact (its ``slot_mgv``); an inner node C is estimated by one light j drawn
    by :func:`draw_light` with probability p_j, ``M_j G_j V_j I_j / p_j`` (one shadow ray, cast in
    packets; none when j is C's own representative, whose ``M G V`` the slot holds), which is
    unbiased for C's lights given the cut. The cut itself was chosen with the tree's
    representatives, independently of these draws. Overwrites ``slot_mgv`` with each slot's
    estimate. Returns as :func:`lightcut` (``rays`` the cut's shadow rays so far, to which the
    draws' are added)."""
    lanes = np.int64(0)
    for s in range(n_slots):
        k = slot_node[s]
        if node_bi[k, NB_LEFT] < 0:
            f, leaf = 1.0, k
        else:
            leaf, p = draw_light(k, node_b, node_bi, key, s)
            if p <= 0.0:
                slot_mgv[s, 0] = 0.0
                slot_mgv[s, 1] = 0.0
                slot_mgv[s, 2] = 0.0
                continue
            f = 1.0 / p
            j = np.int64(node_bi[leaf, NB_REP] & REP_MASK)
            if j != (node_bi[k, NB_REP] & REP_MASK):
                c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
                m0, m1, m2, ratio, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
                    np.int64(light_f[j, LF_TYPE]), light_f[j, LF_POS], light_f[j, LF_POS + 1],
                    light_f[j, LF_POS + 2], light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2],
                    c2, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, ray_offset)
                slot_mgv[s, 0] = m0
                slot_mgv[s, 1] = m1
                slot_mgv[s, 2] = m2
                slot_ratio[s] = ratio
                if lit and visibility:
                    rays += 1
                    if tfar > 0.0:
                        packet_set_ray(pk, width, lanes, o0, o1, o2, d0, d1, d2, 0.0, tfar)
                        lane_slot[lanes] = s
                        lanes += 1
                        if lanes == width:
                            _cast_draws(cdata, buf, width, pk, lanes, lane_slot, slot_mgv)
                            lanes = 0
        slot_mgv[s, 0] *= node_b[leaf, NB_I] * f
        slot_mgv[s, 1] *= node_b[leaf, NB_I + 1] * f
        slot_mgv[s, 2] *= node_b[leaf, NB_I + 2] * f
    if lanes > 0:
        _cast_draws(cdata, buf, width, pk, lanes, lane_slot, slot_mgv)
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    for s in range(n_slots):
        e0, e1, e2 = slot_mgv[s, 0], slot_mgv[s, 1], slot_mgv[s, 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (slot_ratio[s] - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, n_slots, rays, lost
