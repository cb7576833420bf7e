r"""The forest: every light and light tree of a render flattened into the arrays the lightcut reads.

Lights of all types get global ids (types in the order of LIGHT_TYPES), the nodes of all trees
global ids and one root per tree, so that one kernel specialisation serves every light type and
the reference (which has no trees). Nodes are numbered level by level with siblings side by side:
a node's right child is its left child + 1 (both are always read together) and the top levels,
which every receiver reads, share cache lines. Each node has exact float64 rows (node_f, node_k)
and a packed float32 record of 64 bytes, one cache line (node_b, :func:`pack_nodes`): a cut reads
nodes in an order no layout can predict, and with 10^5 lights the tree is larger than the L2
cache. Column layouts: the ``NF_*``, ``NK_*``, ``NB_*`` and ``LF_*`` constants below.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LIGHT_TYPES, LightSet
from lightcuts.lights.spacing import indirect_spacing
from lightcuts.parallel import on_threads
from lightcuts.integrators.bounds import DIRECTIONAL, OMNI, ORIENTED, frame_coefficient
from lightcuts.rounding import down32, up32
from lightcuts.trees.tree import LightTree

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
# axis's frame coefficient (lightcuts.integrators.bounds.frame_coefficient of the float32 axis).
NB_LO, NB_HI, NB_AXIS, NB_COS, NB_I, NB_LEFT, NB_REP, NB_FA, NB_WIDTH = 0, 3, 6, 9, 10, 13, 14, 15, 16
#: Bits of a record's NB_REP column that hold the representative; the flags sit above them.
REP_BITS = 28
#: The representative's bits of a record's NB_REP column.
REP_MASK = (1 << REP_BITS) - 1
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
    vpl_spacing : the indirect VPLs' median spacing, world units (lightcuts.lights.spacing; 0 without
        two of them), which the default clamp radius is a multiple of; vpl_count : their number
    """

    light_f: np.ndarray
    light_i: np.ndarray
    node_f: np.ndarray
    node_k: np.ndarray
    roots: np.ndarray
    n_lights: dict
    node_b: np.ndarray
    node_bi: np.ndarray
    vpl_spacing: float = 0.0
    vpl_count: int = 0


def cache_aligned_zeros(shape: tuple[int, int], dtype) -> np.ndarray:
    """Zeros whose first row starts on a 64-byte cache line: with 64-byte rows, a row is one line
    (numpy's own allocations are only 16-byte aligned, so every row would straddle two lines)."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.zeros(n + 64, np.uint8)
    start = -raw.ctypes.data % 64
    return raw[start:start + n].view(dtype).reshape(shape)


def pack_nodes(node_f: np.ndarray, node_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's node records ``(node_b, node_bi)`` (``NB_*`` columns) from the float64 rows.

    One 64-byte line a node (float32) instead of the rows' 160 bytes in two arrays (module
    docstring). The bounds stay bounds: boxes are rounded outwards and cones widened by CONE_WIDEN
    (float32 rounding moves an axis by about 1e-7 rad, and the float32 frame coefficient tilts the
    cone's frame by about as much). The summed intensity is rounded to the nearest float32
    (relative 6e-8), in the estimate and bound alike (docs/math.md, "Error bound").
    """
    k = node_f.shape[0]
    if k >= 2 ** 31 - 1:
        raise LightcutsError(f"trees: {k} nodes exceed the kernel's int32 node ids")
    if k and node_k[:, NK_REP].max() > REP_MASK:
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
                  n_lights=n_lights, node_b=node_b, node_bi=node_bi,
                  vpl_spacing=indirect_spacing(dict(sets)), vpl_count=int(sum(ls.indirect.sum() for _, ls in sets)))

