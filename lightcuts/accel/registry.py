"""The ray-caster registry (see :mod:`lightcuts.registry`) and :func:`make_caster`.

A caster entry's object is a class (or factory) taking ``(vertices (V, 3), faces (F, 3))`` and
returning a :class:`~lightcuts.accel.base.RayCaster`. Its trait ``kernel_callable`` says that the
caster supplies a ``kernel_caster`` (device functions registered in lightcuts.accel.kernel_api), so
numba kernels (the particle tracer, the renderer) can cast its rays; the plan step refuses other
casters for rendering. Outside casters register through the entry-point group
``lightcuts.ray_casters``.
"""

from __future__ import annotations

import numpy as np

from lightcuts.config.schema import DEFAULT_RAY_CASTER
from lightcuts.registry import Entry, Registry

RAY_CASTERS: Registry = Registry("ray caster", group="lightcuts.ray_casters", builtins=("lightcuts.accel.embree",
                                                                              "lightcuts.accel.bvh_caster",
                                                                              "lightcuts.accel.grid_caster"))


def make_caster(scene, caster: str | Entry = DEFAULT_RAY_CASTER):
    """Build the ray caster ``caster`` (an entry from the plan step, or a name) over ``scene``
    (a Scene, or a (vertices, faces) pair)."""
    entry = caster if isinstance(caster, Entry) else RAY_CASTERS.entry(caster)
    if isinstance(scene, tuple):
        vertices, faces = scene
    else:
        vertices, faces = scene.vertices, scene.faces
    return entry.obj(np.asarray(vertices), np.asarray(faces))
