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

Memory layout: a node is read as a whole (box, cone, intensity, children), so the kernel reads one
packed float32 record of 64 bytes (one cache line, :func:`pack_nodes`) rather than one array per
field, and nodes are numbered level by level with siblings side by side (both children are always
read together; the top levels, which every receiver reads, share cache lines). The float64 rows
(node_f, node_k) stay in the forest as the exact description of the trees.

Time per refined node (Cornell box, 10^5 lights, eps 0.02, mean cut 211): about 420 ns at the
start of this layout, with Embree's own code a small share; the bounds, the light's ``M G`` and
the heap were called functions (LLVM declined to inline calls with 15-40 scalar arguments), and a
profile showed the time in divisions and square roots waiting on each other. Now: every device
function of the loop is ``forceinline`` (LLVM ``alwaysinline``; about 20% alone), the bound is a
ratio with one division (lightcuts.render.bounds, "Evaluation"), without unpredictable branches,
and the loop computes both children's bounds first, so that the two bounds and the light row's
load can overlap. Measured
(benchmarks/bench_render.py, 512 x 512, two threads, on cores shared with other work, back to
back): CPU time of the full render 35.0 s -> 23.5-24.6 s, wall 18.6 s -> 12.5-12.8 s. By the
benchmark's split (full minus no-visibility) shadow rays are now about 40% of the CPU time; in a
perf profile Embree's own code is about 20-25% and the lightcut function (bounds, heap, M G, ray
setup) about 70%. Images are unchanged: the bounds differ from the former arithmetic by rounding
only, and on the benchmark's image the cut, the shadow rays and every pixel came out the same.

The refined node's first child with a bound replaces it at the top of the heap (one sift instead
of a pop and a push), the receiver's frames about N and R are computed once (lightcuts.render.
bounds.receiver_frames), and the loop reads node records and light rows itself. Node records
and light rows start on a cache line (:func:`cache_aligned_zeros`; numpy aligns to 16 bytes, so
every 64-byte record used to straddle two lines). Tried without a measurable gain (timings on
the shared cores vary by 15%): prefetching the children's records of a node entering the heap
(``llvm.prefetch``). Evaluating bounds lazily (children keyed by the parent's bound until they
reach the top) computed fewer bounds but was about 17% slower: the extra heap work costs more
than the bounds it saves.

The heap is updated right after the two bounds, before the representative's shadow ray (its
order depends on the bounds only), and indexes with unsigned integers: numba tests every signed
index for a negative value to wrap around, three instructions on the sift's chain of dependent
loads at every level. Together about 4% less CPU time for the whole image (one thread, the two
versions alternating band by band on one core, twice; alone: about 1% and nothing). Images are
unchanged (the same operations in the same order). A heap entry is one uint64, the bound's bits and
its slot (:func:`_heap_entry`), rather than a float64 key beside an int64 slot: one load and one
store a level instead of two each, and integer compares on the sift's chain; 3.8% less time
(same-process A/B, twice over 10 and 14 pairs), images the same on the benchmark's crop. Tried on
top of that without a gain (same method, noise about 2%): computing the next top's children's bounds
one refinement ahead, before the shadow ray, for the processor to overlap with Embree's traversal
(5% slower); a 4-ary heap (1%, within the noise); choosing the child that needs a new light by
selects instead of a branch per side (1-2% slower); unsigned node ids in :func:`node_bound`, a
select instead of its leaf branch, and ``llvm.prefetch`` of both children's light rows before the
bounds (a profile shows that row's load waiting on memory; no change either way). Two receivers'
cuts interleaved step by step in one loop (each with its own heap, slots and packet), for the
processor to overlap their chains of dependent latencies: images identical, 5% slower (same-process
A/B, B/A 0.953 over 10 pairs).

Deferred visibility: shadow rays are cast 8 at a time (``rtcOccluded8``; 4 where the processor
has no native 8-wide packets) rather than one by one. The order of refinement depends on the
bounds only; the stop test needs the total estimate t. A waiting ray counts as visible, so the
running t is an upper end of the true total, and a top bound > eps * t must be refined whatever
the rays return: the rays are cast when the packet is full or when the top bound is <= eps * t
(then the test is taken again on the true total). A waiting ray belongs to a slot (``lane_slot``)
and follows its representative when the slot is refined. The cut, its shadow rays and the image
came out the same as casting each ray at once, bit for bit (the stop test's total may differ in
rounding only, and the final sum is recomputed from the cut). Measured on the Cornell box with a
glossy floor, 21,000 lights, 128 x 128, one thread: 7.7 rays a packet on average, and by cycle
counts 215 cycles a shadow ray instead of 376. The whole render: 4% less time on one thread (10^5
lights, a 128 x 128 crop, the two versions in one process alternating 12 times: 1.40 s against
1.46 s). The roots' rays (one per tree) are still cast singly.

Scratch (one set per thread, reused across receivers), ``cap = max(max_cut, n_roots) + 2``
(the heap keeps a sentinel 0 after its last entry):
``heap (cap,) uint64`` (:func:`_heap_entry`: a bound and its slot in one integer), ``slot_node (cap,) int64``,
``slot_mgv (cap, 3) float64`` (the representative's ``M G V`` per RGB channel) and
``slot_ratio (cap,) float64`` (unclamped over clamped G of the representative, 1 if not clamped),
``lane_slot (width,) int64`` (the slot of each waiting shadow ray) and the packet itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from lightcuts.accel.embree_kernels import lane_occluded, packet_occluded, packet_set_ray, ray_occluded
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LIGHT_TYPES, LUMINANCE, LightSet
from lightcuts.parallel import on_threads
from lightcuts.render import SLOT_BITS
from lightcuts.rounding import down32, up32
from lightcuts.render.bounds import (DIRECTIONAL, OMNI, ORIENTED, cluster_error_bound_framed, frame_coefficient,
                                     receiver_frames)
from lightcuts.render.shading import light_geometry, material_term
from lightcuts.trees.tree import LightTree

LUM_R, LUM_G, LUM_B = (float(v) for v in LUMINANCE)
TYPE_CODES = {"omni": OMNI, "oriented": ORIENTED, "directional": DIRECTIONAL}

# Columns of a node's float row (node_f, (K, 16) float64).
NF_LO, NF_HI, NF_AXIS, NF_COS, NF_I, NF_TYPE, NF_WIDTH = 0, 3, 6, 9, 10, 13, 16
# Columns of a node's integer row (node_k, (K, 4) int64): children (-1 at a leaf), representative
# (global light id), 1 if every light below is an indirect VPL (the clamped bound applies).
NK_LEFT, NK_RIGHT, NK_REP, NK_ALL_INDIRECT, NK_WIDTH = 0, 1, 2, 3, 4
# Columns of a node's kernel record (node_b, (K, 16) float32, one 64-byte cache line; node_bi is the
# same memory viewed as int32 for the integer columns): box lo (rounded down), hi (rounded up); cone
# axis, cos (widened); summed RGB intensity; left child (-1 at a leaf; the right child is left + 1),
# representative and flags (global light id + (2 * type code + all-indirect) << REP_BITS), the cone
# axis's frame coefficient (lightcuts.render.bounds.frame_coefficient of the float32 axis).
NB_LO, NB_HI, NB_AXIS, NB_COS, NB_I, NB_LEFT, NB_REP, NB_FA, NB_WIDTH = 0, 3, 6, 9, 10, 13, 14, 15, 16
#: Bits of a record's NB_REP column that hold the representative; the flags sit above them.
REP_BITS = 28
_REP_MASK = (1 << REP_BITS) - 1
# Below this many rows build_forest's kernels run on one thread (thread start-up would cost more).
_PARALLEL_MIN = 20000
#: Extra half-angle (radians) given to a node's cone in node_b: covers the float32 rounding of its axis.
CONE_WIDEN = 1e-6
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
    node_b : (K, 16) float32, what the kernel reads of node_f and node_k (``NB_*``), one cache line
        a node; node_bi : the same memory viewed as (K, 16) int32 (:func:`pack_nodes`)
    """

    light_f: np.ndarray
    light_i: np.ndarray
    node_f: np.ndarray
    node_k: np.ndarray
    roots: np.ndarray
    n_lights: dict
    node_b: np.ndarray
    node_bi: np.ndarray


def cache_aligned_zeros(shape: tuple[int, int], dtype) -> np.ndarray:
    """Zeros whose first row starts on a 64-byte cache line: with 64-byte rows, a row is one line
    (numpy's own allocations are only 16-byte aligned, so every row would straddle two lines)."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.zeros(n + 64, np.uint8)
    start = -raw.ctypes.data % 64
    return raw[start:start + n].view(dtype).reshape(shape)


def pack_nodes(node_f: np.ndarray, node_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's node records ``(node_b, node_bi)`` (``NB_*`` columns) from the float64 rows.

    A cut reads nodes in an order no layout can predict, and with 10^5 lights the tree is larger
    than the L2 cache: one 64-byte line a node (float32) instead of the rows' 160 bytes in two
    arrays. The bounds stay bounds: boxes are rounded outwards and cones widened by CONE_WIDEN
    (float32 rounding moves an axis by about 1e-7 rad, and the float32 frame coefficient tilts the
    cone's frame by about as much). The summed
    intensity is rounded to the nearest float32 (relative 6e-8), in the estimate and bound alike.
    """
    k = node_f.shape[0]
    if k >= 2 ** 31 - 1:
        raise LightcutsError(f"trees: {k} nodes exceed the kernel's int32 node ids")
    if k and node_k[:, NK_REP].max() > _REP_MASK:
        raise LightcutsError(f"trees: more than 2^{REP_BITS} lights do not fit the kernel's node records")
    node_b = cache_aligned_zeros((k, NB_WIDTH), np.float32)
    node_bi = node_b.view(np.int32)
    on_threads(_pack, k, _PARALLEL_MIN, np.ascontiguousarray(node_f, np.float64),
               np.ascontiguousarray(node_k, np.int64), node_b, node_bi)
    return node_b, node_bi


@njit(cache=True, nogil=True)
def _pack(node_f, node_k, node_b, node_bi, s, e):
    """:func:`pack_nodes`' loop over rows s..e-1: node_b and node_bi are two views of the same (K, 16)
    records."""
    for k in range(s, e):
        for t in range(3):
            node_b[k, NB_LO + t] = down32(node_f[k, NF_LO + t])
            node_b[k, NB_HI + t] = up32(node_f[k, NF_HI + t])
            node_b[k, NB_AXIS + t] = np.float32(node_f[k, NF_AXIS + t])
            node_b[k, NB_I + t] = np.float32(node_f[k, NF_I + t])
        c = node_f[k, NF_COS]
        beta = np.arccos(min(1.0, max(-1.0, c))) + CONE_WIDEN
        if c <= -1.0 or beta >= np.pi:
            node_b[k, NB_COS] = np.float32(-1.0)
        else:
            node_b[k, NB_COS] = down32(np.cos(beta))
        node_bi[k, NB_LEFT] = node_k[k, NK_LEFT]
        flags = 2 * np.int64(node_f[k, NF_TYPE]) + (node_k[k, NK_ALL_INDIRECT] > 0)
        node_bi[k, NB_REP] = node_k[k, NK_REP] | (flags << REP_BITS)
        node_b[k, NB_FA] = np.float32(frame_coefficient(np.float64(node_b[k, NB_AXIS]),
                                                        np.float64(node_b[k, NB_AXIS + 1]),
                                                        np.float64(node_b[k, NB_AXIS + 2])))


def _level_order(tree: LightTree) -> list[np.ndarray]:
    """Node ids level by level from the root, siblings side by side (left, right, left, right, ...)."""
    levels = []
    level = np.array([tree.root], np.int64)
    while level.size:
        levels.append(level)
        inner = level[tree.left[level] >= 0]
        level = np.stack([tree.left[inner], tree.right[inner]], axis=1).ravel().astype(np.int64)
    return levels


def _check_tree(typ: str, tree: LightTree, n: int) -> np.ndarray:
    """LightcutsError if the tree does not fit n lights; else its node ids in level order."""
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
    order = np.concatenate(_level_order(tree)).astype(np.int64)
    if len(order) != k:
        raise LightcutsError(f"trees.{typ}: {k} nodes expected below the root for {n} lights")
    return order


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


@njit(cache=True, nogil=True)
def _flatten_rows(order, new_id, left, right, light, rep, bbox_min, bbox_max, cone_axis, cone_cos, intensity,
                  indirect, type_code, node_base, light_base, node_f, node_k, s, e):
    """Rows s..e-1 of one tree's part of the forest: node_f (K, 16), node_k (K, 4), row t for the
    tree's node ``order[t]`` (level order; ``new_id`` its inverse), with global node ids
    (``node_base`` + row) and light ids (``light_base`` + light). The all-indirect flag is set at
    the leaves only (:func:`_flatten_flags` does the rest)."""
    for t in range(s, e):
        old = order[t]
        for d in range(3):
            node_f[t, NF_LO + d] = bbox_min[old, d]
            node_f[t, NF_HI + d] = bbox_max[old, d]
            node_f[t, NF_AXIS + d] = cone_axis[old, d]
            node_f[t, NF_I + d] = intensity[old, d]
        node_f[t, NF_COS] = cone_cos[old]
        node_f[t, NF_TYPE] = type_code
        node_k[t, NK_REP] = rep[old] + light_base
        if left[old] < 0:
            node_k[t, NK_LEFT] = -1
            node_k[t, NK_RIGHT] = -1
            node_k[t, NK_ALL_INDIRECT] = 1 if indirect[light[old]] else 0
        else:
            node_k[t, NK_LEFT] = new_id[left[old]] + node_base
            node_k[t, NK_RIGHT] = new_id[right[old]] + node_base


@njit(cache=True)
def _flatten_flags(node_k, node_base):
    """A cluster is all-indirect if both children are: set from the last row up, as in level order
    children come after their parent."""
    for t in range(node_k.shape[0] - 1, -1, -1):
        a = node_k[t, NK_LEFT]
        if a >= 0:
            node_k[t, NK_ALL_INDIRECT] = (node_k[a - node_base, NK_ALL_INDIRECT]
                                          & node_k[node_k[t, NK_RIGHT] - node_base, NK_ALL_INDIRECT])


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
    light_f = cache_aligned_zeros((n, LF_WIDTH), np.float64)
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

    roots = []
    flat = []
    if trees is not None:
        for typ, ls in sets:
            tree = trees.get(typ)
            if tree is None:
                raise LightcutsError(f"trees: no tree for the {len(ls)} {typ} lights")
            flat.append((typ, ls, tree, _check_tree(typ, tree, len(ls))))
    total = sum(len(order) for *_, order in flat)
    node_f = np.zeros((total, NF_WIDTH))
    node_k = np.empty((total, NK_WIDTH), np.int64)
    light_base = 0
    node_base = 0
    for typ, ls, tree, order in flat:
        rows = slice(node_base, node_base + len(order))
        new_id = np.empty(len(order), np.int64)
        new_id[order] = np.arange(len(order))
        on_threads(_flatten_rows, len(order), _PARALLEL_MIN, order, new_id, tree.left, tree.right, tree.light, tree.rep,
                   tree.bbox_min, tree.bbox_max, tree.cone_axis, tree.cone_cos, tree.intensity,
                   np.ascontiguousarray(ls.indirect, np.bool_), TYPE_CODES[typ], node_base, light_base, node_f[rows],
                   node_k[rows])
        _flatten_flags(node_k[rows], node_base)
        roots.append(node_base)  # the root is first in level order
        light_base += len(ls)
        node_base += len(order)
    node_b, node_bi = pack_nodes(node_f, node_k)
    return Forest(light_f=light_f, light_i=light_i, node_f=node_f, node_k=node_k, roots=np.array(roots, np.int64),
                  n_lights=n_lights, node_b=node_b, node_bi=node_bi)


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
    if tfar > 0.0 and ray_occluded(occluded1, scene, buf, o0, o1, o2, d0, d1, d2, 0.0, tfar):
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
    frames (lightcuts.render.bounds.receiver_frames)."""
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


@intrinsic
def _f64_bits(typingctx, x):
    """The bits of a float64 as a uint64."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.uint64(types.float64), codegen


@intrinsic
def _bits_f64(typingctx, u):
    """The float64 with the bits of a uint64."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.uint64), codegen


_SLOT_MASK = np.uint64((1 << SLOT_BITS) - 1)


@njit(cache=True, error_model="numpy", forceinline=True)
def _heap_entry(bound, slot):
    """A heap entry (uint64): the bits of a bound > 0 (positive float64s order as their bits do, +inf
    included) rounded up to a multiple of 2^SLOT_BITS, or-ed with the slot. Rounded up: the entry's
    bound (:func:`_entry_bound`) is >= the bound, by at most 2^(SLOT_BITS - 52) relative, so the stop
    test on it can only refine more; entries are unique, so the order never depends on a tie."""
    u = _f64_bits(bound)
    return ((u + _SLOT_MASK) & ~_SLOT_MASK) | np.uint64(slot)


@njit(cache=True, error_model="numpy", forceinline=True)
def _entry_bound(e):
    """The bound of a heap entry (>= the bound it was made from)."""
    return _bits_f64(e & ~_SLOT_MASK)


@njit(cache=True, error_model="numpy", forceinline=True)
def _heap_push(heap, size, key):
    """Insert the entry key into the max-heap of ``size`` entries; returns the new size. Indices are
    unsigned (no wraparound test: module docstring); every operand is uint64, as numba makes a
    float64 of a mix of signed and unsigned integers."""
    i = np.uint64(size)
    while i > 0:
        parent = (i - np.uint64(1)) >> np.uint64(1)
        if heap[parent] >= key:
            break
        heap[i] = heap[parent]
        i = parent
    heap[i] = key
    return size + 1


@njit(cache=True, error_model="numpy", forceinline=True)
def _sift_down(heap, size, key):
    """Put the entry key at the top of the max-heap of ``size`` entries (replacing the top) and sift it
    down; returns size. heap[size] must be 0 (the sentinel: no test for a missing right child)."""
    i = np.uint64(0)
    n = np.uint64(size)
    one = np.uint64(1)
    while True:
        child = i + i + one
        if child >= n:
            break
        child += np.uint64(heap[child + one] > heap[child])
        if heap[child] <= key:
            break
        heap[i] = heap[child]
        i = child
    heap[i] = key
    return size


@njit(cache=True, error_model="numpy")
def _flush(occluded_n, width, scene, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio, node_b, t0, t1, t2):
    """Cast the waiting shadow rays (lanes 0..lanes-1 of the packet pk) and zero the estimate of
    each slot whose ray is occluded. Returns the cut's RGB total t less the estimates so removed."""
    packet_occluded(occluded_n, width, scene, pk, lanes)
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
             node_b, node_bi, roots, light_f, eps, max_cut, clamp_d2, ray_offset, visibility, occluded1, scene, buf,
             occluded_n, width, pk, heap, slot_node, slot_mgv, slot_ratio, lane_slot):
    """Radiance reflected at x towards the viewer, by a lightcut through every tree of the forest.

    x, n, r, rd, rs, exponent : receiver as in :func:`light_mgv`; node_b, node_bi, roots, light_f :
    the forest; eps : relative error threshold; max_cut : cut size limit; occluded_n, width, pk :
    the packet function and its width (``caster.packet_handles``) and the packet's scratch
    (lightcuts.accel.embree_kernels.new_ray_packet); the remaining arguments: see
    :func:`light_mgv` and the module docstring (scratch).
    Returns ``(L_r, L_g, L_b, cut_size, shadow_rays, clamp_lost)``: clamp_lost = the cut's estimate
    of the luminance that clamping removed here.

    The refinement loop reads the node record and the light row itself and calls functions of
    scalars for the rest (and the two heap helpers).
    """
    fr = receiver_frames(n0, n1, n2, r0, r1, r2)
    n_slots = 0
    size = 0
    rays = 0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for t in range(roots.shape[0]):
        k = roots[t]
        m0, m1, m2, ratio, nr = light_mgv(np.int64(node_bi[k, NB_REP] & _REP_MASK), light_f, x0, x1, x2, n0, n1, n2,
                                          r0, r1, r2, rd0, rd1, rd2, rs0, rs1, rs2, exponent, clamp_d2, ray_offset,
                                          visibility, occluded1, scene, buf)
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
            size = _heap_push(heap, size, _heap_entry(b, n_slots))
        n_slots += 1
    heap[size] = 0

    # Shadow rays wait in the packet (lane r belongs to slot lane_slot[r], -1 for a ray nobody
    # needs any more) while t counts them as visible. t is then the upper end of the true total,
    # so a top bound > eps * t must be refined whatever the rays return; only a top bound
    # <= eps * t needs their answers (module docstring, "Deferred visibility").
    lanes = 0
    while size > 0 and n_slots < max_cut:
        if _entry_bound(heap[0]) <= eps * luminance(t0, t1, t2):
            if lanes == 0:
                break
            t0, t1, t2 = _flush(occluded_n, width, scene, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio,
                                node_b, t0, t1, t2)
            lanes = 0
            continue
        # The top s leaves the heap; its first child with a bound takes its place (one sift down
        # instead of a pop and a push).
        s = np.int64(heap[0] & _SLOT_MASK)
        k = slot_node[s]
        prep = node_bi[k, NB_REP] & _REP_MASK
        left = np.int64(node_bi[k, NB_LEFT])  # siblings are side by side (build_forest)
        jl = np.int64(node_bi[left, NB_REP] & _REP_MASK)
        jr = np.int64(node_bi[left + 1, NB_REP] & _REP_MASK)
        if lanes + (jl != prep) + (jr != prep) > width:
            # Cast before s's estimate leaves t: a waiting ray of s may change that estimate.
            t0, t1, t2 = _flush(occluded_n, width, scene, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio,
                                node_b, t0, t1, t2)
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
        # The heap first (it needs the bounds only), then the children's lights and shadow ray. Heap
        # order: the left child (if it has a bound) takes the top, then the right.
        if bl > 0.0:
            _sift_down(heap, size, _heap_entry(bl, s))
            if br > 0.0:
                size = _heap_push(heap, size, _heap_entry(br, n_slots))
                heap[size] = 0
        elif br > 0.0:
            _sift_down(heap, size, _heap_entry(br, n_slots))
        else:  # no child entered the heap: the last entry fills the top
            size -= 1
            key = heap[size]
            heap[size] = 0
            if size > 0:
                _sift_down(heap, size, key)
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
            t0, t1, t2 = _flush(occluded_n, width, scene, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio,
                                node_b, t0, t1, t2)
            lanes = 0
    if lanes > 0:
        _flush(occluded_n, width, scene, pk, lanes, lane_slot, slot_node, slot_mgv, slot_ratio, node_b, t0, t1, t2)

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
