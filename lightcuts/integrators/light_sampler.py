r"""The light sampler: light trees as the compact records that importance walks read
(lightcuts.integrators.importance), for any builder's trees, unchanged.

:func:`build_light_sampler` takes the render's light sets and their trees (one per light type, as
lightcuts' cut takes them) and lays every tree out level by level, siblings side by side, with 44
bytes a node: box (float32, rounded outwards), the emission cone's cosine and the power (float32),
the cone's axis (octahedral, 32 bits; the cone widened by the axis's quantisation error, so it
still bounds every normal), the left child and the parent (int32), and the leaf of every light
(int32). With 2N - 1 nodes that is about 92 bytes per light. Per-light boxes (``boxes``) replace a
leaf's point box, and every box above is refitted to them: a tree over the emitting triangles
(lightcuts.lights.triangles) is clustered on the centroids by any builder and sampled with the
triangles' own extents.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lightcuts.errors import LightcutsError
from lightcuts.integrators.forest import TYPE_CODES, _check_lights, _check_tree
from lightcuts.integrators.importance import (REC_COS, REC_HI, REC_LO, REC_PHI, REC_WIDTH, light_pmf, oct_decode,
                                              sample_light)
from lightcuts.lights.lightset import LIGHT_TYPES, LUMINANCE
from lightcuts.parallel import on_threads
from lightcuts.rounding import down32, up32

#: Extra half-angle (radians) added to a cone beyond its axis's measured quantisation error.
CONE_MARGIN = 1e-6
# Below this many nodes the record kernels run on one thread.
_PARALLEL_MIN = 20000


@dataclass
class LightSampler:
    """The records of :mod:`lightcuts.integrators.importance` (its docstring gives the layout) for
    the lights in type order (global light i is light ``i - offset[type]`` of that type's set).

    rec (K, 8) float32; axis (K,) uint32; child, parent (K,) int32; leaf (L,) int32; roots,
    root_type (T,) int64; n_lights {type: count}; offset {type: first global light id}.
    """

    rec: np.ndarray
    axis: np.ndarray
    child: np.ndarray
    parent: np.ndarray
    leaf: np.ndarray
    roots: np.ndarray
    root_type: np.ndarray
    n_lights: dict
    offset: dict

    @property
    def nbytes(self) -> int:
        """Bytes of the records (the sampling structure, without the lights themselves)."""
        return sum(a.nbytes for a in (self.rec, self.axis, self.child, self.parent, self.leaf, self.roots,
                                      self.root_type))

    @property
    def arrays(self) -> tuple:
        """``(rec, axis, child, parent, leaf, roots, root_type)``: the kernels' arguments."""
        return self.rec, self.axis, self.child, self.parent, self.leaf, self.roots, self.root_type

    def draw(self, p, n, u) -> tuple[np.ndarray, np.ndarray]:
        """Lights drawn at the point p with normal n (3,) for each uniform number of ``u`` (M,):
        ((M,) int64 global light ids, -1 where none can light p; (M,) float64 their probabilities)."""
        return _draw_all(*self.arrays, *(float(x) for x in p), *(float(x) for x in n),
                         np.ascontiguousarray(u, np.float64))

    def pmf(self, p, n) -> np.ndarray:
        """(L,) float64 the probability of drawing each light at the point p with normal n (3,)."""
        return _pmf_all(*self.arrays, *(float(x) for x in p), *(float(x) for x in n))


@njit(cache=True)
def _pmf_all(rec, axis, child, parent, leaf, roots, root_type, p0, p1, p2, n0, n1, n2):
    out = np.zeros(leaf.shape[0])
    for j in range(leaf.shape[0]):
        out[j] = light_pmf(rec, axis, child, parent, leaf, roots, root_type, j, p0, p1, p2, n0, n1, n2)
    return out


@njit(cache=True)
def _draw_all(rec, axis, child, parent, leaf, roots, root_type, p0, p1, p2, n0, n1, n2, u):
    lights = np.empty(u.shape[0], np.int64)
    probs = np.empty(u.shape[0])
    for i in range(u.shape[0]):
        lights[i], probs[i] = sample_light(rec, axis, child, roots, root_type, p0, p1, p2, n0, n1, n2, u[i])
    return lights, probs


@njit(cache=True, error_model="numpy")
def _oct_encode(v0, v1, v2):
    """The uint32 octahedral code (two 16-bit halves) of the unit vector v (zero maps to +z)."""
    s = abs(v0) + abs(v1) + abs(v2)
    if s == 0.0:
        v0, v1, v2, s = 0.0, 0.0, 1.0, 1.0
    x, y = v0 / s, v1 / s
    if v2 < 0.0:
        x, y = (1.0 - abs(y)) * (1.0 if x >= 0.0 else -1.0), (1.0 - abs(x)) * (1.0 if y >= 0.0 else -1.0)
    qx = np.uint32(np.rint((min(1.0, max(-1.0, x)) * 0.5 + 0.5) * 65535.0))
    qy = np.uint32(np.rint((min(1.0, max(-1.0, y)) * 0.5 + 0.5) * 65535.0))
    return qx | (qy << np.uint32(16))


@njit(cache=True, nogil=True)
def _gather(order, new_id, left, light, lo, hi, light_lo, light_hi, boxed, node_base, light_base, box, child,
            parent, leaf, s, e):
    """Rows s..e-1 of one tree (level order ``order``, ``new_id`` its inverse): box (K, 6) float64
    (a leaf's from ``light_lo``/``light_hi`` where ``boxed``), child, parent, leaf, with global ids
    from ``node_base`` and ``light_base``."""
    for t in range(s, e):
        old = order[t]
        for d in range(3):
            box[t, d] = lo[old, d]
            box[t, 3 + d] = hi[old, d]
        if left[old] < 0:
            j = light[old]
            child[t] = -(light_base + j + 1)
            leaf[light_base + j] = node_base + t
            if boxed:
                for d in range(3):
                    box[t, d] = light_lo[j, d]
                    box[t, 3 + d] = light_hi[j, d]
        else:
            c = new_id[left[old]]
            child[t] = node_base + c
            parent[c] = node_base + t
            parent[c + 1] = node_base + t


@njit(cache=True)
def _refit(box, child, node_base):
    """Every inner box the union of its children's, from the last row up (children follow their
    parent in level order)."""
    for t in range(box.shape[0] - 1, -1, -1):
        if child[t] >= 0:
            c = child[t] - node_base
            for d in range(3):
                box[t, d] = min(box[c, d], box[c + 1, d])
                box[t, 3 + d] = max(box[c, 3 + d], box[c + 1, 3 + d])


@njit(cache=True, nogil=True, error_model="numpy")
def _pack(order, box, cone_axis, cone_cos, phi, rec, axis, s, e):
    """Rows s..e-1 of the records: box rounded outwards, power, the cone's axis encoded and its
    cosine widened by the encoding's error (cos(theta_o + theta_q + CONE_MARGIN) without trigonometry)."""
    for t in range(s, e):
        old = order[t]
        for d in range(3):
            rec[t, REC_LO + d] = down32(box[t, d])
            rec[t, REC_HI + d] = up32(box[t, 3 + d])
        rec[t, REC_PHI] = np.float32(phi[old])
        c = min(1.0, cone_cos[old])
        if c <= -1.0:
            axis[t] = 0
            rec[t, REC_COS] = np.float32(-1.0)
            continue
        axis[t] = _oct_encode(cone_axis[old, 0], cone_axis[old, 1], cone_axis[old, 2])
        a0, a1, a2 = oct_decode(axis[t])
        q = min(1.0, max(-1.0, cone_axis[old, 0] * a0 + cone_axis[old, 1] * a1 + cone_axis[old, 2] * a2))
        if c <= -q:  # theta_o + theta_q >= pi
            rec[t, REC_COS] = np.float32(-1.0)
            continue
        cb = c * q - np.sqrt(max(0.0, 1.0 - c * c)) * np.sqrt(max(0.0, 1.0 - q * q))
        cb -= np.sqrt(max(0.0, 1.0 - cb * cb)) * CONE_MARGIN + 1e-12
        rec[t, REC_COS] = np.float32(-1.0) if cb <= -1.0 else down32(cb)


def _luminance(rgb: np.ndarray) -> np.ndarray:
    """(K,) luminance of (K, 3) RGB, per element (no BLAS call: lightcuts.lights.lightset.LightSet.luminance)."""
    return rgb[:, 0] * LUMINANCE[0] + rgb[:, 1] * LUMINANCE[1] + rgb[:, 2] * LUMINANCE[2]


def build_light_sampler(lights: dict, trees: dict, boxes: dict | None = None) -> LightSampler:
    """The sampler over ``lights`` ({type: LightSet}) and their ``trees`` ({type: LightTree}, any
    builder's); ``boxes`` {type: (lo, hi)} per-light boxes (N, 3) to refit to (e.g. triangles).
    Empty sets are skipped; LightcutsError naming the set for a mismatch."""
    for typ, ls in lights.items():
        _check_lights(typ, ls)
    sets = [(typ, lights[typ]) for typ in LIGHT_TYPES if typ in lights and len(lights[typ])]
    if not sets:
        raise LightcutsError("lights: no lights to sample")
    flat = []
    for typ, ls in sets:
        if typ not in trees:
            raise LightcutsError(f"trees: no tree for the {len(ls)} {typ} lights")
        flat.append((typ, ls, trees[typ], _check_tree(typ, trees[typ], len(ls))))
    n_nodes = sum(len(order) for *_, order in flat)
    n_lights = sum(len(ls) for _, ls in sets)
    rec = np.zeros((n_nodes, REC_WIDTH), np.float32)
    axis = np.zeros(n_nodes, np.uint32)
    child = np.zeros(n_nodes, np.int32)
    parent = np.zeros(n_nodes, np.int32)
    leaf = np.zeros(n_lights, np.int32)
    roots, root_type, offset = [], [], {}
    node_base = light_base = 0
    for t, (typ, ls, tree, order) in enumerate(flat):
        k = len(order)
        new_id = np.empty(k, np.int64)
        new_id[order] = np.arange(k)
        lo = hi = np.zeros((0, 3))
        if boxes is not None and typ in boxes:
            lo, hi = (np.ascontiguousarray(b, np.float64) for b in boxes[typ])
            if lo.shape != (len(ls), 3) or hi.shape != (len(ls), 3) or not np.all(lo <= hi):
                raise LightcutsError(f"lights.{typ}: per-light boxes must be (N, 3) with lo <= hi for {len(ls)} lights")
        rows = slice(node_base, node_base + k)
        box = np.empty((k, 6))
        on_threads(_gather, k, _PARALLEL_MIN, order, new_id, tree.left, tree.light, tree.bbox_min, tree.bbox_max,
                   lo, hi, len(lo) > 0, node_base, light_base, box, child[rows], parent[rows], leaf)
        parent[node_base] = -(t + 1)
        if len(lo):
            _refit(box, child[rows], node_base)
        on_threads(_pack, k, _PARALLEL_MIN, order, box, np.ascontiguousarray(tree.cone_axis),
                   np.ascontiguousarray(tree.cone_cos), _luminance(tree.intensity), rec[rows], axis[rows])
        roots.append(node_base)
        root_type.append(TYPE_CODES[typ])
        offset[typ] = light_base
        node_base += k
        light_base += len(ls)
    return LightSampler(rec, axis, child, parent, leaf, np.array(roots, np.int64), np.array(root_type, np.int64),
                        {typ: len(ls) for typ, ls in sets}, offset)
