r"""The stochastic lightcut at one receiver (Yuksel, "Stochastic lightcuts", HPG 2019): numba device
functions over the light sampler's records (lightcuts.integrators.light_sampler).

The cut: from the roots of every light tree, the cut node of largest importance
(lightcuts.integrators.importance) is replaced by its children until the cut holds ``max_cut`` nodes
or only leaves; a node of importance 0 leaves the cut (no light below it can light the receiver).
One max-heap over all trees (lightcuts.integrators.heap) picks the node. The cut depends on the
receiver alone, not on random numbers. The estimate: below each cut node one light is drawn by the
importance walk (``sample_below``; a leaf is its own light, probability 1), and the light's ``M G V I``
(lightcuts.integrators.cut's shading of one light, its shadow ray in packets) divided by its
probability is the node's estimate; a light that is an emitting triangle is evaluated at a uniform
point of it (an oriented light of intensity ``Le * area`` there, whose point density is
``1 / area``). The sum over the cut is unbiased for the sum over all lights (docs/math.md,
"Stochastic lightcuts").

Scratch, one set per thread, reused across receivers; ``cap = max(max_cut, n_roots) + 2``: ``heap
(cap,) uint64`` (entries of inner cut nodes, a 0 sentinel after the last), ``slot_node (cap,)
int64`` (the node in each slot of the cut, -1 for a free slot), ``slot_est (cap, 3)`` (the slot's
RGB estimate), ``slot_ratio (cap,)`` (unclamped over clamped G of its light), ``free (cap,) int64``
(free slots), ``lane_slot (width,) int64`` and the shadow-ray packet.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.accel.packets import packet_set_ray
from lightcuts.integrators.bounds import ORIENTED
from lightcuts.integrators.cut import _cast_draws, _light_mg, _u01, luminance
from lightcuts.integrators.forest import LF_INDIRECT, LF_NRM, LF_POS, LF_TYPE
from lightcuts.integrators.heap import SLOT_MASK, heap_entry, heap_push, sift_down
from lightcuts.integrators.importance import importance, node_type, sample_below

# Columns of an emitting triangle's row (tri_geo, (T, 9) float64): a corner, the two edges from it.
TG_P0, TG_E1, TG_E2, TG_WIDTH = 0, 3, 6, 9
# The random numbers of a cut slot (lightcuts.integrators.cut._u01's level): the walk, the point on a
# triangle. int64 like draw_light's levels, not literal ints, so that _u01 compiles once.
_U_WALK, _U_TRI1, _U_TRI2 = np.int64(0), np.int64(1), np.int64(2)


@njit(cache=True, error_model="numpy")
def importance_cut(x0, x1, x2, n0, n1, n2, rec, axis, child, roots, root_type, max_cut, heap, slot_node, free):
    """The cut at the receiver x (unit normal n): fills ``slot_node`` (module docstring) and returns
    ``(n_slots, size)``, the slots used (some may be free, -1) and the cut's node count."""
    n_slots = np.int64(0)
    n_free = np.int64(0)
    size = np.int64(0)
    hsize = np.int64(0)
    for t in range(roots.shape[0]):
        k = roots[t]
        w = importance(rec, axis, k, root_type[t], x0, x1, x2, n0, n1, n2)
        if w > 0.0:
            slot_node[n_slots] = k
            if child[k] >= 0:
                hsize = heap_push(heap, hsize, heap_entry(w, n_slots))
            n_slots += 1
            size += 1
    heap[hsize] = 0
    while hsize > 0 and size < max_cut:
        s = np.int64(heap[0] & SLOT_MASK)
        hsize -= 1
        last = heap[hsize]
        heap[hsize] = 0
        if hsize > 0:
            sift_down(heap, hsize, last)
        k = slot_node[s]
        typ = node_type(roots, root_type, k)
        left = np.int64(child[k])
        size -= 1
        target = s  # the first child with an importance takes the parent's slot
        for c in range(left, left + 2):
            w = importance(rec, axis, c, typ, x0, x1, x2, n0, n1, n2)
            if not w > 0.0:
                continue
            if target >= 0:
                q = target
                target = -1
            elif n_free > 0:
                n_free -= 1
                q = free[n_free]
            else:
                q = n_slots
                n_slots += 1
            slot_node[q] = c
            size += 1
            if child[c] >= 0:
                hsize = heap_push(heap, hsize, heap_entry(w, q))
                heap[hsize] = 0
        if target >= 0:  # neither child can light x
            slot_node[s] = -1
            free[n_free] = s
            n_free += 1
    return n_slots, size


@njit(cache=True, error_model="numpy")
def stochastic_lightcut(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                        rec, axis, child, roots, root_type, light_f, light_i, light_tri, tri_geo, max_cut, clamp_d2,
                        ray_offset, visibility, cdata, buf, width, pk, heap, slot_node, slot_est, slot_ratio, free,
                        lane_slot, key):
    """Radiance reflected at x towards the viewer, by a stochastic lightcut (module docstring).

    x, n, r, rd, rs, exponent : the receiver as in lightcuts.integrators.cut.light_mgv; rec, axis,
    child, roots, root_type : the light sampler's records; light_f, light_i : the forest's light rows
    and RGB intensities (lightcuts.integrators.forest), in the sampler's global light order;
    light_tri (L,) int64 : the row of tri_geo of a light that is an emitting triangle, -1 for a
    point light; max_cut : the cut's size at most; clamp_d2, ray_offset, visibility, cdata, buf,
    width, pk : as lightcuts.integrators.cut.lightcut; key : the eye ray's hash key (the slot's
    random numbers are lightcuts.integrators.cut._u01 of it).
    Returns ``(L_r, L_g, L_b, cut_size, shadow_rays, clamp_lost)`` as lightcuts.integrators.cut.lightcut
    (clamp_lost: the estimate of the luminance that clamping removed here).
    """
    n_slots, size = importance_cut(x0, x1, x2, n0, n1, n2, rec, axis, child, roots, root_type, max_cut, heap,
                                   slot_node, free)
    rays = 0
    lanes = np.int64(0)
    for s in range(n_slots):
        slot_est[s, 0] = 0.0
        slot_est[s, 1] = 0.0
        slot_est[s, 2] = 0.0
        slot_ratio[s] = 1.0
        k = slot_node[s]
        if k < 0:
            continue
        if child[k] < 0:
            j, prob = -(np.int64(child[k]) + 1), 1.0
        else:
            j, prob = sample_below(rec, axis, child, k, node_type(roots, root_type, k), x0, x1, x2, n0, n1, n2,
                                   _u01(key, s, _U_WALK))
            if j < 0:
                continue
        typ = np.int64(light_f[j, LF_TYPE])
        p0, p1, p2 = light_f[j, LF_POS], light_f[j, LF_POS + 1], light_f[j, LF_POS + 2]
        q = light_tri[j]
        if q >= 0:  # a uniform point of the triangle
            u1, u2 = _u01(key, s, _U_TRI1), _u01(key, s, _U_TRI2)
            if u1 + u2 > 1.0:
                u1, u2 = 1.0 - u1, 1.0 - u2
            p0 = tri_geo[q, TG_P0] + u1 * tri_geo[q, TG_E1] + u2 * tri_geo[q, TG_E2]
            p1 = tri_geo[q, TG_P0 + 1] + u1 * tri_geo[q, TG_E1 + 1] + u2 * tri_geo[q, TG_E2 + 1]
            p2 = tri_geo[q, TG_P0 + 2] + u1 * tri_geo[q, TG_E1 + 2] + u2 * tri_geo[q, TG_E2 + 2]
            typ = ORIENTED
        c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
        m0, m1, m2, ratio, lit, o0, o1, o2, d0, d1, d2, tfar = _light_mg(
            typ, p0, p1, p2, light_f[j, LF_NRM], light_f[j, LF_NRM + 1], light_f[j, LF_NRM + 2], c2, x0, x1, x2,
            n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, ray_offset)
        if not lit:
            continue
        f = 1.0 / prob
        slot_est[s, 0] = m0 * light_i[j, 0] * f
        slot_est[s, 1] = m1 * light_i[j, 1] * f
        slot_est[s, 2] = m2 * light_i[j, 2] * f
        slot_ratio[s] = ratio
        # As lightcuts.integrators.cut.light_mgv: one shadow ray counted per light with M G > 0.
        if visibility:
            rays += 1
            if tfar > 0.0:
                packet_set_ray(pk, width, lanes, o0, o1, o2, d0, d1, d2, 0.0, tfar)
                lane_slot[lanes] = s
                lanes += 1
                if lanes == width:
                    _cast_draws(cdata, buf, width, pk, lanes, lane_slot, slot_est)
                    lanes = 0
    if lanes > 0:
        _cast_draws(cdata, buf, width, pk, lanes, lane_slot, slot_est)
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    for s in range(n_slots):
        e0, e1, e2 = slot_est[s, 0], slot_est[s, 1], slot_est[s, 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (slot_ratio[s] - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, size, rays, lost
