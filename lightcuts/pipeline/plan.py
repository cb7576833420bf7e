"""The plan step: every name a run uses resolved, and every combination checked, before any work.

A command loads its config, calls :func:`plan_run` and then only calls the plan's stage methods in
order (scene -> ray caster -> lights -> trees -> render); the stages receive resolved objects (the
scene type, a :class:`~lightcuts.trees.spec.TreeSpec`, the resolved caster, the integrator) and never
look a name up again. :meth:`Plan.record` gives each plugin's resolved parameters for report.json.
"""

from __future__ import annotations

from dataclasses import dataclass

from lightcuts.accel.registry import RAY_CASTERS, make_caster
from lightcuts.config import RunConfig
from lightcuts.errors import LightcutsError
from lightcuts.registry import Resolved
from lightcuts.trees.spec import TreeSpec, config_tree, tree_spec


@dataclass(frozen=True)
class Plan:
    """cfg : the validated config; tree : the resolved builder, metric and c; caster : the resolved
    ray caster (its entry and parameters); scene_type : the resolved ``scene.builtin`` /
    ``scene.procedural`` (None for mesh files alone); integrator : the resolved ``render.integrator``."""

    cfg: RunConfig
    tree: TreeSpec
    caster: Resolved
    scene_type: Resolved | None = None
    integrator: Resolved | None = None

    def record(self) -> dict:
        """Each plugin's resolved parameters, for report.json: ``{"scene": ..., "builder": ...,
        "ray_caster": ..., "integrator": ...}``, each ``{"type": NAME, param: value, ...}`` (scene None
        for meshes alone)."""
        return {"scene": self.scene_type.record() if self.scene_type is not None else None,
                "builder": self.tree.record(),
                "ray_caster": self.caster.record(),
                "integrator": self.integrator.record() if self.integrator is not None else None}

    def scene(self):
        """The Scene the config describes (built-in and/or mesh files, camera applied)."""
        from lightcuts.scene.build import scene_from_config

        return scene_from_config(self.cfg, self.scene_type)

    def make_caster(self, scene):
        """The ray caster over the scene's triangles."""
        return make_caster(scene, self.caster)

    def environment(self):
        """The environment map (loaded or generated once per run), or None."""
        from lightcuts.lights.generate import load_environment

        return load_environment(self.cfg)

    @property
    def uses_trees(self) -> bool:
        """Whether its integrator renders from the config's lights and light trees
        (:func:`uses_trees`); a render whose integrator does not makes neither."""
        from lightcuts.integrators.registry import INTEGRATORS

        integrator = self.integrator or INTEGRATORS.resolve(self.cfg.render.integrator, "render.integrator")
        return uses_trees(self.cfg, integrator)

    def lights(self, scene, caster=None, envmap=None, seed: int | None = None) -> dict:
        """Light sets by type, seeded by ``seed`` (default ``cfg.seed``); a caster is built if
        indirect lights need one."""
        from lightcuts.lights.generate import lights_from_config

        if caster is None and self.cfg.lights.indirect.count > 0:
            caster = self.make_caster(scene)
        if envmap is None:
            envmap = self.environment()
        cfg = self.cfg if seed is None else self.cfg.model_copy(update={"seed": int(seed)})
        return lights_from_config(cfg, scene, caster, envmap)

    def trees(self, light_sets: dict, seed: int | None = None) -> dict:
        """One LightTree per light type, built by the plan's builder (seed default ``cfg.seed``)."""
        from lightcuts.trees.build import build_tree

        seed = self.cfg.seed if seed is None else int(seed)
        return {typ: build_tree(ls, self.tree, seed=seed) for typ, ls in light_sets.items()}


def uses_trees(cfg, resolved) -> bool:
    """Whether the integrator ``resolved`` (a Resolved ``render.integrator``) of ``cfg`` renders from
    lights and light trees: the integrator object's ``uses_trees`` where it has one (an integrator
    whose use of trees depends on its parameters says so there), else its entry's ``forest`` trait."""
    from lightcuts.integrators.registry import make_integrator

    return bool(getattr(make_integrator(cfg, resolved), "uses_trees", resolved.trait("forest", False)))


def plan_run(cfg: RunConfig, *, render: bool = False, tree: TreeSpec | None = None) -> Plan:
    """Resolve the config's scene type, builder, metric, c, ray caster and integrator; LightcutsError
    naming the key at fault.

    render : the run renders, so the caster must be callable from the render kernels
    tree : an already resolved TreeSpec (e.g. from command-line options) instead of the config's
    """
    from lightcuts.integrators.registry import INTEGRATORS, make_integrator
    from lightcuts.scene.registry import resolve_scene

    scene_type = resolve_scene(cfg.scene)
    if cfg.scene.mitsuba is not None:
        from lightcuts.scene.mitsuba_xml import xml_settings

        cfg = xml_settings(cfg)
    if tree is None:
        tree = tree_spec(*config_tree(cfg.tree))
    lc = cfg.lights
    # The sizes the config asks for (the particle tracer lands within a few percent of its count).
    n_direct = lc.direct.count if lc.direct.source == "samples" else 0  # the scene's emitting triangles: unknown yet
    for n in (n_direct + lc.indirect.count,
              (lc.sun is not None) + (lc.environment.count if lc.environment is not None else 0)):
        tree.check_size(n)
    caster = RAY_CASTERS.resolve(cfg.render.ray_caster, "render.ray_caster")
    if render and not caster.trait("kernel_callable", False):
        usable = [e.name for e in RAY_CASTERS.entries() if e.trait("kernel_callable", False)]
        raise LightcutsError(f"render.ray_caster: {caster.name!r} cannot be called from the render kernels; "
                             f"use one of {', '.join(usable)}")
    if render:
        check_work(cfg, scene_type)
    integrator = INTEGRATORS.resolve(cfg.render.integrator, "render.integrator")
    if cfg.camera.aperture > 0 and not integrator.trait("lens", False):
        lens = [e.name for e in INTEGRATORS.entries() if e.trait("lens", False)]
        raise LightcutsError(f"camera.aperture: integrator {integrator.name!r} renders a pinhole camera only; "
                             f"use render.integrator: {' or '.join(lens)} for depth of field")
    if lc.direct.source == "triangles" and not integrator.trait("triangle_lights", False):
        users = [e.name for e in INTEGRATORS.entries() if e.trait("triangle_lights", False)]
        raise LightcutsError(f"lights.direct.source: integrator {integrator.name!r} renders point lights only; "
                             f"use render.integrator: {' or '.join(users)} for triangle lights")
    r = cfg.render
    if r.continuation_rays > 1 and not r.compensation:
        raise LightcutsError(f"render.continuation_rays: {r.continuation_rays} continuations per eye ray need "
                             "render.compensation: true")
    for key, asked in (("compensation", r.compensation), ("representatives", r.representatives == "stochastic")):
        if asked and not integrator.trait("converging", False):
            converging = [e.name for e in INTEGRATORS.entries() if e.trait("converging", False)]
            raise LightcutsError(f"render.{key}: integrator {integrator.name!r} does not support it; "
                                 f"use render.integrator: {' or '.join(converging)}")
    if render:
        make_integrator(cfg, integrator)  # the integrator checks the settings it takes
    return Plan(cfg, tree, caster, scene_type, integrator)


def check_work(cfg: RunConfig, scene_type: Resolved | None) -> int:
    """The eye rays the config's render traces, pixels (of ``render.crop``, checked against the
    image) x spp x passes (x continuation_rays with compensation); LightcutsError naming the
    ``render`` keys if they are more than MAX_EYE_RAYS."""
    from types import SimpleNamespace

    from lightcuts.limits import MAX_EYE_RAYS
    from lightcuts.integrators.camera import check_crop
    from lightcuts.scene.build import image_size

    width, height = image_size(cfg, scene_type)
    x0, y0, x1, y1 = check_crop(cfg.render.crop, SimpleNamespace(width=width, height=height))
    r = cfg.render
    pixels = (x1 - x0) * (y1 - y0)
    continuations = r.continuation_rays if r.compensation else 1
    rays = pixels * r.spp * r.passes * continuations
    if rays > MAX_EYE_RAYS:
        per = f" x {continuations} continuation_rays" if continuations > 1 else ""
        raise LightcutsError(f"render: {pixels:,} pixels x {r.spp} spp x {r.passes} passes{per} = {rays:,} eye rays, "
                             f"more than {MAX_EYE_RAYS:,} (lightcuts.limits.MAX_EYE_RAYS); lower render.spp, "
                             "render.passes or the resolution")
    return rays


def tree_meta(trees: dict) -> dict:
    """What the trees were built with, from their meta: builder, metric and c (None where not read)."""
    first = next(iter(trees.values()))
    return {"builder": first.meta.get("builder"), "metric": first.meta.get("metric"),
            "c": {typ: (float(t.meta["c"]) if "c" in t.meta else None) for typ, t in trees.items()}}
