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

The representative draw is a counter-based hash of ``(seed, cluster)``, where a cluster is named by
the smallest light index of each of its two children; so the draw does not depend on how a builder
numbers its nodes, and two builders that produce the same clusters get the same representatives.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LightSet
from lightcuts.trees.cones import cone_from_box
from lightcuts.trees.metrics import Metric, as_metric
from lightcuts.trees.registry import get_builder, get_metric
from lightcuts.trees.tree import LightTree

# Metadata keys holding the scene's bounding-box diagonal, in order of preference.
_DIAGONAL_KEYS = ("scene_diagonal", "diagonal")
# How far from unit length a normal (oriented) or a direction (directional) may be.
_UNIT_TOL = 1e-6


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
        diag = float(lights.meta[key])
        if not np.isfinite(diag) or diag < 0:
            raise LightcutsError(f"lights: meta {key} = {diag} is not a finite non-negative number")
    if diag is None:
        diag = float(np.linalg.norm(lights.position.max(axis=0) - lights.position.min(axis=0)))
    return diag / 16.0 if diag > 0 else 1.0


def _check_lights(lights: LightSet) -> None:
    """LightcutsError naming the array at fault, before anything reaches a kernel."""
    if not isinstance(lights, LightSet):
        raise TypeError(f"build_tree expects a LightSet, got {type(lights).__name__}")
    if len(lights) == 0:
        raise LightcutsError("lights: the light set is empty")
    for key in ("position", "normal", "intensity"):
        if not np.all(np.isfinite(getattr(lights, key))):
            raise LightcutsError(f"lights: {key} has non-finite values")
    if np.any(lights.intensity < 0):
        raise LightcutsError("lights: intensity has negative values")
    unit_key = {"oriented": "normal", "directional": "position"}.get(lights.type)
    if unit_key is not None:
        err = np.abs(np.linalg.norm(getattr(lights, unit_key), axis=1) - 1.0)
        i = int(np.argmax(err))
        if err[i] > _UNIT_TOL:
            what = "normals" if unit_key == "normal" else "directions (position)"
            raise LightcutsError(f"lights: {lights.type} light {unit_key} {i} is not unit length "
                                 f"(|v| - 1 = {err[i]:.3g}); {what} must be unit vectors")


def _check_topology(name: str, out, n: int):
    """The builder's (left, right, light, root) as int32 arrays plus a parents-first node order;
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
        arrays.append(a.astype(np.int64))
    left, right, light = arrays
    try:
        root = int(out[3])
    except (TypeError, ValueError):
        raise bad(f"root {out[3]!r} is not an integer") from None
    if not 0 <= root < k:
        raise bad(f"root {root} is not a node id in [0, {k})")
    leaf = left < 0
    if np.any(leaf != (right < 0)):
        raise bad(f"node {int(np.argmax(leaf != (right < 0)))} has exactly one child")
    if np.any(light[~leaf] != -1):
        raise bad(f"internal node {int(np.flatnonzero(~leaf & (light != -1))[0])} has a light")
    if np.any(left >= k) or np.any(right >= k) or np.any(left < -1) or np.any(right < -1):
        raise bad(f"child ids outside [-1, {k})")
    leaf_lights = light[leaf]
    if len(leaf_lights) != n or np.any(leaf_lights < 0) or np.any(leaf_lights >= n):
        raise bad(f"{len(leaf_lights)} leaves for {n} lights, or a leaf with a light index outside [0, {n})")
    seen = np.bincount(leaf_lights, minlength=n)
    if np.any(seen != 1):
        i = int(np.argmax(seen != 1))
        raise bad(f"light {i} is in {seen[i]} leaves, expected exactly one")
    parents = np.bincount(np.concatenate([left[~leaf], right[~leaf]]), minlength=k)
    if parents[root] != 0:
        raise bad(f"the root {root} is the child of another node")
    parents[root] = 1
    if np.any(parents != 1):
        i = int(np.argmax(parents != 1))
        raise bad(f"node {i} is the child of {parents[i]} nodes, expected exactly one")
    left, right, light = (a.astype(np.int32) for a in (left, right, light))
    order = np.empty(k, np.int32)
    # Every non-root node has one parent and the root none, so a walk from the root never revisits
    # a node; it reaches all k nodes unless some are on a cycle cut off from the root.
    if _preorder(left, right, root, order) != k:
        raise bad("some nodes are not reachable from the root")
    return left, right, light, root, order


@njit(cache=True)
def _preorder(left, right, root, order):
    """Fill ``order`` with node ids, parents before children; return how many were reached."""
    k = left.shape[0]
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
            stack[top] = left[node]
            stack[top + 1] = right[node]
            top += 2
    return count


@njit(cache=True)
def _mix64(x):
    """splitmix64 finaliser: a well-mixed uint64 from a uint64."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(cache=True)
def _uniform(seed, a, b):
    """A uniform float in [0, 1) from (seed, a, b), a < b light indices."""
    h = _mix64(seed + np.uint64(0x9E3779B97F4A7C15))
    h = _mix64(h ^ np.uint64(a))
    h = _mix64(h ^ np.uint64(b))
    return float(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _fill_nodes(order, left, right, light, position, normal, intensity, luminance, oriented, seed,
                bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep):
    """Bounds, cones, intensities and representatives of every node, children before parents."""
    k = left.shape[0]
    nlo = np.empty((k, 3))
    nhi = np.empty((k, 3))
    lum = np.empty(k)
    first = np.empty(k, np.int64)  # smallest light index of the cluster: names it for the draw
    for t in range(k - 1, -1, -1):
        node = order[t]
        a = left[node]
        if a < 0:
            i = light[node]
            for d in range(3):
                bbox_min[node, d] = position[i, d]
                bbox_max[node, d] = position[i, d]
                nlo[node, d] = normal[i, d]
                nhi[node, d] = normal[i, d]
                node_intensity[node, d] = intensity[i, d]
            lum[node] = luminance[i]
            first[node] = i
            rep[node] = i
        else:
            b = right[node]
            for d in range(3):
                bbox_min[node, d] = min(bbox_min[a, d], bbox_min[b, d])
                bbox_max[node, d] = max(bbox_max[a, d], bbox_max[b, d])
                nlo[node, d] = min(nlo[a, d], nlo[b, d])
                nhi[node, d] = max(nhi[a, d], nhi[b, d])
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
        if oriented:
            ax, ay, az, cc = cone_from_box(nlo[node, 0], nlo[node, 1], nlo[node, 2],
                                           nhi[node, 0], nhi[node, 1], nhi[node, 2])
            cone_axis[node, 0] = ax
            cone_axis[node, 1] = ay
            cone_axis[node, 2] = az
            cone_cos[node] = cc
        else:
            cone_axis[node, 0] = 0.0
            cone_axis[node, 1] = 0.0
            cone_axis[node, 2] = 0.0
            cone_cos[node] = -1.0


def build_tree(lights: LightSet, builder: str = "agglomerative", metric: str = "walter2008",
               c: float | None = None, seed: int = 0) -> LightTree:
    """A LightTree over ``lights`` (one light type), 2N-1 nodes.

    builder : registered builder name (``lightcuts.trees.BUILDERS.names()``)
    metric : registered metric name (``lightcuts.trees.METRICS.names()``)
    c : cone-term scale of the metric, world units; default :func:`default_c` (scene diagonal / 16)
    seed : seed of the builder (if it draws) and of the representatives

    Builders must handle any N >= 1 (N = 1: one leaf, which is the root).
    LightcutsError for unknown names, bad lights (non-finite, negative intensity, non-unit normals)
    or a builder that returns an invalid topology.
    """
    builder_fn = get_builder(builder)
    metric_obj: Metric = as_metric(get_metric(metric), metric)
    _check_lights(lights)
    if c is None:
        c = default_c(lights)
    c = float(c)
    if not (np.isfinite(c) and c > 0):
        raise LightcutsError(f"tree.c = {c}: must be a positive finite number")
    seed = int(seed)
    n = len(lights)
    normal = lights.normal
    if lights.type == "oriented":
        # The box-of-normals cone assumes unit vectors; normals within _UNIT_TOL of unit length (e.g.
        # read back from float32) would otherwise stray outside their cones by up to ~sqrt(_UNIT_TOL).
        normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    luminance = lights.luminance
    out = builder_fn(lights.position, normal, luminance, lights.type, metric_obj, c, seed)
    left, right, light, root, order = _check_topology(builder, out, n)
    k = 2 * n - 1
    bbox_min, bbox_max, cone_axis, node_intensity = (np.empty((k, 3)) for _ in range(4))
    cone_cos = np.empty(k)
    rep = np.empty(k, np.int32)
    _fill_nodes(order, left, right, light, lights.position, normal, lights.intensity, luminance,
                lights.type == "oriented", np.uint64(seed % 2**64), bbox_min, bbox_max, cone_axis, cone_cos,
                node_intensity, rep)
    meta = dict(builder=builder, metric=metric_obj.name, c=c, seed=seed, type=lights.type, n_lights=n)
    return LightTree(left, right, light, bbox_min, bbox_max, cone_axis, cone_cos, node_intensity, rep, root, meta)
