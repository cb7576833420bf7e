"""LightTree: a binary cluster hierarchy over one LightSet, as flat arrays (2N-1 nodes).

Node ids are arbitrary (builders number them as they like); ``root`` names the top. Leaves have
``left == right == -1`` and ``light`` = the light index; internal nodes have ``light == -1``.

Per node (K = 2N-1):
    left, right : (K,) int32 child node ids, -1 at leaves
    light : (K,) int32 light index at leaves, -1 elsewhere
    bbox_min, bbox_max : (K, 3) float64 spatial box of the cluster's light positions
        (directional lights: box over their unit directions)
    cone_axis : (K, 3) float64 unit axis of the normal cone (zeros where there is no cone)
    cone_cos : (K,) float64 cosine of the cone half-angle; 1 for a single direction, < 0 past 90
        degrees, -1 for the full sphere (and for omni/directional lights, which have no cone)
    intensity : (K, 3) float64 summed RGB intensity of the cluster's lights
    rep : (K,) int32 light index of the representative (a light of the cluster)
    root : int
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.io import one_line, read_npz, save_npz

TREE_KEYS = ("left", "right", "light", "bbox_min", "bbox_max", "cone_axis", "cone_cos", "intensity", "rep")


@dataclass
class LightTree:
    left: np.ndarray
    right: np.ndarray
    light: np.ndarray
    bbox_min: np.ndarray
    bbox_max: np.ndarray
    cone_axis: np.ndarray
    cone_cos: np.ndarray
    intensity: np.ndarray
    rep: np.ndarray
    root: int
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        for k in ("left", "right", "light", "rep"):
            setattr(self, k, np.ascontiguousarray(getattr(self, k), np.int32))
        for k in ("bbox_min", "bbox_max", "cone_axis", "intensity"):
            setattr(self, k, np.ascontiguousarray(getattr(self, k), np.float64).reshape(-1, 3))
        self.cone_cos = np.ascontiguousarray(self.cone_cos, np.float64)
        self.root = int(self.root)

    @property
    def n_nodes(self) -> int:
        return len(self.left)

    @property
    def n_lights(self) -> int:
        return int(np.count_nonzero(self.light >= 0))

    def depth(self) -> int:
        """Number of nodes on the longest root-to-leaf path."""
        depth = np.zeros(self.n_nodes, np.int64)
        depth[self.root] = 1
        stack = [self.root]
        best = 1
        while stack:
            k = stack.pop()
            for c in (self.left[k], self.right[k]):
                if c >= 0:
                    depth[c] = depth[k] + 1
                    best = max(best, depth[c])
                    stack.append(c)
        return int(best)

    def clusters(self) -> list[frozenset]:
        """Every node's cluster as a frozenset of light indices (to compare trees built differently)."""
        out: list[frozenset | None] = [None] * self.n_nodes
        order = []
        stack = [self.root]
        while stack:
            k = stack.pop()
            order.append(k)
            if self.left[k] >= 0:
                stack += [self.left[k], self.right[k]]
        for k in reversed(order):
            out[k] = frozenset([int(self.light[k])]) if self.left[k] < 0 else out[self.left[k]] | out[self.right[k]]
        return [c for c in out if c is not None]

    def save(self, path) -> Path:
        arrays = {k: getattr(self, k) for k in TREE_KEYS}
        arrays["root"] = np.array(self.root)
        for k, v in self.meta.items():
            arrays[f"meta_{k}"] = np.asarray(v)
        return save_npz(path, **arrays)

    @classmethod
    def load(cls, path) -> "LightTree":
        """Read a tree file; LightcutsError naming the file and the key if it is malformed."""
        path = Path(path)
        z = read_npz(path, "tree")
        missing = [k for k in TREE_KEYS + ("root",) if k not in z]
        if missing:
            raise LightcutsError(f"{path}: missing key(s) {', '.join(missing)}")
        for k in TREE_KEYS + ("root",):
            if z[k].dtype.kind not in "biuf":
                raise LightcutsError(f"{path}: {k} has dtype {z[k].dtype}; expected numbers")
        if z["root"].size != 1:
            raise LightcutsError(f"{path}: root must be one integer, got shape {z['root'].shape}")
        meta = {k[5:]: a.item() if a.ndim == 0 else a for k, a in z.items() if k.startswith("meta_")}
        try:
            return cls(*(z[k] for k in TREE_KEYS), int(z["root"].reshape(())), meta)
        except LightcutsError:
            raise
        except (TypeError, ValueError, IndexError) as exc:
            raise LightcutsError(f"{path}: malformed tree ({one_line(exc)})") from None

