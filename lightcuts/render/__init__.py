"""Rendering: the integrators (registry), the image driver they share, the eye-ray start, the lightcut
per receiver (forest, heap, cut, bounds), shading and camera, the multidimensional cut
(:mod:`lightcuts.render.multidim`) and the path tracer."""

from lightcuts.limits import MAX_CUT, SLOT_BITS  # noqa: F401

#: Light representatives per light node in a multidimensional cut (1: the tree's own only); the
#: integrator's default, here so that the integrator registry and the kernels' module share it.
DEFAULT_REPRESENTATIVES = 4
#: Vertices of a path at most in the path integrator (lightcuts.render.path; Russian roulette ends
#: nearly all paths long before): its ``max_depth``'s default and bound.
MAX_PATH_VERTICES = 64
