"""Rendering: the integrators (registry), the image driver they share, the eye-ray start, the lightcut
per receiver (forest, heap, cut, bounds), shading and camera, the multidimensional cut
(:mod:`lightcuts.integrators.multidim`) and the path tracer."""

from lightcuts.limits import MAX_CUT, SLOT_BITS  # noqa: F401
