"""Limits fixed by the kernels' data layout, kept free of kernels so the config schema can read them.

SLOT_BITS : low bits of a lightcut heap entry that hold its slot (lightcuts.render.heap)
MAX_CUT : the largest cut, since the cut's scratch holds max_cut + 2 slots
"""

SLOT_BITS = 20
MAX_CUT = (1 << SLOT_BITS) - 2
