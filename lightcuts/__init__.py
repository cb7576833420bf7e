"""lightcuts: Lightcuts rendering of many-light scenes with pluggable light-tree builders.

From Python: :func:`load_config`, :func:`render` and :func:`compare` (:mod:`lightcuts.api`), loaded
on first use so that ``import lightcuts`` stays cheap.

One sub-package per stage, each importing only the stages before it: ``cluster`` (the agglomerative
clustering engine: kd-tree, Fig. 3/4, dissimilarities, shared by the BVH and the light trees) ->
``scene`` -> ``accel`` (ray casting over the scene's triangles, which the particle tracer already
needs) -> ``lights`` -> ``trees`` -> ``integrators`` (how each pixel is computed: lightcuts,
multidimensional lightcuts, the path tracer, and their parts) -> ``report`` -> ``mitsuba`` (the
optional Mitsuba 3 reference renderer, imported only when used). Above them, in order: ``pipeline``
(the plan and the stages of a run), ``distributed`` (runs on a Dask cluster, imported only with
``--workers`` / ``--scheduler`` or ``cluster=``), ``api`` (the Python API), ``commands`` (one module
per CLI command: arguments and printing) and ``cli``; below them,
``config`` (the run schema and its defaults), ``registry`` (plugins), ``plugin_docs`` (the plugin
reference generated from the registries) and small helpers. Data travel
between stages as flat numpy arrays in small classes (:class:`~lightcuts.scene.Scene`,
:class:`~lightcuts.lights.LightSet`, :class:`~lightcuts.trees.LightTree`), each saved as ``.npz``;
docs/architecture.md draws the whole.
"""

import os

__version__ = "0.1.0"

# LLVM's SLP vectorizer (straight-line code on pairs of doubles), which numba ships switched off, is
# on for lightcuts' processes unless NUMBA_SLP_VECTORIZE is set: the lightcut's bounds compute the
# same arithmetic for the axes of a box (docs/performance.md has the measurement). NUMBA_SLP_VECTORIZE=0
# switches it off. numba reads the variable again before each compilation, so this holds even if numba
# was imported first; kernels already in numba's on-disk cache keep the code they were compiled with.
os.environ.setdefault("NUMBA_SLP_VECTORIZE", "1")

from lightcuts.errors import LightcutsError  # noqa: E402,F401

#: The names of the Python API (lightcuts.api), imported on first use.
_API = ("load_config", "render", "compare", "Render", "Comparison")


def __getattr__(name: str):
    if name in _API:
        from lightcuts import api

        return getattr(api, name)
    raise AttributeError(f"module 'lightcuts' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))
