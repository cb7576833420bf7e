"""The reference renderers (see :mod:`lightcuts.registry`): the path tracers a run is measured
against by ``lightcuts reference`` (``--renderer NAME``) and its ``--curve`` / ``--split`` studies.

An entry is a :class:`ReferenceRenderer` subclass; an instance renders runs:
``render(cfg, scene, envmap, spp, seed, integrator) -> (image, seconds)`` (seconds: the render
alone), ``seconds_per_spp`` (timing runs), ``prepare`` (the command's renders, with its
``--max-depth``), ``describe()`` (its name and version for report.json) and ``close()``. It
declares (:func:`lightcuts.registry.declare`) what differs between renderers as traits, which the
command and the studies check instead of its name:

* ``exact_materials``: True if it evaluates lightcuts' own BRDF; False if Phong lobes are a
  stand-in (report.json's ``phong_approximated``)
* ``light_types``: what it renders of a config's lights: ``emitters`` (emitting triangles),
  ``sun``, ``environment``
* ``lens``: it renders a thin lens (``camera.aperture > 0``)
* ``integrators``: its ``--integrator`` choices (``path``, ``direct``)
* ``max_depth``: it takes ``--max-depth`` (else it follows every bounce)
* ``sampler``: how its samples per pixel are placed (one line for listings)

Entries: ``lightcuts``, this project's ``path`` integrator (lightcuts.integrators.path) at high sample
counts, and ``mitsuba``, Mitsuba 3 (lightcuts.mitsuba.reference, the optional extra). Outside
packages add one through the entry-point group ``lightcuts.references``.
"""

from __future__ import annotations

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.registry import Registry, declaration, declare

REFERENCES: Registry = Registry("reference renderer", group="lightcuts.references",
                                builtins=("lightcuts.integrators.references", "lightcuts.mitsuba.reference"))
#: ``--renderer``'s default.
DEFAULT_REFERENCE = "mitsuba"
#: Every trait an entry declares (the plan reads them all).
TRAITS = ("exact_materials", "light_types", "lens", "integrators", "max_depth", "sampler")
#: A light type as the messages name it.
_LIGHT_NAMES = {"emitters": "emitting triangles", "sun": "the sun", "environment": "the environment"}


def make_reference(name: str) -> "ReferenceRenderer":
    """The reference renderer registered as ``name``; LightcutsError ``--renderer: ...`` listing the
    names for an unknown one."""
    try:
        entry = REFERENCES.entry(name)
    except LightcutsError as exc:
        raise LightcutsError(f"--renderer: {exc}") from None
    return entry.obj(entry.name)


class ReferenceRenderer:
    """A reference renderer (module docstring). ``name``: its registry name; ``label``: its rows'
    "method" in a curve; ``file``: the stem of its image files; ``title``: its name in messages;
    ``report_key``: a second report.json key its description is also written under (or None)."""

    label = "reference"
    file = "reference"
    title = "path tracer"
    report_key = None

    def __init__(self, name: str):
        self.name = name
        self._casters = {}

    def trait(self, key: str, default=None):
        return declaration(type(self)).get("traits", {}).get(key, default)

    def check(self, cfg, integrator: str = "path") -> None:
        """LightcutsError (before any work) if this renderer cannot render the run: an integrator it
        does not offer, a light type it does not render or a lens without the ``lens`` trait."""
        types = self.trait("light_types", ())
        why = (f"--integrator {integrator}" if integrator not in self.trait("integrators", ())
               else "lights.sun" if cfg.lights.sun is not None and "sun" not in types
               else "lights.environment" if cfg.lights.environment is not None and "environment" not in types
               else "camera.aperture" if cfg.camera.aperture > 0 and not self.trait("lens") else None)
        if why is None:
            return
        able = [e.name for e in REFERENCES.entries() if _renders(e.trait, why, integrator)]
        lights = " and ".join(_LIGHT_NAMES[t] for t in types)
        raise LightcutsError(f"--renderer {self.name}: its path tracer renders {lights} through "
                             f"{'a thin lens' if self.trait('lens') else 'a pinhole'}"
                             f"{'' if self.trait('max_depth') else ', with every bounce'}; {why} needs "
                             f"--renderer {' or '.join(able) or '(none registered)'}")

    def describe(self) -> dict:
        """{"renderer": name, "version", ...} for report.json."""
        raise NotImplementedError

    def render(self, cfg, scene, envmap, spp: int, seed: int, integrator: str = "path") -> tuple[np.ndarray, float]:
        """((H, W, 3) float32 linear RGB of the config's pixels, render seconds) at ``spp``."""
        raise NotImplementedError

    def prepare(self, cfg, scene, envmap, spp: int, integrator: str = "path", max_depth: int = -1):
        """The command's renders at about ``spp`` samples per pixel: ``(render, spp taken, load
        seconds)``, ``render(seed) -> (image, render seconds)`` (the command renders two independent
        halves with it)."""
        return (lambda seed: self.render(cfg, scene, envmap, spp, seed, integrator)), spp, 0.0

    def warm(self, cfg, scene, envmap) -> None:
        """Load what its first render would (e.g. numba kernels) before timing runs."""

    def seconds_per_spp(self, cfg, scene, envmap, min_seconds: float = 1.0) -> float:
        """Render seconds per sample per pixel, from timing runs of doubling spp until one takes
        ``min_seconds`` (a short run's fixed costs would overstate it)."""
        self.warm(cfg, scene, envmap)
        spp = 4
        while True:
            _, t = self.render(cfg, scene, envmap, spp, 0)
            if t >= min_seconds or spp >= 1 << 16:
                return max(t / spp, 1e-9)
            spp *= 2

    def close(self) -> None:
        for _, caster in self._casters.values():
            caster.close()
        self._casters.clear()


def _renders(trait, why: str, integrator: str) -> bool:
    """Whether an entry with these traits renders what ``why`` (a check's reason) names."""
    if why.startswith("--integrator"):
        return integrator in trait("integrators", ())
    if why == "camera.aperture":
        return bool(trait("lens"))
    return why.split(".")[1] in trait("light_types", ())


def _names_path(cfg) -> bool:
    """Whether the config's ``render.integrator`` is the path integrator."""
    spec = cfg.render.integrator
    return (spec if isinstance(spec, str) else spec["type"]) == "path"


@REFERENCES.register("lightcuts")
@declare(exact_materials=True, light_types=("emitters",), lens=False, integrators=("path",), max_depth=False,
         sampler="stratified jittered eye rays (lightcuts.integrators.camera)")
class PathReference(ReferenceRenderer):
    """This project's path integrator (lightcuts.integrators.path) at the reference's sample count: the
    exact BRDF, emitting triangles only, through a pinhole, every bounce. Its next-event estimation
    draws emitters by power, or as the config's own ``render.integrator`` does when that is ``path``
    with another ``light_sampler`` (a tree of ``tree.builder``: the reference of a scene with many
    emitters converges faster)."""

    label = "lightcuts-path"
    file = "path"

    def describe(self) -> dict:
        from lightcuts import __version__

        return {"renderer": self.name, "version": __version__, "variant": "lightcuts.integrators.path"}

    def render(self, cfg, scene, envmap, spp: int, seed: int, integrator: str = "path") -> tuple[np.ndarray, float]:
        from lightcuts.accel import make_caster
        from lightcuts.integrators.path import Path, path_trace
        from lightcuts.integrators.registry import make_integrator

        if id(scene) not in self._casters:
            self._casters[id(scene)] = (scene, make_caster(scene))
        own = make_integrator(cfg) if _names_path(cfg) else None
        sampler = {"light_sampler": own.light_sampler, "tree": own.tree} if isinstance(own, Path) else {}
        return path_trace(scene, self._casters[id(scene)][1], spp=spp, seed=seed, crop=cfg.render.crop, **sampler)

    def warm(self, cfg, scene, envmap) -> None:
        self.render(cfg, scene, envmap, 1, 0)  # numba loads (or compiles) the kernel
