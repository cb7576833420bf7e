"""One render in memory (:class:`Render`) and the run that makes it, shared by :func:`lightcuts.render`
and ``lightcuts render``: plan -> scene -> ray caster -> lights -> trees -> image (-> reference)."""

from __future__ import annotations

import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Render:
    """A lightcuts render, nothing written to disk until :meth:`save`.

    config : the RunConfig it was rendered from
    image : (H, W, 3) float32, linear RGB radiance (H, W: the crop window's size when cropped)
    cut_size : (H, W) float32, the cut per pixel in the integrator's ``cut_unit`` (report's
        ``cut_size_unit``): ``lightcuts``, light nodes summed over the trees, mean over the eye rays;
        ``multidimensional``, (gather, light) pairs in the pixel's cut
    report : the dict ``lightcuts render`` writes as report.json (settings, counts, seconds)
    reference : (H, W, 3) float32, the all-lights reference image, or None (``reference=False``)
    """

    config: object
    image: np.ndarray
    cut_size: np.ndarray
    report: dict
    reference: np.ndarray | None = None

    def srgb8(self) -> np.ndarray:
        """(H, W, 3) uint8: the image as image.png has it (sRGB through ``render.tonemap``)."""
        from lightcuts.report.tonemap import of, srgb8

        return srgb8(self.image, *of(self.config.render.tonemap))

    def _repr_png_(self) -> bytes:
        """The tone-mapped image as PNG bytes (shown by Jupyter/IPython)."""
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.srgb8()).save(buf, format="PNG")
        return buf.getvalue()

    def save(self, folder) -> Path:
        """Write the files ``lightcuts render`` writes into ``folder`` (replaced as a whole, see
        :func:`lightcuts.io.output_set`): image.exr, image.png, cutsize.png, report.json, report.html
        (:mod:`lightcuts.report.pages`), and reference.exr / reference.png if there is a reference.
        Returns the folder."""
        from lightcuts.io import SUBRUN_FOLDERS, check_output_dir, output_set, save_json
        from lightcuts.report import pages
        from lightcuts.report.html import write_report
        from lightcuts.report.images import write_exr, write_heatmap, write_png

        cfg, report = self.config, self.report
        out = check_output_dir(folder, "folder")
        with output_set(out, keep=SUBRUN_FOLDERS) as tmp:
            write_exr(tmp / "image.exr", self.image)
            write_png(tmp / "image.png", self.image, cfg.render.tonemap)
            by = report["builder"] or report["plugins"]["integrator"]["type"]  # no trees: the integrator
            write_heatmap(tmp / "cutsize.png", self.cut_size, label=f"cut size ({report['cut_size_unit']})",
                          title=f"{cfg.name}: {by}, eps {cfg.render.eps:g}, mean cut {report['cut_size_mean']:.0f}")
            if self.reference is not None:
                write_exr(tmp / "reference.exr", self.reference)
                write_png(tmp / "reference.png", self.reference, cfg.render.tonemap)
            save_json(tmp / "report.json", report)
            write_report(tmp / "report.html", pages.render(self))
        return out

    def summary(self) -> str:
        """The one-line summary ``lightcuts render`` prints (size, lights, cut, rays, seconds, and the
        error against the reference when there is one)."""
        r = self.report
        line = (f"{r['name']}: {r['resolution'][0]}x{r['resolution'][1]}, {self._lights()}: "
                f"cut {r['cut_size_mean']:.1f} avg / {r['cut_size_max']:.0f} max, "
                f"{r['shadow_rays_per_pixel']:.1f} shadow rays/pixel, "
                f"preprocess {r['preprocess_seconds']:.2f} s, build {r['build_seconds']:.2f} s, "
                f"render {r['render_seconds']:.2f} s")
        if "reference" in r:
            e = r["reference"]["relative_error"]
            line += (f"; vs reference: median {100 * e['median']:.2f}%, p99 {100 * e['p99']:.2f}%, "
                     f"speed-up {r['reference']['speedup']:.0f}x")
        return line

    def _lights(self) -> str:
        """The summary's lights: the config's and their builder, or those the integrator draws itself
        (its ``light_sampler`` record: how many, by what, through which builder's tree)."""
        r = self.report
        if r["lights"]:
            return f"{sum(r['lights'].values())} lights, builder {r['builder']}"
        s = r.get("light_sampler", {})
        if "lights" not in s:
            return "no lights"
        return f"{s['lights']} lights drawn by {s['type']}" + (f", builder {r['builder']}" if r["builder"] else "")

    def __repr__(self) -> str:
        return f"<Render {self.summary()}>"


def check_reference_lights(cfg, key: str, instead: str = "") -> None:
    """LightcutsError naming ``key`` (the option that asks for the all-lights reference) when the
    config's lights are not points it can sum: the emitting triangles of ``lights.direct.source:
    triangles`` are integrated by sampling alone. ``instead``: what else the caller can do."""
    from lightcuts.errors import LightcutsError

    if cfg.lights.direct.source == "triangles":
        raise LightcutsError(f"{key}: the all-lights reference sums point lights, not the emitting triangles of "
                             f"lights.direct.source: triangles; {instead}compare against a path tracer "
                             "(lightcuts reference CONFIG)")


def check_reference(cfg, integrator) -> None:
    """LightcutsError unless the brute-force reference measures this run: the plan's ``integrator``
    must have one (its ``reference`` trait), and it is the image of one VPL set without the
    compensation, so passes > 1 and compensation have none (their reference is a path tracer's:
    ``lightcuts reference``), nor triangle lights (:func:`check_reference_lights`)."""
    from lightcuts.errors import LightcutsError

    check_reference_lights(cfg, "--reference")
    if not integrator.trait("reference", False):
        raise LightcutsError(f"--reference: integrator {integrator.name!r} has no brute-force reference; "
                             f"compare it with another run or a path tracer (lightcuts reference CONFIG)")
    if cfg.render.passes > 1 or cfg.render.compensation:
        raise LightcutsError("--reference: the all-lights reference is one VPL set's image without compensation; "
                             "with render.passes > 1 or render.compensation compare against a path tracer "
                             "(lightcuts reference CONFIG)")


def render_run(cfg, plan, source: str | None, reference: bool = False, progress: bool = True,
               runner=None) -> Render:
    """Run the plan (:func:`lightcuts.pipeline.plan.plan_run` of ``cfg`` with ``render=True``) and
    return the Render; ``source`` is the config file recorded in the report (None: none).

    runner : renders the passes and the reference instead of this process, with the signature of
        :func:`~lightcuts.pipeline.passes.render_passes` (``runner.passes``), ``runner.reference(cfg, plan,
        scene, lights, envmap, desc, progress) -> RenderResult`` and ``runner.record() -> dict``
        (report.json's ``cluster``): a cluster's (:class:`lightcuts.distributed.runner.ClusterRunner`);
        None renders here.
    """
    from lightcuts.pipeline.warmup import finish_warmup

    if reference:
        check_reference(cfg, plan.integrator)

    warmup = []  # the child compiling the render kernel, if any
    try:
        return _run(cfg, plan, source, reference, progress, warmup, runner)
    finally:
        finish_warmup(warmup[0] if warmup else None, timeout=0)


def _run(cfg, plan, source, reference: bool, progress: bool, warmup: list, runner) -> Render:
    from lightcuts import __version__
    from lightcuts.pipeline.passes import render_passes
    from lightcuts.pipeline.timing import progress_bar
    from lightcuts.pipeline.plan import tree_meta
    from lightcuts.pipeline.warmup import compile_seconds, finish_warmup, start_render_warmup
    from lightcuts.integrators.registry import make_integrator
    from lightcuts.report.images import relative_error

    def phase(name):  # each phase named as it starts, so a long cold compile is not silence
        if progress:
            print(f"{cfg.name}: {name} ...", file=sys.stderr, flush=True)

    t0, c0 = time.perf_counter(), compile_seconds()
    phase("scene")
    scene = plan.scene()
    if runner is None and plan.caster.trait("warm_render_kernel", False):
        # None where the render kernel is cached (a cluster's workers load it themselves)
        warmup.append(start_render_warmup(plan.integrator.trait("kernels")))
    caster = plan.make_caster(scene)
    envmap = plan.environment()
    # Without them (the path tracer draws the scene's emitters itself): no lights, no trees.
    uses_trees = plan.uses_trees
    light_sets, trees, t_lights, t_build, c_build = {}, None, 0.0, 0.0, 0.0
    if uses_trees:
        phase("lights")
        t1, c1 = time.perf_counter(), compile_seconds()
        light_sets = plan.lights(scene, caster, envmap)
        t_lights = time.perf_counter() - t1 - (compile_seconds() - c1)
    c_pre = compile_seconds() - c0
    t_pre = time.perf_counter() - t0 - c_pre

    if uses_trees:
        t0, c0 = time.perf_counter(), compile_seconds()
        phase("trees")
        trees = plan.trees(light_sets)
        c_build = compile_seconds() - c0
        t_build = time.perf_counter() - t0 - c_build
    phase("render")

    # The wait for numba (the child compiling the render kernel, then loading it) is reported on its own.
    wait = []

    def finish():
        t0 = time.perf_counter()
        finish_warmup(warmup[0] if warmup else None)
        wait.append(time.perf_counter() - t0)

    render = render_passes if runner is None else runner.passes
    passes = render(cfg, plan, scene, caster, envmap, desc=f"{cfg.name}: lightcuts", progress=progress,
                    lights=light_sets, trees=trees, before_render=finish)
    result = passes.result0
    used = tree_meta(trees) if uses_trees else sampler_meta(result.light_sampler)
    t_render = passes.render_seconds
    t_jit = wait[0] + passes.load_seconds
    rows = result.image.shape[0]

    n_pixels = result.image.shape[0] * result.image.shape[1]
    report = {
        "lightcuts_version": __version__,
        "config": source,
        "name": cfg.name,
        "seed": cfg.seed,
        "scene": {"name": scene.name, "triangles": scene.n_faces, "emitters": int(len(scene.emitters)),
                  "diagonal": scene.diagonal},
        "lights": {typ: len(ls) for typ, ls in light_sets.items()},
        "lights_indirect": int(sum(int(ls.indirect.sum()) for ls in light_sets.values())),
        "builder": used["builder"],
        "metric": used["metric"],
        "c": used["c"],
        "plugins": plan.record(),
        "eps": cfg.render.eps,
        "max_cut": cfg.render.max_cut,
        "resolution": [int(result.image.shape[1]), int(result.image.shape[0])],
        "crop": cfg.render.crop,
        "spp": cfg.render.spp,
        "clamping": clamping_record(cfg.render.clamp, passes, make_integrator(cfg, plan.integrator).clamp),
        "compensation": cfg.render.compensation,
        "continuation_rays": cfg.render.continuation_rays,
        "representatives": cfg.render.representatives,
        "passes": passes.records,
        "preprocess_seconds": t_pre,
        "jit_seconds": t_jit,
        "compile_seconds": {"preprocess": c_pre, "build": c_build, "render": t_jit},
        "build_seconds": t_build,
        "render_seconds": t_render,
        **image_seconds(t_lights, t_build, passes),
        "cut_size_unit": plan.integrator.trait("cut_unit"),
        "cut_size_mean": float(passes.cut_size.mean()),
        "cut_size_max": float(passes.cut_size.max()),
        "eye_rays": int(passes.eye_rays),
        "shadow_rays": int(passes.shadow_rays),
        "shadow_rays_per_pixel": float(passes.shadow_rays) / n_pixels,
        "rays_per_second": float(passes.eye_rays + passes.shadow_rays) / max(t_render, 1e-9),
        "threads": _threads(),
        "machine": platform.machine(),
    }
    if result.light_sampler:
        report["light_sampler"] = result.light_sampler
    ref_image = None
    if reference and runner is not None:
        t0 = time.perf_counter()
        ref = runner.reference(cfg, plan, scene, light_sets, envmap, f"{cfg.name}: reference", progress)
        t_ref = time.perf_counter() - t0
    elif reference:
        with progress_bar(rows, f"{cfg.name}: reference", not progress) as bar:
            t0 = time.perf_counter()
            ref = make_integrator(cfg, plan.integrator).reference().render(
                scene, caster, light_sets, None, envmap=envmap, seed=cfg.seed, crop=cfg.render.crop,
                progress=bar.update)
            t_ref = time.perf_counter() - t0
    if reference:
        ref_image = ref.image
        report["reference"] = {"render_seconds": t_ref, "shadow_rays": int(ref.shadow_rays),
                               "speedup": t_ref / max(t_render, 1e-9),
                               "relative_error": relative_error(passes.image, ref.image)}
    if runner is not None:
        report["cluster"] = runner.record()
    return Render(cfg, passes.image, passes.cut_size, report, ref_image)


def sampler_meta(light_sampler: dict | None) -> dict:
    """report.json's ``builder``, ``metric`` and ``c`` of a render without the config's light trees:
    the builder and metric of the integrator's own ``light_sampler`` record where it names them (the
    path tracer's tree over the emitting triangles, whose ``c`` is in that record), else None; ``c``
    (per light type of the config's trees) empty."""
    record = light_sampler or {}
    return {"builder": record.get("builder"), "metric": record.get("metric"), "c": {}}


def clamping_record(clamp, passes, enabled: bool) -> dict:
    """report.json's ``clamping``: whether the integrator clamps (``enabled``: the config's setting,
    or the integrator's default when the config gives none), the settings of ``render.clamp`` that its mode reads, the radius
    pass 0 clamped within (world units, 0 when off; each pass's is in its ``passes`` record) and
    the fraction of the reflected light clamping removed (the passes' mean)."""
    setting = {"density": "vpls", "diagonal": "min_distance"}[clamp.mode]
    return {"enabled": bool(enabled), "mode": clamp.mode, setting: getattr(clamp, setting),
            "radius": float(passes.records[0]["clamp_radius"]),
            "clamped_energy_fraction": float(passes.clamped_fraction)}


def image_seconds(t_lights: float, t_trees: float, passes) -> dict:
    """report.json's ``image_seconds`` and its parts: from the loaded scene (and its ray caster, which
    any renderer of it needs) to the finished image, pass 0's lights and trees (``t_lights``,
    ``t_trees``) and every pass after them (their lights, trees and image), compiling and loading
    kernels left out: the time an efficiency divides by."""
    parts = {"lights": float(t_lights), "trees": float(t_trees), "passes": passes.seconds}
    return {"image_seconds": parts["lights"] + parts["trees"] + parts["passes"], "image_seconds_parts": parts}


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())
