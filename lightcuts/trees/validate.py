r"""An independent check of a LightTree against its LightSet (numpy, no kernels shared with the build).

Used by the builder contract tests and available to users who register their own builders.
Checks what the renderer relies on:

- topology: 2N-1 nodes, all reachable from the root exactly once, binary, one leaf per light;
- boxes: every node's box contains its children's boxes (a leaf's: its light's position), so it
  contains every position of its cluster;
- cones (oriented lights): every node's cone contains every normal of its cluster, up to a small
  angle tolerance; omni and directional lights have no cone (cos -1, zero axis);
- intensity: a leaf's is its light's, a parent's the sum of its children's;
- representatives: a light of the node's cluster (a leaf's: its own light).

It does not require a parent's cone to contain its children's cones: box-of-normals cones
(Walter 2008, section 5) are not monotone under union (a union's cone can be narrower than a loose
child cone) and the bound only needs the normals.
"""

from __future__ import annotations

import numpy as np

from lightcuts.cluster.cones import cone_contains
from lightcuts.lights.lightset import LightSet
from lightcuts.trees.tree import LightTree


def validate_tree(tree: LightTree, lights: LightSet, angle_tol: float = 1e-7) -> None:
    """Raise AssertionError naming the first node and property at fault; return None if valid.

    angle_tol : radians a normal may lie outside its cluster's cone (rounding of the cone formula).
    O(N * depth) time for the cone check, O(N) otherwise.
    """
    who = tree.meta.get("builder", "?")

    def check(ok, msg):
        """msg: a string, or a callable giving it (for messages that index the failing entries)."""
        if not ok:
            raise AssertionError(f"light tree (builder {who}): {msg() if callable(msg) else msg}")

    n = len(lights)
    k = 2 * n - 1
    check(tree.n_nodes == k, f"{tree.n_nodes} nodes for {n} lights, expected {k}")
    for key in ("left", "right", "light", "rep", "cone_cos"):
        check(getattr(tree, key).shape == (k,), f"{key} has shape {getattr(tree, key).shape}, expected ({k},)")
    for key in ("bbox_min", "bbox_max", "cone_axis", "intensity"):
        check(getattr(tree, key).shape == (k, 3), f"{key} has shape {getattr(tree, key).shape}, expected ({k}, 3)")
    left, right, light = (getattr(tree, key).astype(np.int64) for key in ("left", "right", "light"))
    root = tree.root
    check(0 <= root < k, f"root {root} outside [0, {k})")

    # Topology.
    leaf = left < 0
    check(np.array_equal(leaf, right < 0), "a node has exactly one child")
    check(np.all((left[~leaf] < k) & (right[~leaf] < k)), "a child id is out of range")
    check(np.all(light[~leaf] == -1), "an internal node has a light")
    check(leaf.sum() == n, f"{leaf.sum()} leaves for {n} lights")
    check(np.array_equal(np.sort(light[leaf]), np.arange(n)), "the leaves do not hold every light exactly once")
    parent = np.full(k, -1, np.int64)
    tin = np.full(k, -1, np.int64)
    tout = np.full(k, -1, np.int64)
    stack = [(root, False)]
    clock = 0
    while stack:
        node, done = stack.pop()
        if done:
            tout[node] = clock
            continue
        check(tin[node] < 0, f"node {node} is reached twice from the root")
        tin[node] = clock
        clock += 1
        stack.append((node, True))
        if left[node] >= 0:
            for child in (right[node], left[node]):
                parent[child] = node
                stack.append((child, False))
    check(clock == k, f"{k - clock} nodes are not reachable from the root")
    internal = np.flatnonzero(~leaf)
    leaves = np.flatnonzero(leaf)
    leaf_of = np.empty(n, np.int64)
    leaf_of[light[leaves]] = leaves

    # Boxes: leaves hold their light's point; parents contain both children.
    lo, hi = tree.bbox_min, tree.bbox_max
    check(np.all(lo <= hi), lambda: f"node {np.argmax(np.any(lo > hi, axis=1))}: bbox_min > bbox_max")
    pos = lights.position[light[leaves]]
    bad = np.any((lo[leaves] > pos) | (hi[leaves] < pos), axis=1)
    check(not bad.any(), lambda: f"leaf {leaves[np.argmax(bad)]}: box does not contain its light")
    for child in (left, right):
        c = child[internal]
        bad = np.any((lo[internal] > lo[c]) | (hi[internal] < hi[c]), axis=1)
        check(not bad.any(), lambda: f"node {internal[np.argmax(bad)]}: box does not contain a child's box")

    # Intensity.
    check(np.array_equal(tree.intensity[leaves], lights.intensity[light[leaves]]),
          "a leaf's intensity is not its light's")
    summed = tree.intensity[left[internal]] + tree.intensity[right[internal]]
    bad = ~np.all(np.isclose(tree.intensity[internal], summed, rtol=1e-12, atol=0), axis=1)
    check(not bad.any(), lambda: f"node {internal[np.argmax(bad)]}: intensity is not the sum of its children's")

    # Representatives: the leaf of rep[node] lies in node's depth-first interval.
    rep = tree.rep.astype(np.int64)
    check(np.all((rep >= 0) & (rep < n)), "a representative is not a light index")
    check(np.array_equal(rep[leaves], light[leaves]), "a leaf's representative is not its light")
    t = tin[leaf_of[rep]]
    bad = (t < tin) | (t >= tout)
    check(not bad.any(), lambda: f"node {np.argmax(bad)}: representative {rep[np.argmax(bad)]} is not in its cluster")

    # Cones.
    axis, cos_half = tree.cone_axis, tree.cone_cos
    if lights.type != "oriented":
        check(np.all(cos_half == -1.0) and np.all(axis == 0.0),
              f"{lights.type} lights have no cone, expected cone_cos -1 and a zero axis")
        return
    check(np.all((cos_half >= -1.0) & (cos_half <= 1.0)), "a cone_cos is outside [-1, 1]")
    full = cos_half <= -1.0
    norms = np.linalg.norm(axis, axis=1)
    check(np.all(np.abs(norms[~full] - 1.0) < 1e-9), "a cone axis is not a unit vector")
    # Walk every light up to the root, testing its normal against each ancestor's cone.
    lights_idx = np.arange(n)
    node = leaf_of.copy()
    while len(node):
        inside = cone_contains(axis[node], cos_half[node], lights.normal[lights_idx], tol=angle_tol)
        i = int(np.argmin(inside))
        check(inside.all(), lambda: f"node {node[i]}: normal of light {lights_idx[i]} is outside its cone "
                                    f"(half-angle {np.degrees(np.arccos(cos_half[node[i]])):.9f} degrees)")
        node = parent[node]
        keep = node >= 0
        node, lights_idx = node[keep], lights_idx[keep]
