r"""The lightcut's priority queue: a binary max-heap of uint64 entries, each a bound and a slot of the cut.

One integer per entry (:func:`heap_entry`) rather than a float64 key beside an int64 slot: one load
and one store per level of a sift, and integer compares on its chain of dependent loads. Indices are
uint64, since numba tests every signed index for a negative value. The array (``heap``, the cut's
scratch in lightcuts.integrators.cut) keeps a 0 sentinel after its last entry, so :func:`sift_down` need
not test for a missing right child. Every function is ``forceinline``: all run inside the
lightcut's refinement loop.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from lightcuts.integrators import SLOT_BITS


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


#: The low bits of an entry, which hold its slot.
SLOT_MASK = np.uint64((1 << SLOT_BITS) - 1)


@njit(cache=True, error_model="numpy", forceinline=True)
def heap_entry(bound, slot):
    """A heap entry (uint64): the bits of a bound > 0 (positive float64s order as their bits do, +inf
    included) rounded up to a multiple of 2^SLOT_BITS, or-ed with the slot. Rounded up: the entry's
    bound (:func:`entry_bound`) is >= the bound, by at most 2^(SLOT_BITS - 52) relative, so the stop
    test on it can only refine more; entries are unique, so the order never depends on a tie."""
    u = _f64_bits(bound)
    return ((u + SLOT_MASK) & ~SLOT_MASK) | np.uint64(slot)


@njit(cache=True, error_model="numpy", forceinline=True)
def entry_bound(e):
    """The bound of a heap entry (>= the bound it was made from)."""
    return _bits_f64(e & ~SLOT_MASK)


@njit(cache=True, error_model="numpy", forceinline=True)
def heap_push(heap, size, key):
    """Insert the entry key into the max-heap of ``size`` entries; returns the new size. Every
    operand is uint64 (module docstring), as numba makes a float64 of a mix of signed and unsigned
    integers."""
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
def sift_down(heap, size, key):
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


@njit(cache=True, error_model="numpy", forceinline=True)
def replace_top(heap, size, bl, left, br, right):
    """Replace the top entry (a cluster being refined) by its two children's: bound ``bl`` for the
    slot ``left`` and ``br`` for ``right``, a child with bound 0 left out (its estimate is exact).
    The left child, if it has a bound, takes the top, then the right is pushed; with neither, the
    last entry fills the top. Returns the new size; keeps the 0 sentinel after the last entry."""
    if bl > 0.0:
        sift_down(heap, size, heap_entry(bl, left))
        if br > 0.0:
            size = heap_push(heap, size, heap_entry(br, right))
            heap[size] = 0
    elif br > 0.0:
        sift_down(heap, size, heap_entry(br, right))
    else:
        size -= 1
        key = heap[size]
        heap[size] = 0
        if size > 0:
            sift_down(heap, size, key)
    return size
