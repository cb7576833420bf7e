"""The scene types (see :mod:`lightcuts.registry`): the built-in Cornell box and the generated
kitchen, building of rooms, gallery, city and office, each registered beside its code with the
parameters it reads.

A config names a built-in type as ``scene.builtin: NAME`` and a generated one as ``scene.procedural:
NAME`` or ``{type: NAME, param: value, ...}``; :func:`resolve_scene` resolves either in the plan
step. An entry's object is a factory

    make(params: dict, materials: dict | None, exhibits: list[Scene], offsets: list, name: str) -> Scene

returning the scene with its default camera (``materials``: overrides by surface name; ``exhibits``
and ``offsets``: the config's meshes and their translates, for types with the ``exhibits`` trait).
Traits: ``builtin`` (named by ``scene.builtin``), ``resolution`` (the default camera's (width,
height), pixels, known without building the scene), ``exhibits`` (takes ``scene.meshes``, at least
one). Every choice a type makes is seeded by its ``seed`` parameter (not the run's), so a config
gives the same bytes of ``Scene.save`` every time.

Outside packages add scene types through the entry-point group ``lightcuts.scenes``.
"""

from __future__ import annotations

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_EMITTER_TRIANGLES, MAX_SEED
from lightcuts.registry import Param, Registry, Resolved

MAX_PROCEDURAL_TRIANGLES = 4_000_000
MAX_ROOMS = 16
#: The fewest emitting triangles a many-emitter type (city, office) is asked for.
MIN_EMITTERS = 1000

SCENES: Registry = Registry(
    "scene type", group="lightcuts.scenes",
    builtins=("lightcuts.scene.cornell", "lightcuts.scene.kitchen", "lightcuts.scene.rooms",
              "lightcuts.scene.gallery", "lightcuts.scene.city", "lightcuts.scene.office"))

#: The geometry's seed, apart from the run's ``seed`` so the scene stays when that changes.
SEED = Param(int, 0, lo=0, hi=MAX_SEED, doc="the geometry's seed (the run's seed drives the lights)")


def triangles(default: int, doc: str = "the triangle count, hit within a few percent") -> Param:
    """The ``triangles`` parameter of a generated type, 10,000 to MAX_PROCEDURAL_TRIANGLES."""
    return Param(int, default, lo=10_000, hi=MAX_PROCEDURAL_TRIANGLES, doc=doc)


def emitters(default: int) -> Param:
    """The ``emitters`` parameter of a many-emitter type: its emitting triangles, MIN_EMITTERS to
    MAX_EMITTER_TRIANGLES (lightcuts.limits)."""
    return Param(int, default, lo=MIN_EMITTERS, hi=MAX_EMITTER_TRIANGLES,
                 doc="the emitting triangles, hit within 1% (the scene grows its lights to meet it)")


def resolve_scene(sc, *, has_meshes: bool | None = None) -> Resolved | None:
    """The scene type a config's ``scene`` section names (``builtin`` or ``procedural``), resolved
    with its parameters; None for mesh files alone. LightcutsError naming ``scene.builtin`` or
    ``scene.procedural[.<param>]`` for an unknown type, one of the other kind, an undeclared or bad
    parameter, or an ``exhibits`` type without meshes.

    sc : :class:`~lightcuts.config.schema.SceneConfig` (or a Resolved, returned as is)
    """
    if isinstance(sc, Resolved):
        return sc
    if sc.builtin is not None:
        spec, key, builtin = sc.builtin, "scene.builtin", True
    elif sc.procedural is not None:
        spec, key, builtin = sc.procedural, "scene.procedural", False
    else:
        return None
    name = spec.get("type") if isinstance(spec, dict) else spec
    valid = [e.name for e in SCENES.entries() if bool(e.trait("builtin")) == builtin]
    if name not in SCENES or SCENES.entry(name).name not in valid:
        other = "scene.procedural" if builtin else "scene.builtin"
        hint = f" ({other} names it)" if name in SCENES else ""
        raise LightcutsError(f"{key}{'' if builtin else '.type'}: unknown {'built-in' if builtin else 'procedural'} "
                             f"scene {name!r}{hint}; valid: {', '.join(valid)}")
    resolved = SCENES.resolve(spec, key)
    meshes = bool(sc.meshes) if has_meshes is None else has_meshes
    if resolved.trait("exhibits") and not meshes:
        raise LightcutsError(f"{key}: type {resolved.name} needs scene.meshes (the exhibits)")
    return resolved


def make_scene(spec, materials=None, exhibits=(), offsets=(), name: str = "scene", key: str = "scene.procedural"):
    """The scene a type builds: ``spec`` a name, ``{type: NAME, ...}`` mapping or Resolved."""
    resolved = SCENES.resolve(spec, key)
    return resolved.obj(dict(resolved.params), materials, list(exhibits), list(offsets), name)
