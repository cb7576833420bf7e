r"""Light tree construction: a named builder gives the topology, one kernel fills the bounds.

``build_tree`` resolves the builder and the metric by name, calls the builder for the topology
(left, right, light, root), checks it (user builders can be wrong), and then computes for every
node, bottom-up, the same way for all builders:

- the spatial box of its lights' positions (directional lights: of their unit directions);
- the normal cone from the box of its lights' normals (Walter et al. 2008, section 5; oriented
  lights only, omni and directional lights get ``cone_cos = -1`` and a zero axis);
- the summed RGB intensity;
- the representative: a leaf's is its light; a parent takes the representative of one child with
  probability proportional to that child's scalar intensity (luminance), else the other's.

The fill runs on the numba threads, one subtree per task (:func:`_fill_nodes`); every node's values
depend only on its children's, so the tree does not depend on the thread count.

The representative draw is a counter-based hash of ``(seed, cluster)``, where a cluster is named by
the smallest light index of each of its two children; so the draw does not depend on how a builder
numbers its nodes, and two builders that produce the same clusters get the same representatives.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import box_union, points_box, row3, set_row3
from lightcuts.cluster.cones import cone_from_box
from lightcuts.errors import LightcutsError
from lightcuts.hashing import mix64 as _mix64
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.limits import MAX_COORD, MAX_INTENSITY
from lightcuts.parallel import balance, on_threads, run_all, threads_for
from lightcuts.trees.metrics import Metric
from lightcuts.trees.spec import TreeSpec, tree_spec
from lightcuts.trees.tree import LightTree

# Metadata keys holding the scene's bounding-box diagonal, in order of preference.
_DIAGONAL_KEYS = ("scene_diagonal", "diagonal")
# How far from unit length a normal (oriented) or a direction (directional) may be.
_UNIT_TOL = 1e-6
# Nodes per block of _fill_blocks: their rows (about 200 bytes a node) stay in the L2 cache.
_FILL_BLOCK = 4096
# Below this many nodes the fill runs on one thread (thread start-up would cost more).
_PARALLEL_MIN = 40000


def default_c(lights: LightSet) -> float:
    """Cone-term scale c = scene diagonal / 16 (Walter et al. 2008).

    The diagonal is the scene's, from the light set's metadata (``scene_diagonal``, or ``diagonal``
    as ``lights_from_config`` writes it) when present, else the diagonal of the lights' position
    box; directional lights always use the box of their directions, the space their tree lives in.
    A zero diagonal (all lights at one point) gives c = 1: then every cluster has L = 0 and any
    positive c orders the merges the same way.
    """
    diag = None
    key = next((k for k in _DIAGONAL_KEYS if k in lights.meta), None)
    if lights.type != "directional" and key is not None:
        try:
            diag = float(lights.meta[key])
        except (TypeError, ValueError):
            raise LightcutsError(f"lights: meta {key} = {lights.meta[key]!r} is not a number") from None
        if not 0 <= diag <= 16 * MAX_COORD:
            raise LightcutsError(f"lights: meta {key} = {diag} is not a number in [0, {16 * MAX_COORD:g}]")
    if diag is None:
        diag = _box_diagonal(np.ascontiguousarray(lights.position, np.float64))
    return diag / 16.0 if diag > 0 else 1.0


@njit(cache=True)
def _box_diagonal(position):
    """Length of the diagonal of the (N, 3) points' bounding box."""
    lo, hi = points_box(position, 0, position.shape[0])
    return np.sqrt((hi[0] - lo[0]) ** 2 + (hi[1] - lo[1]) ** 2 + (hi[2] - lo[2]) ** 2)


def _check_lights(lights: LightSet) -> tuple[np.ndarray, np.ndarray]:
    """LightcutsError naming the array at fault, before anything reaches a kernel that computes with
    it; returns the (N, 3) normals the tree uses (oriented lights: ``lights.normal`` rescaled to unit
    length, see build_tree; other types: ``lights.normal``) and the (N,) luminances
    (``lights.luminance``, bit for bit, from the same read of the arrays)."""
    if not isinstance(lights, LightSet):
        raise TypeError(f"build_tree expects a LightSet, got {type(lights).__name__}")
    if len(lights) == 0:
        raise LightcutsError("lights: the light set is empty")
    unit_key = {"oriented": "normal", "directional": "position"}.get(lights.type)
    unit = {None: 0, "normal": 1, "position": 2}[unit_key]
    nonfinite, negative, worst, err, unit_normal, luminance = _scan_lights(
        lights.position, lights.normal, lights.intensity, np.asarray(LUMINANCE, np.float64), unit)
    for bit, key in enumerate(("position", "normal", "intensity")):
        if nonfinite >> bit & 1:
            raise LightcutsError(f"lights: {key} has non-finite values")
    if negative:
        raise LightcutsError("lights: intensity has negative values")
    # Within these bounds no metric overflows (lightcuts.limits), so every builder finds a pair.
    for key, arr, limit in (("position", lights.position, MAX_COORD), ("intensity", lights.intensity, MAX_INTENSITY)):
        if len(arr) and float(np.abs(arr).max()) > limit:
            raise LightcutsError(f"lights: {key} has values beyond {limit:g} in magnitude "
                                 "(the clustering metric would overflow)")
    if unit_key is not None and err > _UNIT_TOL:
        what = "normals" if unit_key == "normal" else "directions (position)"
        raise LightcutsError(f"lights: {lights.type} light {unit_key} {worst} is not unit length "
                             f"(|v| - 1 = {err:.3g}); {what} must be unit vectors")
    return (unit_normal if unit == 1 else lights.normal), luminance


@njit(cache=True)
def _scan_lights(position, normal, intensity, weights, unit):
    """One read of the light arrays for _check_lights, (N, 3) float64 each.

    unit : 1 to check (and rescale) the normals, 2 to check the positions, 0 neither
    weights : (3,) luminance weights
    Returns (nonfinite, negative, worst, err, unit_normal, luminance): a bitmask of the arrays holding non-finite
    values (1 position, 2 normal, 4 intensity), whether an intensity is negative, the first row whose
    vector is furthest from unit length and that distance ``| |v| - 1 |``, and if unit == 1 the
    normals divided by their lengths (else an empty array), and the (N,) luminances summed in the
    order of LightSet.luminance. ``|v|`` is summed as np.linalg.norm sums
    it, so these are the numpy expressions' results, bit for bit.
    """
    n = position.shape[0]
    unit_normal = np.empty((n if unit == 1 else 0, 3))
    luminance = np.empty(n)
    nonfinite = 0
    negative = False
    worst = 0
    err = -1.0
    for i in range(n):
        for d in range(3):
            if not np.isfinite(position[i, d]):
                nonfinite |= 1
            if not np.isfinite(normal[i, d]):
                nonfinite |= 2
            if not np.isfinite(intensity[i, d]):
                nonfinite |= 4
            if intensity[i, d] < 0.0:
                negative = True
        luminance[i] = intensity[i, 0] * weights[0] + intensity[i, 1] * weights[1] + intensity[i, 2] * weights[2]
        if unit == 0:
            continue
        if unit == 1:
            x, y, z = normal[i, 0], normal[i, 1], normal[i, 2]
        else:
            x, y, z = position[i, 0], position[i, 1], position[i, 2]
        length = np.sqrt(x * x + y * y + z * z)
        if abs(length - 1.0) > err:
            worst = i
            err = abs(length - 1.0)
        if unit == 1 and length > 0.0:  # a zero normal fails the unit check; no 0 / 0 here
            unit_normal[i, 0] = x / length
            unit_normal[i, 1] = y / length
            unit_normal[i, 2] = z / length
    return nonfinite, negative, worst, err, unit_normal, luminance


# The topology rules _check_tree tests, in the order it tests them: its code - 1 indexes this.
_TOPOLOGY_ERRORS = (
    "node {i} has exactly one child",
    "internal node {i} has a light",
    "child ids outside [-1, {k})",
    "{count} leaves for {n} lights, or a leaf with a light index outside [0, {n})",
    "light {i} is in {count} leaves, expected exactly one",
    "the root {root} is the child of another node",
    "node {i} is the child of {count} nodes, expected exactly one",
    "some nodes are not reachable from the root",
)


def _check_topology(name: str, out, n: int):
    """The builder's (left, right, light, root) as int32 arrays plus the nodes in preorder and each
    node's subtree size (:func:`_preorder`);
    LightcutsError naming the builder if the topology is not a binary tree with one leaf per light."""
    def bad(msg: str) -> LightcutsError:
        return LightcutsError(f"builder {name!r} returned an invalid tree: {msg}")

    if not isinstance(out, tuple) or len(out) != 4:
        raise bad("expected a tuple (left, right, light, root)")
    k = 2 * n - 1
    arrays = []
    for key, a in zip(("left", "right", "light"), out[:3]):
        a = np.asarray(a)
        if a.shape != (k,) or not np.issubdtype(a.dtype, np.integer):
            raise bad(f"{key} has shape {a.shape} and dtype {a.dtype}, expected ({k},) integers for {n} lights")
        if a.dtype == np.int32:
            a = a.copy()
        else:
            # Every valid id fits in int32; clipping the others keeps each comparison the checks
            # make (< -1, < 0, >= k, >= n), so one int32 kernel checks every integer dtype.
            a = np.clip(a.astype(np.int64), -2**31, 2**31 - 1).astype(np.int32)
        arrays.append(a)
    left, right, light = arrays
    try:
        root = int(out[3])
    except (TypeError, ValueError):
        raise bad(f"root {out[3]!r} is not an integer") from None
    if not 0 <= root < k:
        raise bad(f"root {root} is not a node id in [0, {k})")
    order = np.empty(k, np.int32)
    size = np.empty(k, np.int32)
    code, i, count = _check_tree(left, right, light, root, n, order, size)
    if code:
        raise bad(_TOPOLOGY_ERRORS[code - 1].format(i=i, count=count, k=k, n=n, root=root))
    return left, right, light, root, order, size


@njit(cache=True)
def _check_tree(left, right, light, root, n, order, size):
    """The first topology rule broken, as ``(code, index, count)`` (code 0: none), see _TOPOLOGY_ERRORS.

    If the topology is a tree, fills ``order`` with the node ids in depth-first preorder and ``size``
    with each node's subtree size (:func:`_preorder`): parents before children, every subtree a
    contiguous range, which the fill hands out to threads.
    """
    k = left.shape[0]
    one_child = False
    has_light = False
    out_of_range = False
    leaves = 0
    bad_light = False
    # Flags only, no branch per node (leaves and internal nodes alternate unpredictably, and
    # mispredictions cost more than the loop's work); the node at fault is looked for afterwards.
    for node in range(k):
        a = left[node]
        b = right[node]
        i = light[node]
        leaf = a < 0
        one_child |= leaf != (b < 0)
        has_light |= (a >= 0) & (i != -1)
        out_of_range |= (a < -1) | (b < -1) | (a >= k) | (b >= k)
        leaves += leaf
        bad_light |= leaf & ((i < 0) | (i >= n))
    if one_child:
        for node in range(k):
            if (left[node] < 0) != (right[node] < 0):
                return 1, node, 0
    if has_light:
        for node in range(k):
            if left[node] >= 0 and light[node] != -1:
                return 2, node, 0
    if out_of_range:
        return 3, 0, 0
    if leaves != n or bad_light:
        return 4, 0, leaves
    seen = np.zeros(n, np.int32)
    parents = np.zeros(k, np.int32)
    for node in range(k):
        a = left[node]
        if a < 0:
            seen[light[node]] += 1
        else:
            parents[a] += 1
            parents[right[node]] += 1
    for i in range(n):
        if seen[i] != 1:
            return 5, i, seen[i]
    if parents[root] != 0:
        return 6, root, 0
    parents[root] = 1
    for i in range(k):
        if parents[i] != 1:
            return 7, i, parents[i]
    # One parent per node but the root, which has none: a walk from the root never revisits a node,
    # so it reaches all k nodes unless some lie on a cycle cut off from the root.
    return (0, 0, 0) if _preorder(left, right, root, order, size) == k else (8, 0, 0)


@njit(cache=True)
def _preorder(left, right, root, order, size):
    """Write the nodes below ``root`` into ``order`` depth-first, parent, left subtree, right subtree
    (every subtree a contiguous range), and into ``size`` the number of nodes of each one's subtree;
    returns how many were written (at most len(order); ``size`` is valid only if all were).

    Builders that number nodes that way already (the divisive ones) get the identity, found without
    a walk: a node's left child follows it and its right child follows the left subtree.
    """
    k = left.shape[0]
    if root == 0:
        preorder = True
        for node in range(k - 1, -1, -1):
            a = left[node]
            if a < 0:
                size[node] = 1
                continue
            b = right[node]
            if a != node + 1 or b != a + size[a] or b + size[b] > k:
                preorder = False
                break
            size[node] = 1 + size[a] + size[b]
        if preorder and size[0] == k:
            for t in range(k):
                order[t] = t
            return k
    stack = np.empty(k + 1, np.int32)
    stack[0] = root
    top = 1
    count = 0
    while top > 0 and count < k:
        top -= 1
        node = stack[top]
        order[count] = node
        count += 1
        if left[node] >= 0:
            stack[top] = right[node]
            stack[top + 1] = left[node]
            top += 2
    if count == k:
        for node in range(k):
            size[node] = 1
        for t in range(k - 1, -1, -1):
            node = order[t]
            if left[node] >= 0:
                size[node] = 1 + size[left[node]] + size[right[node]]
    return count


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


def _fill_nodes(order, size, left, right, light, position, normal, intensity, luminance, oriented, seed):
    """``(bbox_min, bbox_max, cone_axis, cone_cos, intensity, rep)`` of every node, bottom-up.

    ``order``, ``size`` : the nodes in preorder and their subtree sizes (:func:`_check_tree`).
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


def build_tree(lights: LightSet, builder: str | TreeSpec | None = None, metric: str | Metric | None = None,
               c: float | None = None, seed: int = 0) -> LightTree:
    """A LightTree over ``lights`` (one light type), 2N-1 nodes.

    builder : a :class:`~lightcuts.trees.spec.TreeSpec` from the plan step, or a registered builder
        name (``lightcuts.trees.BUILDERS.names()``; default the schema's), resolved with ``metric``
        and ``c`` by :func:`~lightcuts.trees.spec.tree_spec`
    metric : registered metric name or Metric, if the builder reads one (default the schema's)
    c : cone-term scale, world units, if the builder reads it; default :func:`default_c`
        (scene diagonal / 16)
    seed : seed of the builder (if it draws) and of the representatives

    Builders must handle any N >= 1 (N = 1: one leaf, which is the root). The tree's meta records
    the builder, and the metric and c only where they were read.
    LightcutsError for unknown names, parameters the builder does not read, bad lights (non-finite,
    negative intensity, non-unit normals) or a builder that returns an invalid topology.
    """
    if isinstance(builder, TreeSpec):
        if metric is not None or c is not None:
            raise TypeError("build_tree: give metric and c inside the TreeSpec")
        spec = builder
    else:
        spec = tree_spec(builder, metric, c)
    spec.check_size(len(lights))
    normal, luminance = _check_lights(lights)
    c = spec.c
    if c is None and "c" in spec.builder.reads:
        c = float(default_c(lights))
    seed = int(seed)
    n = len(lights)
    # Oriented lights' normals come back from _check_lights rescaled to unit length: the
    # box-of-normals cone assumes unit vectors, and normals within _UNIT_TOL of unit length (e.g.
    # read back from float32) would otherwise stray outside their cones by up to ~sqrt(_UNIT_TOL).
    out = spec.builder.obj(lights.position, normal, luminance, lights.type, spec.metric, c, seed)
    left, right, light, root, order, size = _check_topology(spec.name, out, n)
    bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep = _fill_nodes(
        order, size, left, right, light, lights.position, normal, lights.intensity, luminance,
        lights.type == "oriented", np.uint64(seed % 2**64))
    meta = dict(builder=spec.name)
    if spec.metric is not None:
        meta["metric"] = spec.metric.name
    if spec.reads_c:
        meta["c"] = c
    meta.update(seed=seed, type=lights.type, n_lights=n)
    return LightTree(left, right, light, bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep, root, meta)
