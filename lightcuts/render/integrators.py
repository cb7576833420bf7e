"""The render integrators (see :mod:`lightcuts.registry`): how each pixel's radiance is computed.

An entry's object is the function the render path calls,

    integrate(scene, caster, lights: dict, trees: dict, *, camera, spp, eps, max_cut, clamp,
              clamp_min_distance, envmap, seed, crop, progress, **params) -> RenderResult

with ``params`` the entry's declared parameters (as resolved from ``render.integrator``). The
config names one as ``render.integrator: NAME`` or ``{type: NAME, param: value, ...}`` (default
``lightcuts``); the plan step resolves it before any work. Adding an integrator is one
``INTEGRATORS.register(...)`` call in a module listed in ``builtins`` (or an entry point in group
``lightcuts.integrators``).

Entries: ``lightcuts``, a lightcut per eye ray through every light tree (Walter et al. 2005,
:func:`lightcuts.render.integrator.render_image`).
"""

from __future__ import annotations

from lightcuts.registry import Registry

INTEGRATORS: Registry = Registry("integrator", group="lightcuts.integrators",
                                 builtins=("lightcuts.render.integrators",))


@INTEGRATORS.register("lightcuts")
def lightcuts(scene, caster, lights: dict, trees: dict, **settings):
    """A lightcut per eye ray through every light tree (Walter et al. 2005): ``render_image``.

    Its kernels are imported on the first call, so that resolving a config stays light.
    """
    from lightcuts.render.integrator import render_image

    return render_image(scene, caster, lights, trees, **settings)
