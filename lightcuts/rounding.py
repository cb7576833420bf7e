"""Outward rounding to float32, for bounds stored at half the memory (kd-tree nodes, packed light-tree
records): a lower end rounded down and an upper end rounded up still bound what they bounded."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def down32(x):
    """The largest float32 <= x."""
    f = np.float32(x)
    if f > x:
        f = np.nextafter(f, np.float32(-np.inf))
    return f


@njit(cache=True)
def up32(x):
    """The smallest float32 >= x."""
    f = np.float32(x)
    if f < x:
        f = np.nextafter(f, np.float32(np.inf))
    return f
