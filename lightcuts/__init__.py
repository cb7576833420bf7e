"""lightcuts: Lightcuts rendering of many-light scenes with pluggable light-tree builders.

One sub-package per stage, each importing only the stages before it: ``cluster`` (the agglomerative
clustering engine: kd-tree, Fig. 3/4, dissimilarities, shared by the BVH and the light trees) ->
``scene`` -> ``accel`` (ray casting over the scene's triangles, which the particle tracer already
needs) -> ``lights`` -> ``trees`` -> ``render`` -> ``report`` -> ``mitsuba`` (the optional Mitsuba 3
reference renderer, imported only when used). Above them, ``commands`` (one module per CLI command, each resolving its
plan before any work) and ``cli``; below them, ``config`` (the run schema and its defaults),
``registry`` (plugins) and small helpers. Data travel between stages as flat numpy arrays in small
classes (:class:`~lightcuts.scene.Scene`, :class:`~lightcuts.lights.LightSet`,
:class:`~lightcuts.trees.LightTree`), each saved as ``.npz``.
"""

import os

__version__ = "0.1.0"

# LLVM's SLP vectorizer (straight-line code on pairs of doubles): numba ships it switched off (since
# 2023, numba PR #8852, after miscompilations of integer code reported with older LLVMs). lightcuts
# turns it on for the process unless NUMBA_SLP_VECTORIZE is set: the lightcut's bounds compute the
# same arithmetic for the axes of a box, and the Cornell-box render took 8-11% less time with it.
# Every output was checked bit for bit against the vectorizer off (lights, every builder and metric,
# renders, the reference). NUMBA_SLP_VECTORIZE=0 switches it off. numba
# reads the variable again before each compilation, so this holds even if numba was imported first;
# kernels already in numba's on-disk cache keep the code they were compiled with.
os.environ.setdefault("NUMBA_SLP_VECTORIZE", "1")

from lightcuts.errors import LightcutsError  # noqa: E402,F401
