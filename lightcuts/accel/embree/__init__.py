"""The Embree casters: ``embree`` (libembree4 through ctypes, called from numba kernels; embree.py,
embree_kernels.py) and ``embreex`` (embreex's batch API, the independent check)."""
