#: Low bits of a lightcut heap entry that hold its slot (lightcuts.render.heap.heap_entry), and so the
#: largest cut (the scratch has max_cut + 2 slots). Here rather than in cut, so that validating a
#: config (lightcuts.config.schema) does not import the kernels.
SLOT_BITS = 20
MAX_CUT = (1 << SLOT_BITS) - 2
