"""lightcuts: Lightcuts rendering of many-light scenes with pluggable light-tree builders.

From Python: :func:`load_config`, :func:`render` and :func:`compare` (:mod:`lightcuts.api`), loaded
on first use so that ``import lightcuts`` stays cheap. ``lightcuts.render`` is also the render
stage's package: called, it is :func:`lightcuts.api.render`.

One sub-package per stage, each importing only the stages before it: ``cluster`` (the agglomerative
clustering engine: kd-tree, Fig. 3/4, dissimilarities, shared by the BVH and the light trees) ->
``scene`` -> ``accel`` (ray casting over the scene's triangles, which the particle tracer already
needs) -> ``lights`` -> ``trees`` -> ``render`` -> ``report`` -> ``mitsuba`` (the optional Mitsuba 3
reference renderer, imported only when used). Above them, ``api`` (the Python API), ``distributed``
(runs on a Dask cluster, beside the API, imported only with ``--workers`` / ``--scheduler``) and
``commands`` (one module per CLI command, each resolving its plan before any work) and ``cli``; below them,
``config`` (the run schema and its defaults), ``registry`` (plugins), ``plugin_docs`` (the plugin
reference generated from the registries) and small helpers. Data travel
between stages as flat numpy arrays in small classes (:class:`~lightcuts.scene.Scene`,
:class:`~lightcuts.lights.LightSet`, :class:`~lightcuts.trees.LightTree`), each saved as ``.npz``;
docs/architecture.md draws the whole.
"""

import os
import sys
import types

__version__ = "0.1.0"

# LLVM's SLP vectorizer (straight-line code on pairs of doubles), which numba ships switched off, is
# on for lightcuts' processes unless NUMBA_SLP_VECTORIZE is set: the lightcut's bounds compute the
# same arithmetic for the axes of a box (docs/performance.md has the measurement). NUMBA_SLP_VECTORIZE=0
# switches it off. numba reads the variable again before each compilation, so this holds even if numba
# was imported first; kernels already in numba's on-disk cache keep the code they were compiled with.
os.environ.setdefault("NUMBA_SLP_VECTORIZE", "1")

from lightcuts.errors import LightcutsError  # noqa: E402,F401

#: The names of the Python API (lightcuts.api), imported on first use.
_API = ("load_config", "compare", "Render", "Comparison")


def __getattr__(name: str):
    if name in _API:
        from lightcuts import api

        return getattr(api, name)
    if name == "render":  # the stage's package, callable (see _Package)
        import importlib

        return importlib.import_module("lightcuts.render")
    raise AttributeError(f"module 'lightcuts' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API) | {"render"})


class _RenderPackage(types.ModuleType):
    """The ``lightcuts.render`` package, callable: ``lightcuts.render(config, ...)`` is
    :func:`lightcuts.api.render`."""

    def __call__(self, config, **kwargs):
        from lightcuts.api import render

        return render(config, **kwargs)


class _Package(types.ModuleType):
    """The ``lightcuts`` package: when the import system binds the ``render`` sub-package to it, the
    sub-package becomes callable (the package name and the API function share one name)."""

    def __setattr__(self, name, value):
        if name == "render" and type(value) is types.ModuleType:
            value.__class__ = _RenderPackage
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
