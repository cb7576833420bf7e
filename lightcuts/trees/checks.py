r"""The build-time checks of ``build_tree``: the lights before any kernel computes with them, and the
topology a builder returns (user builders can be wrong), each failure a one-line LightcutsError.

The topology check also lists the nodes in depth-first preorder with their subtree sizes, which the
fill (:mod:`lightcuts.trees.fill`) hands out to threads. :mod:`lightcuts.trees.validate` is the
independent check of a finished tree, for the tests and for users' builders.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LUMINANCE, LightSet
from lightcuts.limits import MAX_COORD, MAX_INTENSITY

# How far from unit length a normal (oriented) or a direction (directional) may be.
_UNIT_TOL = 1e-6


def check_lights(lights: LightSet, source: str = "lights") -> tuple[np.ndarray, np.ndarray]:
    """LightcutsError naming ``source`` (e.g. the light file) and the array at fault, before anything
    reaches a kernel that computes with it; returns the (N, 3) normals the tree uses (oriented
    lights: ``lights.normal`` rescaled to unit length, see build_tree; other types:
    ``lights.normal``) and the (N,) luminances (``lights.luminance``, bit for bit, from the same read
    of the arrays)."""
    if not isinstance(lights, LightSet):
        raise TypeError(f"build_tree expects a LightSet, got {type(lights).__name__}")
    if len(lights) == 0:
        raise LightcutsError(f"{source}: the light set is empty")
    unit_key = {"oriented": "normal", "directional": "position"}.get(lights.type)
    unit = {None: 0, "normal": 1, "position": 2}[unit_key]
    nonfinite, negative, worst, err, unit_normal, luminance = _scan_lights(
        lights.position, lights.normal, lights.intensity, np.asarray(LUMINANCE, np.float64), unit)
    for bit, key in enumerate(("position", "normal", "intensity")):
        if nonfinite >> bit & 1:
            raise LightcutsError(f"{source}: {key} has non-finite values")
    if negative:
        raise LightcutsError(f"{source}: intensity has negative values")
    # Within these bounds no metric overflows (lightcuts.limits), so every builder finds a pair.
    for key, arr, limit in (("position", lights.position, MAX_COORD), ("intensity", lights.intensity, MAX_INTENSITY)):
        if len(arr) and float(np.abs(arr).max()) > limit:
            raise LightcutsError(f"{source}: {key} has values beyond {limit:g} in magnitude "
                                 "(the clustering metric would overflow)")
    if unit_key is not None and err > _UNIT_TOL:
        what = "normals" if unit_key == "normal" else "directions (position)"
        raise LightcutsError(f"{source}: {lights.type} light {unit_key} {worst} is not unit length "
                             f"(|v| - 1 = {err:.3g}); {what} must be unit vectors")
    return (unit_normal if unit == 1 else lights.normal), luminance


@njit(cache=True)
def _scan_lights(position, normal, intensity, weights, unit):
    """One read of the light arrays for check_lights, (N, 3) float64 each.

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


def check_topology(name: str, out, n: int):
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

