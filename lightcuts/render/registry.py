r"""The render integrators (see :mod:`lightcuts.registry`): how each pixel's radiance is computed.

An integrator is an object built once from its settings (Mitsuba's plugin shape): the constructor
takes the config's render settings and the entry's own parameters and checks them (one-line
LightcutsError naming the config key), and :meth:`Integrator.render` renders a window of the image
(a crop window or a pixel list) from the scene, the ray caster, the lights and trees (or their light
forest, made once for many windows: :meth:`Integrator.forest`) and the per-run inputs (camera,
environment map, seed, progress). :meth:`Integrator.reference` is its brute-force counterpart over
the same samples, against which its errors are measured. Every integrator renders through the one
image driver (lightcuts.render.driver), supplying its band kernel call (:meth:`Integrator.band_kernel`).

The registry's entries are the integrator classes. The config names one as ``render.integrator:
NAME`` or ``{type: NAME, param: value, ...}`` (default ``lightcuts``); the plan step resolves it and
builds it (:func:`make_integrator`) before any work, and the commands build it the same way. A class
declares (:func:`lightcuts.registry.declare`) its own parameters and its traits: ``cut_unit`` (what
its cut sizes count, as report.json names it), ``lens`` (it renders a thin lens: the plan refuses
``camera.aperture > 0`` otherwise), ``converging`` (it takes ``render.compensation``,
``render.representatives`` and ``render.continuation_rays``; the plan refuses them otherwise),
``reference`` (it has a brute-force reference: ``--reference`` and compare's errors), ``forest`` (it
renders from the light forest of the lights and trees; without it the run builds no trees) and
``kernels``: the module whose ``_render_band`` kernel its renders use and whose ``warm_kernels()``
compiles it, which the commands compile in a second process while the lights and trees are made
(lightcuts.commands.warmup). The kernels are imported on the first render, so that resolving a
config stays light. Adding an integrator is a subclass registered with ``INTEGRATORS.register`` in a
module listed in ``builtins`` (or an entry point in group ``lightcuts.integrators``).

Entries: ``lightcuts``, a lightcut per eye ray through every light tree (Walter et al. 2005,
lightcuts.render.lightcut); ``multidimensional``, one cut per pixel through the product of a gather
tree over the pixel's eye-ray hits and the light trees (Walter et al. 2006,
lightcuts.render.multidim); ``path``, a path tracer with lightcuts' own BRDF over the scene's
emitting triangles (lightcuts.render.path), which uses no lights or trees.
"""

from __future__ import annotations

import math

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_CONTINUATION_RAYS
from lightcuts.registry import Param, Registry, declaration, declare
from lightcuts.render import DEFAULT_REPRESENTATIVES, MAX_CUT, MAX_PATH_VERTICES

INTEGRATORS: Registry = Registry("integrator", group="lightcuts.integrators",
                                 builtins=("lightcuts.render.registry",))


def _positive_int(value, key: str, hi: int | None = None) -> int:
    if isinstance(value, bool) or int(value) != value or value < 1 or (hi is not None and value > hi):
        raise LightcutsError(f"{key}: {value} must be " + (f"an integer from 1 to {hi}" if hi is not None
                                                           else "a positive integer"))
    return int(value)


def _non_negative(value, key: str) -> float:
    if not (value >= 0 and math.isfinite(value)):
        raise LightcutsError(f"{key}: {value} must be a finite number >= 0")
    return float(value)


class Integrator:
    """An integrator (module docstring): its settings, checked when made, and its render.

    spp : eye rays per pixel (stratified, jittered: lightcuts.render.camera). ``eps``, ``max_cut``
    (the bound of a pixel's cut per eye ray, in its ``cut_unit``) and ``brute_force`` (it is a
    reference) are what its RenderResults record.
    """

    eps = 0.0
    max_cut = 0
    brute_force = False

    def __init__(self, *, spp: int = 1):
        self.spp = _positive_int(spp, "render.spp")

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

    def forest(self, lights: dict, trees: dict | None):
        """The light forest its renders take (lightcuts.render.forest.build_forest of the lights and
        trees; a reference's of the lights alone), or None if it uses none."""
        from lightcuts.render.forest import build_forest

        return build_forest(lights, None if self.brute_force else trees)

    def reference(self) -> "Integrator":
        """The brute-force integrator over the same samples (its errors are measured against it)."""
        raise LightcutsError(f"render.integrator: {type(self).__name__} has no brute-force reference")

    def band_kernel(self, frame):
        """Its band kernel call (lightcuts.render.driver.Band) for the driver's ``frame``
        (lightcuts.render.driver.Frame)."""
        raise NotImplementedError

    def render(self, scene, caster, lights: dict, trees: dict | None = None, *, forest=None, camera=None,
               envmap=None, seed: int = 0, crop=None, pixels=None, progress=None):
        """Render the window ``crop`` of the image (or the pixels ``pixels``): a
        lightcuts.render.driver.RenderResult.

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
        from lightcuts.render.driver import render_window

        return render_window(self, scene, caster, lights, trees, forest=forest, camera=camera, envmap=envmap,
                             seed=seed, crop=crop, pixels=pixels, progress=progress)


class CutIntegrator(Integrator):
    """An integrator that cuts light trees: eps : relative error threshold of a cut (0: refine until
    every node is exact); max_cut : largest cut per eye ray (1 to MAX_CUT); clamp,
    clamp_min_distance : clamping of indirect VPLs at ``clamp_min_distance * scene diagonal``;
    visibility : False casts no shadow rays (every light visible: unshadowed images, and the cost of
    the cut without the caster's share, benchmarks/bench_render.py)."""

    def __init__(self, *, spp: int = 1, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_min_distance: float = 0.05, visibility: bool = True):
        super().__init__(spp=spp)
        self.eps = _non_negative(eps, "render.eps")
        self.max_cut = _positive_int(max_cut, "render.max_cut", MAX_CUT)
        self.clamp = bool(clamp)
        self.clamp_min_distance = _non_negative(clamp_min_distance, "render.clamp.min_distance")
        self.visibility = bool(visibility)

    @classmethod
    def settings(cls, cfg) -> dict:
        r = cfg.render
        return {**super().settings(cfg), "eps": r.eps, "max_cut": r.max_cut, "clamp": r.clamp.enabled,
                "clamp_min_distance": r.clamp.min_distance}

    def clamp_d2(self, scene) -> float:
        """The squared clamping distance in the scene (0: no clamping)."""
        return float((self.clamp_min_distance * scene.diagonal) ** 2 if self.clamp else 0.0)


@INTEGRATORS.register("lightcuts")
@declare(lens=False, cut_unit="light nodes per eye ray", kernels="lightcuts.render.lightcut", converging=True,
         reference=True, forest=True)
class Lightcuts(CutIntegrator):
    """A lightcut per eye ray through every light tree (Walter et al. 2005): lightcuts.render.lightcut.

    Settings as :class:`CutIntegrator`, plus compensation : add the light the VPLs lose to clamping
    and to glossy surfaces by a continuation of the eye path (lightcuts.render.continuation; the
    VPLs must come from glossy particle paths), whose rays count as shadow rays; representatives :
    ``fixed`` (the trees') or ``stochastic`` (one light drawn per cut node and eye ray,
    lightcuts.render.cut.stochastic_estimate); continuation_rays : with compensation, the
    continuations averaged per eye ray (1 to MAX_CONTINUATION_RAYS); all_lights : the brute-force
    reference instead (every light at every hit, one shadow ray each, no trees). A pinhole camera
    only (the plan refuses an aperture).
    """

    def __init__(self, *, spp: int = 1, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_min_distance: float = 0.05, visibility: bool = True, compensation: bool = False,
                 representatives: str = "fixed", continuation_rays: int = 1, all_lights: bool = False):
        super().__init__(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_min_distance=clamp_min_distance,
                         visibility=visibility)
        self.continuation_rays = _positive_int(continuation_rays, "render.continuation_rays", MAX_CONTINUATION_RAYS)
        if representatives not in ("fixed", "stochastic"):
            raise LightcutsError(f"render.representatives: {representatives!r} must be 'fixed' or 'stochastic'")
        self.compensation = bool(compensation)
        self.representatives = representatives
        self.brute_force = bool(all_lights)

    @classmethod
    def settings(cls, cfg) -> dict:
        r = cfg.render
        return {**super().settings(cfg), "compensation": r.compensation, "representatives": r.representatives,
                "continuation_rays": r.continuation_rays}

    def reference(self) -> "Lightcuts":
        """Every light at every eye ray's hit, the same eye rays and shading (no trees, eps 0, no
        compensation)."""
        return Lightcuts(spp=self.spp, eps=0.0, max_cut=1, clamp=self.clamp,
                         clamp_min_distance=self.clamp_min_distance, visibility=self.visibility, all_lights=True)

    def band_kernel(self, frame):
        from lightcuts.render.lightcut import band_kernel

        return band_kernel(self, frame)


@INTEGRATORS.register("multidimensional")
@declare(lens=True, cut_unit="pairs per pixel", kernels="lightcuts.render.multidim.render", reference=True,
         forest=True, params={
             "representatives": Param(int, DEFAULT_REPRESENTATIVES, lo=1, hi=64,
                                      doc="light representatives per light node (1: the tree's own only)"),
             "gather_representatives": Param(int, 1, lo=1, hi=64,
                                             doc="representative gather points per gather node (1: the gather "
                                                 "tree's own only)")})
class Multidimensional(CutIntegrator):
    """One cut per pixel through (gather tree) x (light trees) (Walter et al. 2006):
    lightcuts.render.multidim.

    Settings as :class:`CutIntegrator` (``max_cut``: pairs per gather point, so the pixel's cut
    holds at most ``max_cut * spp`` pairs, up to MAX_CUT: a config means the same effort per eye
    ray for both cut integrators), plus aperture : lens radius, world units (0: pinhole, exactly
    the lightcuts integrator's eye rays); focus_distance : distance of the plane in focus along the
    view axis (None: |look_at - position|); representatives : light representatives per light node
    (1: the tree's own only); gather_representatives : representative gather points per gather
    node, the pair (G, L) using the one of column L mod R (1: the gather tree's own only; more
    decorrelates the pairs' errors at the cost of shadow rays); all_pairs : the brute-force
    reference instead (every gather point with every light). ``cut_size``: pairs per pixel.
    """

    def __init__(self, *, spp: int = 16, eps: float = 0.02, max_cut: int = 1000, clamp: bool = True,
                 clamp_min_distance: float = 0.05, visibility: bool = True, aperture: float = 0.0,
                 focus_distance: float | None = None, representatives: int = DEFAULT_REPRESENTATIVES,
                 gather_representatives: int = 1, all_pairs: bool = False):
        super().__init__(spp=spp, eps=eps, max_cut=max_cut, clamp=clamp, clamp_min_distance=clamp_min_distance,
                         visibility=visibility)
        self.aperture = _non_negative(aperture, "camera.aperture")
        if focus_distance is not None and not (focus_distance > 0 and math.isfinite(focus_distance)):
            raise LightcutsError(f"camera.focus_distance: {focus_distance} must be a finite number > 0")
        self.focus_distance = None if focus_distance is None else float(focus_distance)
        self.representatives = self.param("representatives", representatives)
        self.gather_representatives = self.param("gather_representatives", gather_representatives)
        self.brute_force = bool(all_pairs)

    @classmethod
    def settings(cls, cfg) -> dict:
        return {**super().settings(cfg), "aperture": cfg.camera.aperture, "focus_distance": cfg.camera.focus_distance}

    def reference(self) -> "Multidimensional":
        """Every gather point of every pixel with every light (one shadow ray each): the same gather
        points."""
        return Multidimensional(spp=self.spp, eps=self.eps, max_cut=self.max_cut, clamp=self.clamp,
                                clamp_min_distance=self.clamp_min_distance, visibility=self.visibility,
                                aperture=self.aperture, focus_distance=self.focus_distance,
                                representatives=self.representatives,
                                gather_representatives=self.gather_representatives, all_pairs=True)

    def band_kernel(self, frame):
        from lightcuts.render.multidim.render import band_kernel

        return band_kernel(self, frame)


@INTEGRATORS.register("path")
@declare(lens=False, cut_unit="path vertices per eye ray", kernels="lightcuts.render.path", reference=False,
         forest=False, params={
             "max_depth": Param(int, MAX_PATH_VERTICES, lo=1, hi=MAX_PATH_VERTICES,
                                doc="path vertices at most (1: the emitters seen and their direct light)")})
class Path(Integrator):
    """A path tracer with lightcuts' own BRDF (lightcuts.render.path): next-event estimation on the
    scene's emitting triangles and BRDF draws, combined by multiple importance sampling, Russian
    roulette, at most ``max_depth`` vertices per path. It uses no lights or trees (the emitting
    triangles are its lights), so a run with a sun or an environment map is refused; ``cut_size`` is
    the path's vertices per eye ray and ``shadow_rays`` its next-event rays. It is its own
    reference (unbiased): it has no brute-force counterpart.
    """

    def __init__(self, *, spp: int = 1, max_depth: int = MAX_PATH_VERTICES):
        super().__init__(spp=spp)
        self.max_depth = self.max_cut = self.param("max_depth", max_depth)

    @classmethod
    def settings(cls, cfg) -> dict:
        for key, value in (("lights.sun", cfg.lights.sun), ("lights.environment", cfg.lights.environment)):
            if value is not None:
                raise LightcutsError(f"{key}: integrator 'path' renders the scene's emitting triangles only; "
                                     f"leave {key} out or use render.integrator: lightcuts")
        return super().settings(cfg)

    def forest(self, lights: dict, trees: dict | None):
        return None

    def band_kernel(self, frame):
        from lightcuts.render.path import band_kernel

        return band_kernel(self, frame)


def make_integrator(cfg, integrator=None) -> Integrator:
    """The integrator of the run ``cfg`` (a RunConfig): the entry ``integrator`` (a Resolved, e.g. the
    plan's, or a spec; None: ``cfg.render.integrator``) built from the config's settings and its
    resolved parameters. LightcutsError with one line naming the config key."""
    resolved = INTEGRATORS.resolve(cfg.render.integrator if integrator is None else integrator, "render.integrator")
    return resolved.obj.from_config(cfg, **resolved.params)
