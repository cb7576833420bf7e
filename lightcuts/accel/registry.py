"""The ray-caster registry (see :mod:`lightcuts.registry`), :func:`register_caster` and :func:`make_caster`.

A caster entry's object is a class (or factory) taking ``(vertices (V, 3), faces (F, 3), **params)``
(its declared parameters, resolved by the plan step) and returning a
:class:`~lightcuts.accel.base.RayCaster`. Traits:

- ``kernel_callable``: the caster supplies a ``kernel_caster`` whose data starts with the tag of the
  entry's ``device`` functions (lightcuts.accel.kernel_api), so numba kernels (the particle
  tracer, the renderer) can cast its rays; the plan step refuses other casters for rendering;
- ``device``: those :class:`~lightcuts.accel.kernel_api.DeviceFunctions`;
- ``warm_render_kernel``: the commands compile the render kernel for this caster in a second
  process while they build lights and trees (lightcuts.pipeline.warmup).

Outside casters register with :func:`register_caster` or through the entry-point group
``lightcuts.ray_casters`` (their object declared with :func:`lightcuts.registry.declare`, traits as above).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from lightcuts.accel.kernel_api import DeviceFunctions, register_device
from lightcuts.config.schema import DEFAULT_RAY_CASTER
from lightcuts.errors import LightcutsError
from lightcuts.registry import Entry, Param, Registry, Resolved



def _register_declared_device(name: str, obj):
    """An entry point's object declared with ``lightcuts.registry.declare(..., kernel_callable=True,
    device=DeviceFunctions(...))``: its device functions become callable from kernels."""
    device = (getattr(obj, "__lightcuts_plugin__", None) or {}).get("traits", {}).get("device")
    if isinstance(device, DeviceFunctions):
        register_device(device)
    return obj


RAY_CASTERS: Registry = Registry("ray caster", group="lightcuts.ray_casters",
                                 builtins=("lightcuts.accel.embree.embree", "lightcuts.accel.bvh.bvh_caster",
                                           "lightcuts.accel.grids.grid_caster"), coerce=_register_declared_device)


def register_caster(name: str, obj=None, *, device: DeviceFunctions | None = None,
                    params: Mapping[str, Param] | None = None, aliases: Mapping[str, Mapping] | tuple = (),
                    replace: bool = False, description: str | None = None, **traits):
    """Register the caster ``obj`` (a class or factory, see the module docstring) as ``name``, in one
    call: with ``device`` (its kernel's device functions) it is kernel-callable and the device
    functions become callable from kernels under their kernel name (shared by casters with the same
    device, as the BVH casters are). params, aliases, traits: as :meth:`Registry.register`.
    A decorator when ``obj`` is omitted."""
    if device is not None:
        if not isinstance(device, DeviceFunctions):
            raise LightcutsError(f"ray caster {name!r}: device must be a lightcuts.accel.kernel_api.DeviceFunctions")
        if traits.get("kernel_callable") is False:
            raise LightcutsError(f"ray caster {name!r}: device functions given, but kernel_callable=False")
        traits = {**traits, "kernel_callable": True, "device": device}
    elif traits.get("kernel_callable"):
        raise LightcutsError(f"ray caster {name!r}: kernel_callable needs its device functions (device=...)")

    def add(o):
        if device is not None:
            register_device(device, replace=replace)
        RAY_CASTERS.register(name, o, params=params, aliases=aliases, replace=replace, description=description,
                             **traits)
        return o

    return add if obj is None else add(obj)


def make_caster(scene, caster: str | Mapping | Entry | Resolved = DEFAULT_RAY_CASTER):
    """Build the ray caster ``caster`` over ``scene`` (a Scene, or a (vertices, faces) pair).

    caster : a :class:`Resolved` from the plan step, a name (or alias), a ``{type: NAME, param: value}``
        mapping, or an Entry (its parameters' defaults); its parameters go to the caster's factory.
    """
    if isinstance(caster, Entry):
        caster = Resolved(caster, {p: decl.default for p, decl in caster.params.items()})
    resolved = RAY_CASTERS.resolve(caster, "ray caster")
    if isinstance(scene, tuple):
        vertices, faces = scene
    else:
        vertices, faces = scene.vertices, scene.faces
    return resolved.obj(np.asarray(vertices), np.asarray(faces), **resolved.params)
