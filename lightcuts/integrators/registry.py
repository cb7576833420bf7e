r"""The render integrators (see :mod:`lightcuts.registry`): how each pixel's radiance is computed.

An integrator is an object built once from its settings (Mitsuba's plugin shape): the constructor
takes the config's render settings and the entry's own parameters and checks them (one-line
LightcutsError naming the config key), and :meth:`Integrator.render` renders a window of the image
(a crop window or a pixel list) from the scene, the ray caster, the lights and trees (or their light
forest, or whatever else it makes once per render for many windows: :meth:`Integrator.forest`, which
a cluster's worker makes once for all its tiles) and the per-run inputs (camera,
environment map, seed, progress). :meth:`Integrator.reference` is its brute-force counterpart over
the same samples, against which its errors are measured. Every integrator renders through the one
image driver (lightcuts.integrators.driver), supplying its band kernel call (:meth:`Integrator.band_kernel`).

The registry's entries are the integrator classes, each beside its kernels (its module, listed in
``builtins``, registers it when imported). The config names one as ``render.integrator: NAME`` or
``{type: NAME, param: value, ...}`` (default ``lightcuts``); the plan step resolves it and builds it
(:func:`make_integrator`) before any work, and the commands build it the same way. A class declares
(:func:`lightcuts.registry.declare`) its own parameters and its traits: ``cut_unit`` (what its cut
sizes count, as report.json names it), ``cuts_per`` (for integrators that cut light trees: what
one cut serves, ``eye ray`` or ``pixel``; ``lightcuts scaling --gather`` compares one of each), ``lens`` (it renders a thin lens: the plan refuses
``camera.aperture > 0`` otherwise), ``converging`` (it takes ``render.compensation``,
``render.representatives`` and ``render.continuation_rays``; the plan refuses them otherwise),
``reference`` (it has a brute-force reference: ``--reference`` and compare's errors), ``forest`` (it
renders from the light forest of the lights and trees, :meth:`Integrator.forest`, which a cluster's
worker makes once for all its tiles; compare, whose rows differ by their trees, refuses an
integrator without it), ``triangle_lights`` (it renders the emitting triangles that
``lights.direct.source: triangles`` makes the direct lights; the plan refuses that source otherwise)
and ``kernels``: the module whose ``_render_band`` kernel its renders use and
whose ``warm_kernels()`` compiles it, which the commands compile in a second process while the
lights and trees are made (lightcuts.pipeline.warmup). Adding an integrator is a subclass of
:class:`Integrator` registered with ``INTEGRATORS.register`` (or an entry point in group
``lightcuts.integrators`` naming the class).

Entries: ``lightcuts``, a lightcut per eye ray through every light tree (Walter et al. 2005,
lightcuts.integrators.lightcut); ``multidimensional``, one cut per pixel through the product of a gather
tree over the pixel's eye-ray hits and the light trees (Walter et al. 2006,
lightcuts.integrators.multidim); ``path``, a path tracer with lightcuts' own BRDF over the scene's
emitting triangles (lightcuts.integrators.path), which uses none of the config's lights or trees
(with ``light_sampler: tree``, a tree of its own over the emitting triangles); ``stochastic-lightcuts``,
a cut by importance per eye ray and one light drawn below each cut node (Yuksel 2019,
lightcuts.integrators.stochastic).
"""

from __future__ import annotations

import math

from lightcuts.config.schema import DEFAULT_CLAMP_VPLS, LIT_AREA_SHARES
from lightcuts.errors import LightcutsError
from lightcuts.registry import Registry, declaration
from lightcuts.integrators import MAX_CUT

INTEGRATORS: Registry = Registry("integrator", group="lightcuts.integrators",
                                 builtins=("lightcuts.integrators.lightcut", "lightcuts.integrators.multidim.render",
                                           "lightcuts.integrators.path", "lightcuts.integrators.stochastic"))


def check_count(value, key: str, hi: int | None = None) -> int:
    """``value`` as an int from 1 (to ``hi``); LightcutsError naming the config key ``key`` otherwise."""
    if isinstance(value, bool) or int(value) != value or value < 1 or (hi is not None and value > hi):
        raise LightcutsError(f"{key}: {value} must be " + (f"an integer from 1 to {hi}" if hi is not None
                                                           else "a positive integer"))
    return int(value)


def check_non_negative(value, key: str) -> float:
    """``value`` as a finite float >= 0; LightcutsError naming the config key ``key`` otherwise."""
    if not (value >= 0 and math.isfinite(value)):
        raise LightcutsError(f"{key}: {value} must be a finite number >= 0")
    return float(value)


class Integrator:
    """An integrator (module docstring): its settings, checked when made, and its render.

    spp : eye rays per pixel (stratified, jittered: lightcuts.integrators.camera). ``eps``, ``max_cut``
    (the bound of a pixel's cut per eye ray, in its ``cut_unit``) and ``brute_force`` (it is a
    reference) are what its RenderResults record; ``clamp``: it clamps indirect VPLs (report.json's
    ``clamping.enabled``).
    """

    eps = 0.0
    max_cut = 0
    brute_force = False
    clamp = False

    def __init__(self, *, spp: int = 1):
        self.spp = check_count(spp, "render.spp")

    @classmethod
    def settings(cls, cfg) -> dict:
        """The constructor's keyword arguments that the config ``cfg`` sets (not the entry's own
        parameters); LightcutsError naming the key if the config asks for something it cannot do."""
        return {"spp": cfg.render.spp}

    @classmethod
    def from_config(cls, cfg, **params) -> "Integrator":
        """The integrator of ``cfg``'s settings and the entry's resolved parameters ``params``."""
        return cls(**cls.settings(cfg), **params)

    def param(self, name: str, value):
        """``value`` of the entry's own parameter ``name`` checked against its declared Param (key
        ``render.integrator.<name>``)."""
        return declaration(type(self))["params"][name].check(value, f"render.integrator.{name}")

    def clamp_radius(self, scene, forest) -> float:
        """The radius within which indirect VPLs are clamped, world units (0: none)."""
        return 0.0

    def forest(self, lights: dict, trees: dict | None, scene):
        """What its renders of ``scene`` take, made once for many windows (a cluster's worker keeps it
        for all its tiles): the light forest (lightcuts.integrators.forest.build_forest of the lights
        and trees; a reference's of the lights alone), or the integrator's own per-run data.
        LightcutsError for a set of triangle lights (``lights.direct.source: triangles``): the
        forest's lights are points."""
        from lightcuts.integrators.forest import build_forest
        from lightcuts.lights.triangles import leading_triangles

        if any(leading_triangles(ls) for ls in lights.values()):
            raise LightcutsError(f"lights.direct.source: integrator {type(self).__name__} renders point lights "
                                 f"only, not the emitting triangles")
        return build_forest(lights, None if self.brute_force else trees)

    def sampler_record(self, forest) -> dict:
        """How its renders from ``forest`` draw lights, for report.json's ``light_sampler`` ({}: it draws
        none)."""
        return {}

    def reference(self) -> "Integrator":
        """The brute-force integrator over the same samples (its errors are measured against it)."""
        raise LightcutsError(f"render.integrator: {type(self).__name__} has no brute-force reference")

    def band_kernel(self, frame):
        """Its band kernel call (lightcuts.integrators.driver.Band) for the driver's ``frame``
        (lightcuts.integrators.driver.Frame)."""
        raise NotImplementedError

    def render(self, scene, caster, lights: dict, trees: dict | None = None, *, forest=None, camera=None,
               envmap=None, seed: int = 0, crop=None, pixels=None, progress=None):
        """Render the window ``crop`` of the image (or the pixels ``pixels``): a
        lightcuts.integrators.driver.RenderResult.

        scene : lightcuts.scene.Scene; caster : a kernel-callable ray caster over it (open during the
        call); lights : {type: LightSet}; trees : {type: LightTree}, one per light set (unused by a
        reference); forest : :meth:`forest` of those, made once for several calls (e.g. the tiles of
        one image), None: made here; camera : lightcuts.scene.Camera (default ``scene.camera``);
        envmap : lightcuts.lights.environment.EnvironmentMap seen by eye rays that miss, or None
        (black); seed : the eye rays' seed (and the stochastic choices'); crop : (x0, y0, x1, y1)
        pixels of the image, or None (all); pixels : (K, 2) int (x, y) to render instead of a window
        (the result's arrays are then (K, 1, ...), with the values of those pixels in a whole-image
        render); progress : called with the number of rows finished after each band.
        LightcutsError naming the key for bad inputs.
        """
        from lightcuts.integrators.driver import render_window

        return render_window(self, scene, caster, lights, trees, forest=forest, camera=camera, envmap=envmap,
                             seed=seed, crop=crop, pixels=pixels, progress=progress)


class CutIntegrator(Integrator):
    """An integrator that cuts light trees: eps : relative error threshold of a cut (0: refine until
    every node is exact); max_cut : largest cut per eye ray (1 to MAX_CUT); clamp : clamping of
    indirect VPLs at the radius :meth:`clamp_radius`, from the VPLs' density (``clamp_vpls``: the
    VPLs its disc holds) or, with ``clamp_min_distance`` given, ``clamp_min_distance * scene
    diagonal``; visibility : False casts no shadow rays (every light visible: unshadowed images, and
    the cost of the cut without the caster's share, benchmarks/bench_render.py)."""

    def __init__(self, *, spp: int = 1, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_vpls: float = DEFAULT_CLAMP_VPLS, clamp_min_distance: float | None = None,
                 visibility: bool = True):
        super().__init__(spp=spp)
        self.eps = check_non_negative(eps, "render.eps")
        self.max_cut = check_count(max_cut, "render.max_cut", MAX_CUT)
        self.clamp = bool(clamp)
        self.clamp_vpls = check_non_negative(clamp_vpls, "render.clamp.vpls")
        self.clamp_min_distance = None if clamp_min_distance is None else \
            check_non_negative(clamp_min_distance, "render.clamp.min_distance")
        self.visibility = bool(visibility)

    @classmethod
    def settings(cls, cfg) -> dict:
        r, c = cfg.render, cfg.render.clamp
        return {**super().settings(cfg), "eps": r.eps, "max_cut": r.max_cut, "clamp": c.enabled,
                "clamp_vpls": c.vpls, "clamp_min_distance": c.min_distance if c.mode == "diagonal" else None}

    def clamp_settings(self) -> dict:
        """The clamp keyword arguments of the constructor, for a counterpart (e.g. :meth:`reference`)."""
        return {"clamp": self.clamp, "clamp_vpls": self.clamp_vpls, "clamp_min_distance": self.clamp_min_distance}

    def clamp_radius(self, scene, forest) -> float:
        """The clamping radius of indirect VPLs in the scene, world units (:func:`clamp_radius`)."""
        return clamp_radius(self.clamp, self.clamp_vpls, self.clamp_min_distance, scene, forest)

    def clamp_d2(self, scene, forest) -> float:
        """The squared clamping radius (:meth:`clamp_radius`)."""
        return self.clamp_radius(scene, forest) ** 2


def clamp_radius(clamp: bool, clamp_vpls: float, clamp_min_distance: float | None, scene, forest) -> float:
    """The clamping radius of indirect VPLs in the scene, world units (0: no clamping):
    ``sqrt(min(clamp_vpls, N / LIT_AREA_SHARES)) * forest.vpl_spacing`` for the forest's N indirect
    VPLs (the radius of a disc holding about ``clamp_vpls`` VPLs, and at most 1 / LIT_AREA_SHARES
    of them; docs/math.md, "Clamping"), or ``clamp_min_distance * scene.diagonal`` when that is set."""
    if not clamp:
        return 0.0
    if clamp_min_distance is not None:
        return float(clamp_min_distance * scene.diagonal)
    if forest is None:
        return 0.0
    return float(math.sqrt(min(clamp_vpls, forest.vpl_count / LIT_AREA_SHARES)) * forest.vpl_spacing)


def make_integrator(cfg, integrator=None) -> Integrator:
    """The integrator of the run ``cfg`` (a RunConfig): the entry ``integrator`` (a Resolved, e.g. the
    plan's, or a spec; None: ``cfg.render.integrator``) built from the config's settings and its
    resolved parameters. LightcutsError with one line naming the config key."""
    resolved = INTEGRATORS.resolve(cfg.render.integrator if integrator is None else integrator, "render.integrator")
    return resolved.obj.from_config(cfg, **resolved.params)
