"""Rendering: the lightcut per receiver (forest, heap, cut, bounds), shading, camera and the image loop."""

from lightcuts.limits import MAX_CUT, SLOT_BITS  # noqa: F401
