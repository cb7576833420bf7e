"""Rendering: the lightcut per receiver (forest, heap, cut, bounds), shading, camera and the image loop,
and the multidimensional cut (:mod:`lightcuts.render.multidim`)."""

from lightcuts.limits import MAX_CUT, SLOT_BITS  # noqa: F401

#: Light representatives per light node in a multidimensional cut (1: the tree's own only); the
#: integrator's default, here so that the integrator registry and the kernels' module share it.
DEFAULT_REPRESENTATIVES = 4
