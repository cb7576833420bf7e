r"""Morton (Z-order) codes: the order of items along a Z-curve of their points.

The agglomerative loops (:mod:`lightcuts.cluster.agglomerate`) run on the items in this order, so
that clusters near each other in space have nearby ids and the per-cluster arrays stay in cache.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcuts.cluster.bounds import points_box


@njit(cache=True)
def _spread3(v):
    """Spread the low 21 bits of v (uint64) to every third bit (Morton code interleave)."""
    v &= np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    return (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)


@njit(cache=True)
def _morton_keys(position, bits, index_bits):
    """(N,) uint64 keys: the Morton code of each position quantised to ``bits`` bits per axis over the
    bounding box, shifted left by ``index_bits``, or-ed with the point's index (unique keys)."""
    n = position.shape[0]
    box_lo, box_hi = points_box(position, 0, n)
    lo = np.empty(3)
    scale = np.empty(3)
    top = np.float64((1 << bits) - 1)
    for t in range(3):
        lo[t] = box_lo[t]
        scale[t] = top / (box_hi[t] - box_lo[t]) if box_hi[t] > box_lo[t] else 0.0
    keys = np.empty(n, np.uint64)
    for i in range(n):
        code = np.uint64(0)
        for t in range(3):
            x = (position[i, t] - lo[t]) * scale[t]
            # Non-finite coordinates (refused before any tree is built) must not make the cast undefined.
            if not x >= 0.0:
                x = 0.0
            code |= _spread3(np.uint64(min(x, top))) << np.uint64(2 - t)
        keys[i] = (code << np.uint64(index_bits)) | np.uint64(i)
    return keys


def morton_order(position: np.ndarray) -> np.ndarray:
    """(N,) int64 permutation sorting points (lights, box centres) along a Z-order (Morton) curve.

    position : (N, 3) float64, quantised over its bounding box to as many bits per axis (at most 21) as
    fit in 64-bit keys beside the point's index, which breaks ties (the order of the sort is unique, so
    any sort algorithm gives it). Items that arrive in path or mesh order are scattered in space; in
    this order, clusters near each other in space have nearby ids, so the per-cluster arrays the
    builders index stay in cache.
    """
    n = len(position)
    index_bits = max(1, (n - 1).bit_length())
    bits = min(21, (64 - index_bits) // 3)
    keys = _morton_keys(np.ascontiguousarray(position, np.float64), bits, index_bits)
    keys.sort()
    return (keys & np.uint64((1 << index_bits) - 1)).astype(np.int64)
