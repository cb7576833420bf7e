"""The render integrators (see :mod:`lightcuts.registry`): how each pixel's radiance is computed.

An entry's object is the function the render path calls,

    integrate(scene, caster, lights: dict, trees: dict, *, camera, spp, eps, max_cut, clamp,
              clamp_min_distance, envmap, seed, crop, progress, **params) -> RenderResult

with ``params`` the entry's declared parameters (as resolved from ``render.integrator``). The
config names one as ``render.integrator: NAME`` or ``{type: NAME, param: value, ...}`` (default
``lightcuts``); the plan step resolves it before any work. Adding an integrator is one
``INTEGRATORS.register(...)`` call in a module listed in ``builtins`` (or an entry point in group
``lightcuts.integrators``).

Every entry also accepts ``aperture`` and ``focus_distance`` (the camera's thin lens) and declares
the traits ``reference`` (the brute-force function over the same samples, same arguments without
``trees``, ``eps`` and ``max_cut``, against which its errors are measured) and ``lens`` (whether it
renders a thin lens; the plan refuses ``camera.aperture > 0`` otherwise) and ``cut_unit`` (what
its cut sizes count, as report.json names it), and may declare ``converging`` (it takes
``compensation`` and ``representatives``: ``render.compensation`` and ``render.representatives``;
the plan refuses them otherwise), ``forest`` (it and its reference take ``forest``, the
lightcuts.render.forest.build_forest of the same lights and trees, made once for many calls: a
cluster's tiles) and ``kernels``: the module whose
``_render_band`` kernel its renders use and whose ``warm_kernels()`` compiles it, which the commands
compile in a second process while the lights and trees are made (lightcuts.commands.warmup).

Entries: ``lightcuts``, a lightcut per eye ray through every light tree (Walter et al. 2005,
:func:`lightcuts.render.integrator.render_image`); ``multidimensional``, one cut per pixel through
the product of a gather tree over the pixel's eye-ray hits and the light trees (Walter et al. 2006,
:mod:`lightcuts.render.multidim`).
"""

from __future__ import annotations

from lightcuts.registry import Param, Registry
from lightcuts.render import DEFAULT_REPRESENTATIVES


INTEGRATORS: Registry = Registry("integrator", group="lightcuts.integrators",
                                 builtins=("lightcuts.render.integrators",))


def _all_lights(scene, caster, lights: dict, *, aperture: float = 0.0, focus_distance=None, **settings):
    """Every eye ray's hit with every light: ``render_reference``."""
    from lightcuts.render.integrator import render_reference

    return render_reference(scene, caster, lights, **settings)


@INTEGRATORS.register("lightcuts", reference=_all_lights, lens=False, cut_unit="light nodes per eye ray",
                      kernels="lightcuts.render.integrator", converging=True, forest=True)
def lightcuts(scene, caster, lights: dict, trees: dict, *, aperture: float = 0.0, focus_distance=None, **settings):
    """A lightcut per eye ray through every light tree (Walter et al. 2005): ``render_image``.

    Its kernels are imported on the first call, so that resolving a config stays light. A pinhole
    camera only (the plan refuses an aperture).
    """
    from lightcuts.render.integrator import render_image

    return render_image(scene, caster, lights, trees, **settings)


def _all_pairs(scene, caster, lights: dict, **settings):
    """Every gather point of every pixel with every light: ``render_multidimensional_reference``."""
    from lightcuts.render.multidim import render_multidimensional_reference

    return render_multidimensional_reference(scene, caster, lights, **settings)


@INTEGRATORS.register("multidimensional", reference=_all_pairs, lens=True, cut_unit="pairs per pixel",
                      kernels="lightcuts.render.multidim.render", forest=True, params={
    "representatives": Param(int, DEFAULT_REPRESENTATIVES, lo=1, hi=64,
                             doc="light representatives per light node (1: the tree's own only)"),
    "gather_representatives": Param(int, 1, lo=1, hi=64,
                                    doc="representative gather points per gather node (1: the gather tree's own only)")})
def multidimensional(scene, caster, lights: dict, trees: dict, **settings):
    """One cut per pixel through (gather tree) x (light trees) (Walter et al. 2006):
    ``render_multidimensional``; the result's ``cut_size`` is pairs evaluated per pixel."""
    from lightcuts.render.multidim import render_multidimensional

    return render_multidimensional(scene, caster, lights, trees, **settings)
