r"""The lightcut at one receiver (Walter et al. 2005, section 4): the forest and numba device functions.

The light trees of all types are flattened into one *forest* (:func:`build_forest`): packed node
and light rows with global ids, and one root per tree. A cut is a set of nodes that covers every
light exactly once; its estimate is the sum of the cluster estimates

    L_C = M_j * G_j * V_j * I_C      (per RGB channel; j = the representative of C)

and each node's error bound is ``I_C * M_ub * G_ub`` (lightcuts.render.bounds; 0 for a leaf, whose
estimate is exact). Starting from the roots, the node with the largest bound (in luminance) is
replaced by its children until that bound is <= ``eps`` times the luminance of the cut's total
estimate, or the cut holds ``max_cut`` nodes. One max-heap over the nodes of all trees decides.

A child whose representative is its parent's reuses the parent's ``M G V`` (no new shadow ray):
only the other child's representative needs a shadow ray. Nodes with a zero bound (a leaf, or a
cluster entirely behind the surface) never enter the heap.

Memory layout: a node is read as a whole (box, cone, intensity, children), so nodes are packed rows
(two arrays, 160 bytes a node) rather than one array per field, and numbered level by level with
siblings side by side (both children are always read together; the top levels, which every
receiver reads, share cache lines). With 10^5 lights this more than halved the render time here.

Scratch (one set per thread, reused across receivers), ``cap = max(max_cut, n_roots) + 1``:
``heap_key (cap,) float64``, ``heap_slot (cap,) int64``, ``slot_node (cap,) int64``,
``slot_mgv (cap, 3) float64`` (the representative's ``M G V`` per RGB channel) and
``slot_ratio (cap,) float64`` (unclamped over clamped G of the representative, 1 if not clamped).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.accel.embree_kernels import ray_occluded
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LIGHT_TYPES, LUMINANCE, LightSet
from lightcuts.render.bounds import DIRECTIONAL, OMNI, ORIENTED, cluster_error_bound
from lightcuts.render.shading import light_geometry, material_term
from lightcuts.trees.tree import LightTree

LUM_R, LUM_G, LUM_B = (float(v) for v in LUMINANCE)
TYPE_CODES = {"omni": OMNI, "oriented": ORIENTED, "directional": DIRECTIONAL}

# Columns of a node's float row (node_f, (K, 16) float64).
NF_LO, NF_HI, NF_AXIS, NF_COS, NF_I, NF_TYPE, NF_WIDTH = 0, 3, 6, 9, 10, 13, 16
# Columns of a node's integer row (node_k, (K, 4) int64): children (-1 at a leaf), representative
# (global light id), 1 if every light below is an indirect VPL (the clamped bound applies).
NK_LEFT, NK_RIGHT, NK_REP, NK_ALL_INDIRECT, NK_WIDTH = 0, 1, 2, 3, 4
# Columns of a light's row (light_f, (L, 8) float64): position (directional: unit direction towards
# the light), normal, type code, 1.0 for an indirect VPL.
LF_POS, LF_NRM, LF_TYPE, LF_INDIRECT, LF_WIDTH = 0, 3, 6, 7, 8


@dataclass
class Forest:
    """All lights and trees of a render, flattened for the kernels.

    light_f : (L, 8) float64 light rows (``LF_*`` columns), types in the order of LIGHT_TYPES
    light_i : (L, 3) float64 RGB intensities
    node_f : (K, 16) float64 node rows (``NF_*``): box lo, hi; cone axis, cos; summed RGB intensity; type
    node_k : (K, 4) int64 node rows (``NK_*``): left, right, representative, all-indirect flag
    roots : (T,) int64, one per tree (none without trees: the reference)
    n_lights : {type: count}
    """

    light_f: np.ndarray
    light_i: np.ndarray
    node_f: np.ndarray
    node_k: np.ndarray
    roots: np.ndarray
    n_lights: dict


def _level_order(tree: LightTree) -> list[np.ndarray]:
    """Node ids level by level from the root, siblings side by side (left, right, left, right, ...)."""
    levels = []
    level = np.array([tree.root], np.int64)
    while level.size:
        levels.append(level)
        inner = level[tree.left[level] >= 0]
        level = np.stack([tree.left[inner], tree.right[inner]], axis=1).ravel().astype(np.int64)
    return levels


def _check_tree(typ: str, tree: LightTree, n: int) -> None:
    k = 2 * n - 1
    for key in ("left", "right", "light", "rep", "cone_cos"):
        if getattr(tree, key).shape != (k,):
            raise LightcutsError(f"trees.{typ}: {key} has shape {getattr(tree, key).shape}, expected ({k},) "
                                 f"for {n} lights")
    for key in ("bbox_min", "bbox_max", "cone_axis", "intensity"):
        a = getattr(tree, key)
        if a.shape != (k, 3) or not np.all(np.isfinite(a)):
            raise LightcutsError(f"trees.{typ}: {key} must be finite with shape ({k}, 3)")
    if not 0 <= tree.root < k:
        raise LightcutsError(f"trees.{typ}: root {tree.root} is not a node id in [0, {k})")
    if np.any((tree.rep < 0) | (tree.rep >= n)) or np.any(tree.light >= n):
        raise LightcutsError(f"trees.{typ}: light or representative ids outside [0, {n})")
    if np.any(tree.left >= k) or np.any(tree.right >= k) or np.any((tree.left < 0) != (tree.right < 0)):
        raise LightcutsError(f"trees.{typ}: child ids are not valid node ids")
    if sum(len(level) for level in _level_order(tree)) != k:
        raise LightcutsError(f"trees.{typ}: {k} nodes expected below the root for {n} lights")


def _check_lights(typ: str, ls) -> None:
    if typ not in LIGHT_TYPES:
        raise LightcutsError(f"lights: unknown light type key {typ!r}; valid: {', '.join(LIGHT_TYPES)}")
    if not isinstance(ls, LightSet) or ls.type != typ:
        raise LightcutsError(f"lights.{typ}: expected a LightSet of type {typ!r}")
    for key in ("position", "normal", "intensity"):
        if not np.all(np.isfinite(getattr(ls, key))):
            raise LightcutsError(f"lights.{typ}: {key} has non-finite values")
    if np.any(ls.intensity < 0):
        raise LightcutsError(f"lights.{typ}: intensity has negative values")


def build_forest(lights: dict, trees: dict | None) -> Forest:
    """Flatten light sets (and, for lightcuts, their trees) by type; LightcutsError on a mismatch.

    lights : {type: LightSet}; trees : {type: LightTree} with a tree for every non-empty set, or None
    (the reference needs no trees). Empty light sets are skipped.
    """
    for typ, ls in lights.items():
        _check_lights(typ, ls)
    sets = [(typ, lights[typ]) for typ in LIGHT_TYPES if typ in lights and len(lights[typ])]
    n_lights = {typ: len(ls) for typ, ls in sets}
    n = sum(n_lights.values())
    light_f = np.zeros((n, LF_WIDTH))
    light_i = np.zeros((n, 3))
    base = 0
    for typ, ls in sets:
        rows = slice(base, base + len(ls))
        light_f[rows, LF_POS:LF_POS + 3] = ls.position
        light_f[rows, LF_NRM:LF_NRM + 3] = ls.normal
        light_f[rows, LF_TYPE] = TYPE_CODES[typ]
        light_f[rows, LF_INDIRECT] = ls.indirect
        light_i[rows] = ls.intensity
        base += len(ls)

    node_f = []
    node_k = []
    roots = []
    if trees is not None:
        light_base = 0
        node_base = 0
        for typ, ls in sets:
            tree = trees.get(typ)
            if tree is None:
                raise LightcutsError(f"trees: no tree for the {len(ls)} {typ} lights")
            _check_tree(typ, tree, len(ls))
            levels = _level_order(tree)
            order = np.concatenate(levels)           # new id -> old id
            new_id = np.empty(len(order), np.int64)   # old id -> new id
            new_id[order] = np.arange(len(order))
            f = np.zeros((len(order), NF_WIDTH))
            f[:, NF_LO:NF_LO + 3] = tree.bbox_min[order]
            f[:, NF_HI:NF_HI + 3] = tree.bbox_max[order]
            f[:, NF_AXIS:NF_AXIS + 3] = tree.cone_axis[order]
            f[:, NF_COS] = tree.cone_cos[order]
            f[:, NF_I:NF_I + 3] = tree.intensity[order]
            f[:, NF_TYPE] = TYPE_CODES[typ]
            k = np.full((len(order), NK_WIDTH), -1, np.int64)
            inner = tree.left[order] >= 0
            k[inner, NK_LEFT] = new_id[tree.left[order][inner]] + node_base
            k[inner, NK_RIGHT] = new_id[tree.right[order][inner]] + node_base
            k[:, NK_REP] = tree.rep[order].astype(np.int64) + light_base
            # Bottom-up over the levels: a cluster is all-indirect if both children are.
            flag = np.zeros(len(order), bool)
            flag[~inner] = ls.indirect[tree.light[order][~inner]]
            for level in reversed(levels):
                ids = new_id[level]
                ids = ids[inner[ids]]
                flag[ids] = flag[k[ids, NK_LEFT] - node_base] & flag[k[ids, NK_RIGHT] - node_base]
            k[:, NK_ALL_INDIRECT] = flag
            node_f.append(f)
            node_k.append(k)
            roots.append(node_base)  # the root is first in level order
            light_base += len(ls)
            node_base += len(order)
    return Forest(light_f=light_f, light_i=light_i,
                  node_f=np.ascontiguousarray(np.concatenate(node_f)) if node_f else np.zeros((0, NF_WIDTH)),
                  node_k=np.ascontiguousarray(np.concatenate(node_k)) if node_k else np.zeros((0, NK_WIDTH), np.int64),
                  roots=np.array(roots, np.int64), n_lights=n_lights)


@njit(cache=True, error_model="numpy")
def luminance(r, g, b):
    """Rec. 709 luminance of an RGB triple (inf stays inf)."""
    return LUM_R * r + LUM_G * g + LUM_B * b


@njit(cache=True, error_model="numpy")
def light_mgv(j, light_f, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
              clamp_d2, ray_offset, visibility, occluded1, scene, buf):
    """``M G V`` per RGB channel of light j at the receiver x, with one shadow ray when M G > 0.

    light_f : the forest's light rows; x : receiver; n : unit shading normal (facing the viewer);
    r : mirror direction of wo; rd, rs, exponent : the receiver's material; clamp_d2 : squared
    clamping distance for indirect lights (0: off); ray_offset : shadow-ray origin offset along n and
    the gap left before the light, world units; visibility : False skips the shadow ray (V = 1:
    unshadowed shading, and timing without rays); occluded1, scene, buf : Embree handles and scratch.
    Returns ``(mgv_r, mgv_g, mgv_b, ratio, rays)``: ratio = unclamped / clamped G (>= 1),
    rays = shadow rays cast (0 or 1).
    """
    typ = np.int64(light_f[j, LF_TYPE])
    c2 = clamp_d2 if light_f[j, LF_INDIRECT] > 0.0 else 0.0
    p0, p1, p2 = light_f[j, LF_POS], light_f[j, LF_POS + 1], light_f[j, LF_POS + 2]
    w0, w1, w2, _, g, g_unclamped = light_geometry(typ, p0, p1, p2, light_f[j, LF_NRM], light_f[j, LF_NRM + 1],
                                                   light_f[j, LF_NRM + 2], x0, x1, x2, c2)
    if g <= 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0
    m0, m1, m2 = material_term(n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, w0, w1, w2)
    if m0 <= 0.0 and m1 <= 0.0 and m2 <= 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0
    if not visibility:
        return m0 * g, m1 * g, m2 * g, g_unclamped / g, 0
    # The light is on the normal's side (M > 0), so the origin moves off the surface towards it.
    o0, o1, o2 = x0 + ray_offset * n0, x1 + ray_offset * n1, x2 + ray_offset * n2
    if typ == DIRECTIONAL:
        blocked = ray_occluded(occluded1, scene, buf, o0, o1, o2, w0, w1, w2, 0.0, np.inf)
    else:
        # Lights sit on surfaces: stop short of the light so its own surface does not shadow it.
        d0, d1, d2 = p0 - o0, p1 - o1, p2 - o2
        dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        tfar = dist - ray_offset
        blocked = tfar > 0.0 and ray_occluded(occluded1, scene, buf, o0, o1, o2, d0 / dist, d1 / dist,
                                               d2 / dist, 0.0, tfar)
    if blocked:
        return 0.0, 0.0, 0.0, 1.0, 1
    return m0 * g, m1 * g, m2 * g, g_unclamped / g, 1


@njit(cache=True, error_model="numpy")
def node_bound(k, node_f, node_k, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
               clamp_d2):
    """Error bound of node k in luminance; 0 for a leaf (its estimate is exact)."""
    if node_k[k, NK_LEFT] < 0:
        return 0.0
    c2 = clamp_d2 if node_k[k, NK_ALL_INDIRECT] > 0 else 0.0
    f = node_f
    b0, b1, b2 = cluster_error_bound(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
                                     np.int64(f[k, NF_TYPE]), f[k, NF_LO], f[k, NF_LO + 1], f[k, NF_LO + 2],
                                     f[k, NF_HI], f[k, NF_HI + 1], f[k, NF_HI + 2],
                                     f[k, NF_AXIS], f[k, NF_AXIS + 1], f[k, NF_AXIS + 2], f[k, NF_COS],
                                     f[k, NF_I], f[k, NF_I + 1], f[k, NF_I + 2], c2)
    return luminance(b0, b1, b2)


@njit(cache=True, error_model="numpy")
def _heap_push(heap_key, heap_slot, size, key, slot):
    """Insert (key, slot) into the max-heap of ``size`` entries; returns the new size."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if heap_key[parent] >= key:
            break
        heap_key[i] = heap_key[parent]
        heap_slot[i] = heap_slot[parent]
        i = parent
    heap_key[i] = key
    heap_slot[i] = slot
    return size + 1


@njit(cache=True, error_model="numpy")
def _heap_pop(heap_key, heap_slot, size):
    """Remove the top of the max-heap; returns (slot, new size)."""
    top = heap_slot[0]
    size -= 1
    key = heap_key[size]
    slot = heap_slot[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and heap_key[child + 1] > heap_key[child]:
            child += 1
        if heap_key[child] <= key:
            break
        heap_key[i] = heap_key[child]
        heap_slot[i] = heap_slot[child]
        i = child
    if size > 0:
        heap_key[i] = key
        heap_slot[i] = slot
    return top, size


@njit(cache=True, error_model="numpy")
def lightcut(x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent,
             node_f, node_k, roots, light_f, eps, max_cut, clamp_d2, ray_offset, visibility, occluded1, scene, buf,
             heap_key, heap_slot, slot_node, slot_mgv, slot_ratio):
    """Radiance reflected at x towards the viewer, by a lightcut through every tree of the forest.

    x, n, r, rd, rs, exponent : receiver as in :func:`light_mgv`; node_f, node_k, roots, light_f :
    the forest; eps : relative error threshold; max_cut : cut size limit; the remaining arguments:
    see :func:`light_mgv` and the module docstring (scratch).
    Returns ``(L_r, L_g, L_b, cut_size, shadow_rays, clamp_lost)``: clamp_lost = the cut's estimate
    of the luminance that clamping removed here.
    """
    n_slots = 0
    size = 0
    rays = 0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for t in range(roots.shape[0]):
        k = roots[t]
        m0, m1, m2, ratio, nr = light_mgv(node_k[k, NK_REP], light_f, x0, x1, x2, n0, n1, n2, r0, r1, r2,
                                          rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, ray_offset, visibility,
                                          occluded1, scene, buf)
        rays += nr
        slot_node[n_slots] = k
        slot_mgv[n_slots, 0] = m0
        slot_mgv[n_slots, 1] = m1
        slot_mgv[n_slots, 2] = m2
        slot_ratio[n_slots] = ratio
        t0 += m0 * node_f[k, NF_I]
        t1 += m1 * node_f[k, NF_I + 1]
        t2 += m2 * node_f[k, NF_I + 2]
        b = node_bound(k, node_f, node_k, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2,
                       exponent, clamp_d2)
        if b > 0.0:
            size = _heap_push(heap_key, heap_slot, size, b, n_slots)
        n_slots += 1

    while size > 0 and n_slots < max_cut:
        if heap_key[0] <= eps * luminance(t0, t1, t2):
            break
        s, size = _heap_pop(heap_key, heap_slot, size)
        k = slot_node[s]
        pm0, pm1, pm2, pratio = slot_mgv[s, 0], slot_mgv[s, 1], slot_mgv[s, 2], slot_ratio[s]
        t0 -= pm0 * node_f[k, NF_I]
        t1 -= pm1 * node_f[k, NF_I + 1]
        t2 -= pm2 * node_f[k, NF_I + 2]
        for side in range(2):
            c = node_k[k, NK_LEFT + side]
            # The left child takes the parent's slot, the right child a new one.
            cs = s if side == 0 else n_slots
            if node_k[c, NK_REP] == node_k[k, NK_REP]:
                m0, m1, m2, ratio = pm0, pm1, pm2, pratio
            else:
                m0, m1, m2, ratio, nr = light_mgv(node_k[c, NK_REP], light_f, x0, x1, x2, n0, n1, n2, r0, r1, r2,
                                                  rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, ray_offset,
                                                  visibility, occluded1, scene, buf)
                rays += nr
            slot_node[cs] = c
            slot_mgv[cs, 0] = m0
            slot_mgv[cs, 1] = m1
            slot_mgv[cs, 2] = m2
            slot_ratio[cs] = ratio
            t0 += m0 * node_f[c, NF_I]
            t1 += m1 * node_f[c, NF_I + 1]
            t2 += m2 * node_f[c, NF_I + 2]
            b = node_bound(c, node_f, node_k, x0, x1, x2, n0, n1, n2, r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2,
                           exponent, clamp_d2)
            if b > 0.0:
                size = _heap_push(heap_key, heap_slot, size, b, cs)
        n_slots += 1

    # The final sum again, from the cut itself: the running total above drifts by cancellation.
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    lost = 0.0
    for s in range(n_slots):
        k = slot_node[s]
        e0 = slot_mgv[s, 0] * node_f[k, NF_I]
        e1 = slot_mgv[s, 1] * node_f[k, NF_I + 1]
        e2 = slot_mgv[s, 2] * node_f[k, NF_I + 2]
        t0 += e0
        t1 += e1
        t2 += e2
        lost += (slot_ratio[s] - 1.0) * luminance(e0, e1, e2)
    return t0, t1, t2, n_slots, rays, lost
