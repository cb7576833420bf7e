"""A flat bounding volume hierarchy over triangles: binary, one triangle per leaf, axis-aligned boxes.

:class:`FlatBVH` holds the nodes in depth-first order (structure of arrays): node 0 is the root, an
internal node's left child is the node right after it and ``right[i]`` is its right child, so a
subtree occupies one contiguous range. Boxes are float64: they hold the float32 vertices of the
mesh exactly, and the traversal's conservative slab test (lightcuts.accel.bvh.bvh_kernels) then never
culls a box a triangle's hit lies in.

A builder returns only a topology, in the convention of the light-tree builders
(lightcuts.trees.registry): 2F-1 nodes in any order, ``left[i] = right[i] = -1`` and ``prim[i]`` = the
triangle id for a leaf, ``prim[i] = -1`` for an internal node, and the root's index;
:func:`from_topology` turns it into a FlatBVH with its boxes.

Quality statistics (Walter et al. 2008, Fig. 6), for a random line that hits the root box; a line hits
a node's box with probability SA(node) / SA(root) (docs/math.md, "BVH quality statistics"). As the
paper defines them, the leaves are the triangles, with no box of their own: the root box is always
tested, and any other node's box, or a leaf's triangle, is tested when the line hits its parent's
box. ``E(boxes)`` = 1 + the sum over internal non-root nodes of SA(parent) / SA(root), ``E(tris)`` =
the sum over leaves of SA(parent) / SA(root), ``E(cost) = 0.5 E(boxes) + 1.0 E(tris)``. The variant
``*_leafbox`` gives every leaf a box tested before its triangle: ``E(boxes)`` sums SA(node) / SA(root)
over every node, ``E(tris)`` over the leaves.

.npz keys (:meth:`FlatBVH.save` / :meth:`FlatBVH.load`): ``lo``, ``hi`` (N, 3) float64 node boxes;
``left``, ``right``, ``prim`` (N,) int32 (as above, depth-first); ``n_faces`` () int64; ``builder``
() str, the name of the topology builder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.accel.triangles import triangle_boxes
from lightcuts.errors import LightcutsError
from lightcuts.io import read_npz, save_npz

#: Per-node keys of a saved BVH.
NODE_KEYS = ("lo", "hi", "left", "right", "prim")


@dataclass(frozen=True)
class FlatBVH:
    """Nodes in depth-first order: lo, hi (N, 3) float64 boxes (world units); left, right (N,) int32
    children (-1 for a leaf; left[i] = i + 1 for an internal node); prim (N,) int32 triangle of a leaf
    (-1 for an internal node); n_faces: triangles indexed; builder: the topology builder's name."""

    lo: np.ndarray
    hi: np.ndarray
    left: np.ndarray
    right: np.ndarray
    prim: np.ndarray
    n_faces: int
    builder: str = ""

    @property
    def n_nodes(self) -> int:
        return int(len(self.prim))

    @property
    def nbytes(self) -> int:
        """Memory of the node arrays, bytes."""
        return int(sum(getattr(self, k).nbytes for k in NODE_KEYS))

    @property
    def depth(self) -> int:
        """Edges on the longest root-to-leaf path (0 for a single leaf or an empty BVH)."""
        return int(_depth(self.left, self.right)) if self.n_nodes else 0

    def sah_stats(self) -> dict:
        """Walter et al. 2008 Fig. 6 as the paper defines it (module docstring): ``E_boxes``,
        ``E_tris``, ``E_cost`` = 0.5 E_boxes + E_tris; the leaf-box variant ``E_boxes_leafbox``,
        ``E_tris_leafbox``, ``E_cost_leafbox`` and ``E_boxes_internal`` (internal nodes only, root
        included); plus ``nodes``, ``depth`` and ``memory_bytes`` (node arrays). An empty BVH or a
        root box of zero area gives zeros; a single leaf (no box) gives E_tris 1."""
        out = {"nodes": self.n_nodes, "depth": self.depth, "memory_bytes": self.nbytes}
        keys = ("E_boxes", "E_tris", "E_cost", "E_boxes_leafbox", "E_tris_leafbox", "E_cost_leafbox",
                "E_boxes_internal")
        if self.n_nodes == 0:
            return {**out, **dict.fromkeys(keys, 0.0)}
        e = self.hi - self.lo
        sa = 2.0 * (e[:, 0] * e[:, 1] + e[:, 1] * e[:, 2] + e[:, 2] * e[:, 0])
        root = sa[0]
        if self.left[0] < 0:
            return {**out, **dict.fromkeys(keys, 0.0), "E_tris": 1.0, "E_cost": 1.0}
        ratio = sa / root if root > 0 else np.zeros_like(sa)
        leaf = self.prim >= 0
        inner = np.flatnonzero(~leaf)
        # each internal node's box, when hit, tests its two children: a box each, or a triangle each
        boxes, tris = 1.0, 0.0
        for child in (self.left[inner], self.right[inner]):
            child_leaf = leaf[child]
            boxes += float(ratio[inner][~child_leaf].sum())
            tris += float(ratio[inner][child_leaf].sum())
        boxes_lb = float(ratio.sum())
        tris_lb = float(ratio[leaf].sum())
        return {**out, "E_boxes": boxes, "E_tris": tris, "E_cost": 0.5 * boxes + tris,
                "E_boxes_leafbox": boxes_lb, "E_tris_leafbox": tris_lb, "E_cost_leafbox": 0.5 * boxes_lb + tris_lb,
                "E_boxes_internal": float(ratio[~leaf].sum())}

    def save(self, path) -> None:
        """Write the BVH as .npz (keys in the module docstring), atomically."""
        save_npz(path, **{k: getattr(self, k) for k in NODE_KEYS}, n_faces=np.int64(self.n_faces),
                 builder=np.str_(self.builder))

    @classmethod
    def load(cls, path) -> "FlatBVH":
        """Read a BVH written by :meth:`save`; LightcutsError naming the file and key if it is not a valid one."""
        z = read_npz(path, "BVH")
        for k in (*NODE_KEYS, "n_faces"):
            if k not in z:
                raise LightcutsError(f"{path}: {k}: missing (not a BVH file)")
        try:
            n_faces = int(z["n_faces"])
        except (TypeError, ValueError):
            raise LightcutsError(f"{path}: n_faces: not an integer") from None
        arrays = []
        for k in NODE_KEYS:
            a = z[k]
            want = np.float64 if k in ("lo", "hi") else np.int32
            if a.dtype.kind not in ("f" if want is np.float64 else "iu"):
                raise LightcutsError(f"{path}: {k}: has dtype {a.dtype}; expected {np.dtype(want)}")
            arrays.append(np.ascontiguousarray(a, want))
        bvh = cls(*arrays, n_faces=n_faces, builder=str(z["builder"]) if "builder" in z else "")
        bvh.check(str(path))
        return bvh

    def check(self, where: str = "BVH") -> None:
        """LightcutsError naming ``where`` and the key unless: shapes and dtypes as documented,
        depth-first order, each triangle 0..n_faces-1 in exactly one leaf, every box contains its
        children's boxes."""
        n = len(self.prim)
        for k in NODE_KEYS:
            a = getattr(self, k)
            shape = (n, 3) if k in ("lo", "hi") else (n,)
            dtype = np.float64 if k in ("lo", "hi") else np.int32
            if a.shape != shape or a.dtype != dtype:
                raise LightcutsError(f"{where}: {k}: has {a.dtype} {a.shape}; expected {np.dtype(dtype)} {shape}")
        if n != (2 * self.n_faces - 1 if self.n_faces else 0):
            raise LightcutsError(f"{where}: prim: {n} nodes for {self.n_faces} triangles; expected 2F-1")
        if n == 0:
            return
        if not (np.isfinite(self.lo).all() and np.isfinite(self.hi).all()):
            raise LightcutsError(f"{where}: lo/hi: not finite")
        code = _check_nodes(self.lo, self.hi, self.left, self.right, self.prim, self.n_faces)
        if code:
            raise LightcutsError(f"{where}: {_CHECK_MESSAGES[code]}")


_CHECK_MESSAGES = {
    1: "left/right: a child index out of range or not after its parent (not depth-first)",
    2: "left: an internal node's left child is not the next node (not depth-first)",
    3: "prim: a leaf's triangle out of range, or an internal node with a triangle",
    4: "prim: a triangle in more than one leaf, or in none",
    5: "lo/hi: a box does not contain its children's boxes (or lo > hi)",
    6: "left/right: a node is not reached from the root exactly once",
}


@njit(cache=True)
def _check_nodes(lo, hi, left, right, prim, n_faces):
    n = prim.shape[0]
    seen = np.zeros(n_faces, np.int64)
    reached = np.zeros(n, np.int64)
    reached[0] = 1
    for i in range(n):
        for a in range(3):
            if not lo[i, a] <= hi[i, a]:
                return 5
        if left[i] < 0 or right[i] < 0:
            if left[i] != -1 or right[i] != -1 or prim[i] < 0 or prim[i] >= n_faces:
                return 3
            seen[prim[i]] += 1
            continue
        if prim[i] != -1:
            return 3
        if left[i] >= n or right[i] >= n or right[i] <= i + 1:
            return 1
        if left[i] != i + 1:
            return 2
        for c in (left[i], right[i]):
            reached[c] += 1
            for a in range(3):
                if lo[c, a] < lo[i, a] or hi[c, a] > hi[i, a]:
                    return 5
    for f in range(n_faces):
        if seen[f] != 1:
            return 4
    for i in range(n):
        if reached[i] != 1:
            return 6
    return 0


@njit(cache=True)
def _depth(left, right):
    # Depth-first order: a child's index is larger than its parent's, so one forward pass suffices.
    d = np.zeros(left.shape[0], np.int64)
    best = 0
    for i in range(left.shape[0]):
        if left[i] >= 0:
            d[left[i]] = d[i] + 1
            d[right[i]] = d[i] + 1
        elif d[i] > best:
            best = d[i]
    return best


@njit(cache=True)
def _flatten(left, right, prim, root, tri_lo, tri_hi, out_lo, out_hi, out_left, out_right, out_prim):
    """Depth-first (left subtree first) copy of the topology with boxes; returns 0, or 1 if a node
    is reached twice or a leaf's triangle is out of range (the caller names the problem)."""
    n = left.shape[0]
    n_faces = tri_lo.shape[0]
    order = np.empty(n, np.int64)        # new index -> old index
    parent = np.full(n, -1, np.int64)    # new index -> new index of its parent
    visited = np.zeros(n, np.bool_)
    stack = np.empty(n + 1, np.int64)
    stack_parent = np.empty(n + 1, np.int64)
    top = 0
    stack[0] = root
    stack_parent[0] = -1
    top = 1
    k = 0
    while top > 0:
        top -= 1
        old = stack[top]
        par = stack_parent[top]
        if old < 0 or old >= n or visited[old] or k >= n:
            return 1
        visited[old] = True
        order[k] = old
        parent[k] = par
        if par >= 0:
            if out_left[par] < 0:
                out_left[par] = k
            else:
                out_right[par] = k
        out_left[k] = -1
        out_right[k] = -1
        if left[old] < 0 or right[old] < 0:
            f = prim[old]
            if left[old] != right[old] or f < 0 or f >= n_faces:
                return 1
            out_prim[k] = f
            for a in range(3):
                out_lo[k, a] = tri_lo[f, a]
                out_hi[k, a] = tri_hi[f, a]
        else:
            out_prim[k] = -1
            # Right pushed first so the left subtree comes out (and is numbered) first.
            stack[top] = right[old]
            stack_parent[top] = k
            stack[top + 1] = left[old]
            stack_parent[top + 1] = k
            top += 2
        k += 1
    if k != n:
        return 1
    # Boxes bottom-up: children have larger indices than their parents.
    for i in range(n - 1, -1, -1):
        if out_left[i] >= 0:
            l, r = out_left[i], out_right[i]
            for a in range(3):
                out_lo[i, a] = min(out_lo[l, a], out_lo[r, a])
                out_hi[i, a] = max(out_hi[l, a], out_hi[r, a])
    return 0


def from_topology(left, right, prim, root, vertices, faces, builder: str = "") -> FlatBVH:
    """The FlatBVH of a builder's topology (module docstring) over the mesh ``vertices`` (V, 3),
    ``faces`` (F, 3): nodes renumbered depth-first (left subtree first), boxes from the triangles
    (float32 vertices, held exactly in float64). LightcutsError if the topology is not a binary tree
    of 2F-1 nodes with every triangle in exactly one leaf."""
    tri_lo, tri_hi = triangle_boxes(vertices, faces)
    n_faces = len(tri_lo)
    left, right, prim = (np.ascontiguousarray(a, np.int64) for a in (left, right, prim))
    n = len(left)
    name = builder or "builder"
    if n != (2 * n_faces - 1 if n_faces else 0) or right.shape != (n,) or prim.shape != (n,):
        raise LightcutsError(f"BVH {name}: topology has {n} nodes (left {left.shape}, right {right.shape}, "
                             f"prim {prim.shape}) for {n_faces} triangles; expected 2F-1 each")
    out = FlatBVH(np.empty((n, 3)), np.empty((n, 3)), np.full(n, -1, np.int32), np.full(n, -1, np.int32),
                  np.empty(n, np.int32), n_faces, builder)
    if n:
        if _flatten(left, right, prim, int(root), tri_lo, tri_hi, out.lo, out.hi, out.left, out.right, out.prim):
            raise LightcutsError(f"BVH {name}: topology is not a binary tree over the triangles from root {root}")
        out.check(f"BVH {name}")
    return out
