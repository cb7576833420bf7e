"""``lightcuts reference CONFIG``: the run rendered by a path tracer and by lightcuts, and compared.

The path tracer (``--renderer``) is Mitsuba 3's (default; an independent renderer, the optional
extra ``pip install 'lightcuts[mitsuba]'``: without it the command stops with one line naming
that command, exit status 2, before any work; Phong is approximated there) or lightcuts' own
(:mod:`lightcuts.integrators.path`: the exact BRDF, emitting triangles only, every bounce). The
lightcuts side is rendered here from the same config (the plan's stages, as ``lightcuts render``
does: all ``render.passes`` passes, with ``render.compensation`` and ``render.representatives`` as
set), so both images come from the one config and its ``--set`` overrides; an existing
``renders/<name>/image.exr`` is not reused. With ``--integrator direct`` (Mitsuba only) the
lightcuts side runs with ``lights.indirect.count: 0`` (no indirect VPLs; direct lights, sun and
environment kept), so both compute direct light only; with ``path`` lightcuts renders the config
as given.

Outputs in ``renders/<name>/reference/`` (or ``--out``), one set (:func:`lightcuts.io.output_set`;
``lightcuts render`` keeps it when it replaces ``renders/<name>/``): the path tracer's image
``mitsuba.exr`` / ``.png`` (``path.exr`` / ``.png`` from lightcuts' own), ``lightcuts.exr``,
``lightcuts.png`` (the image compared, rendered here) and ``report.json``: the comparison
(:func:`lightcuts.report.images.compare_images`: energy ratio = mean luminance lightcuts / path
tracer; relative error per pixel and on 8x8 block means: mean, median, p99, max), the path
tracer's name, spp, integrator, max depth, seconds and version, lightcuts' lights, settings and
seconds, and whether any Phong material was approximated; ``report.html`` (both images in a viewer
with the error view, the figures; :mod:`lightcuts.report.pages`).

Two things keep the figures honest. Pixels that see an emitter directly
(:func:`lightcuts.integrators.primary.emitter_mask`) are left out of the energy ratio and the errors
(``energy_ratio_frame`` keeps the whole frame's): their radiance is the emitter's in both images and
can hold most of the frame's energy. And the path tracer's image is the mean of two independent
halves of ``--spp`` (rounded up to even; seeds ``seed`` and ``seed ^ 1``), whose difference gives
each figure's value for the path tracer's own noise (``reference_noise``): an error close to it is
mostly that noise, not lightcuts' error. Both are printed side by side.

``--curve`` (path tracing only) instead measures error against time
(:func:`lightcuts.pipeline.convergence.error_curve`): lightcuts' passes 1, 2, 4, ... ``--passes`` (the
config's converging settings as given) and the path tracer at the same times, both against its long
render at ``--spp``; it writes ``curve.csv`` (method, passes, spp, seconds, energy ratio, per-pixel
and 8x8-block median error), ``curve.png`` (both errors against time, log-log) and the fitted
slopes and per-time verdicts in ``report.json``. ``--split`` writes ``split.csv``: the energy ratio
with clamping off, each remedy on, diffuse materials and direct light alone
(:func:`lightcuts.pipeline.convergence.energy_split`; rows with passes use ``--passes``, default 8).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lightcuts.commands.common import add_set
from lightcuts.config import load_config
from lightcuts.errors import LightcutsError


def add_parser(sub) -> None:
    p = sub.add_parser("reference", help="render a YAML run with a path tracer (Mitsuba 3 or lightcuts' own) and "
                                         "compare lightcuts' image with it")
    p.add_argument("config")
    p.add_argument("--spp", type=int, default=64, help="the path tracer's samples per pixel (default 64)")
    p.add_argument("--integrator", choices=("path", "direct"), default="path",
                   help="path: full light transport; direct: direct light only, lightcuts without indirect VPLs")
    p.add_argument("--max-depth", type=int, default=-1, help="path length limit of the path tracer (-1: none)")
    from lightcuts.integrators.references import DEFAULT_REFERENCE

    p.add_argument("--renderer", default=DEFAULT_REFERENCE,
                   help="the path tracer, a reference renderer (`lightcuts plugins references`): mitsuba, Mitsuba 3 "
                        "(independent; Phong approximated) or lightcuts, lightcuts' own (lightcuts.integrators.path: "
                        "the exact BRDF; emitting triangles only)")
    study = p.add_mutually_exclusive_group()
    study.add_argument("--curve", action="store_true",
                       help="error against time: lightcuts passes 1, 2, 4, ... --passes and the path tracer "
                            "at the same times, against its long render at --spp (curve.csv, curve.png)")
    study.add_argument("--split", action="store_true",
                       help="the energy ratio with clamping off, each remedy on, diffuse materials and direct "
                            "light alone (split.csv)")
    p.add_argument("--passes", type=int, default=None,
                   help="passes of --curve (default 64) and of the --split rows that use passes (default 8)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/reference)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_reference(args)
    return 0


def run_reference(args) -> dict:
    """Run the command as the CLI does; returns the report dict (also written to report.json)."""
    from lightcuts.integrators.references import REFERENCES, make_reference
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.io import check_output_dir, run_dir
    from lightcuts.limits import MAX_BOUNCES, MAX_PASSES, MAX_REFERENCE_SPP

    overrides = list(args.overrides) + (["lights.indirect.count=0"] if args.integrator == "direct" else [])
    if args.passes is not None and not (args.curve or args.split):
        raise LightcutsError("--passes: goes with --curve or --split (for one render set render.passes)")
    if args.passes is not None and not 1 <= args.passes <= MAX_PASSES:
        raise LightcutsError(f"--passes: {args.passes} must be an integer from 1 to {MAX_PASSES}")
    if (args.curve or args.split) and args.integrator != "path":
        raise LightcutsError(f"--{'curve' if args.curve else 'split'}: compares with the path tracer; "
                             "drop --integrator direct")
    if args.curve:
        overrides.append(f"render.passes={args.passes or 64}")
    cfg = load_config(args.config, overrides)
    plan = plan_run(cfg, render=True)
    if not 1 <= args.spp <= MAX_REFERENCE_SPP:
        raise LightcutsError(f"--spp: {args.spp} must be an integer from 1 to {MAX_REFERENCE_SPP:,} "
                             "(lightcuts.limits.MAX_REFERENCE_SPP)")
    if not (args.max_depth == -1 or 1 <= args.max_depth <= MAX_BOUNCES):
        raise LightcutsError(f"--max-depth: {args.max_depth} must be -1 (unbounded) or from 1 to {MAX_BOUNCES} "
                             "(lightcuts.limits.MAX_BOUNCES)")
    tracer = make_reference(args.renderer)
    if args.max_depth != -1 and not tracer.trait("max_depth"):
        able = " or ".join(e.name for e in REFERENCES.entries() if e.trait("max_depth"))
        raise LightcutsError(f"--max-depth: goes with --renderer {able} ({args.renderer}'s path tracer has every "
                             "bounce)")
    tracer.check(cfg, args.integrator)
    out_dir = check_output_dir(Path(args.out) if args.out else run_dir(cfg.name, args.overrides) / "reference",
                               "--out" if args.out else "name")
    try:
        return _study(args, cfg, plan, overrides, out_dir, tracer)
    finally:
        tracer.close()


def _study(args, cfg, plan, overrides, out_dir: Path, tracer) -> dict:
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.warmup import finish_warmup

    if args.split:
        from lightcuts.pipeline.convergence import energy_split

        def make_run(extra):
            c = load_config(args.config, list(overrides) + list(extra))
            return c, plan_run(c, render=True)

        split = energy_split(make_run, args.passes or 8, args.spp, progress=not args.no_progress, tracer=tracer)
        return _write_split(args, cfg, out_dir, split, tracer)
    if args.curve:
        return _run_curve(args, cfg, plan, out_dir, tracer)
    warmup = []
    try:
        return _run(args, cfg, plan, out_dir, warmup, tracer)
    finally:
        finish_warmup(warmup[0] if warmup else None, timeout=0)


def _lightcuts_image(args, cfg, plan, scene, envmap, warmup: list) -> tuple[np.ndarray, dict, np.ndarray]:
    """lightcuts' image of the run (all its passes), its figures (lights, none for an integrator that
    renders from no lights and trees; seconds) and the pixels that see an emitter directly
    (:func:`lightcuts.integrators.primary.emitter_mask`)."""
    from lightcuts.pipeline.passes import pass_lights, render_passes
    from lightcuts.pipeline.rendering import image_seconds
    from lightcuts.pipeline.warmup import finish_warmup, start_render_warmup
    from lightcuts.integrators.primary import emitter_mask

    t0 = time.perf_counter()
    if plan.caster.trait("warm_render_kernel", False):
        warmup.append(start_render_warmup(plan.integrator.trait("kernels")))
    with plan.make_caster(scene) as caster:
        light_sets, trees, t_lights, t_trees = pass_lights(plan, scene, caster, envmap, cfg.seed)
        t_pre = time.perf_counter() - t0
        result = render_passes(cfg, plan, scene, caster, envmap, desc=f"{cfg.name}: lightcuts",
                               progress=not args.no_progress, lights=light_sets, trees=trees,
                               before_render=lambda: finish_warmup(warmup[0] if warmup else None))
        mask = emitter_mask(scene, caster, cfg.render.crop, envmap is not None)
    return result.image, {"lights": {typ: len(ls) for typ, ls in light_sets.items()},
                          "lights_indirect": int(sum(int(ls.indirect.sum()) for ls in light_sets.values())),
                          "eps": cfg.render.eps, "spp": cfg.render.spp, "compensation": cfg.render.compensation,
                          "continuation_rays": cfg.render.continuation_rays,
                          "representatives": cfg.render.representatives, "passes": cfg.render.passes,
                          "preprocess_seconds": t_pre, "render_seconds": result.render_seconds,
                          "seconds": result.seconds, **image_seconds(t_lights, t_trees, result),
                          "cut_size_mean": float(result.cut_size.mean())}, mask


def _xml_mapping(cfg) -> dict:
    """The ``scene.mitsuba`` file and how each of its BSDFs is mapped (what differs from Mitsuba)."""
    from lightcuts.scene.mitsuba_xml import bsdf_mapping

    return {"file": cfg.scene.mitsuba, "bsdfs": bsdf_mapping(cfg.resolve(cfg.scene.mitsuba))}


def _run(args, cfg, plan, out_dir: Path, warmup: list, tracer) -> dict:
    from lightcuts import __version__
    from lightcuts.io import output_set, save_json
    from lightcuts.report import pages
    from lightcuts.report.html import write_report
    from lightcuts.report.images import compare_images, write_exr, write_png

    scene = plan.scene()
    envmap = plan.environment()
    image, lc, mask = _lightcuts_image(args, cfg, plan, scene, envmap, warmup)

    # The path tracer's image is the mean of two independent halves (seeds seed and seed ^ 1): their
    # difference measures its own noise (compare_images, "reference_noise").
    half = (args.spp + 1) // 2 if args.spp > 1 else 1
    render, half, t_load = tracer.prepare(cfg, scene, envmap, half, args.integrator, args.max_depth)
    print(f"{cfg.name}: {tracer.title} {args.integrator}, {half * (1 + (args.spp > 1))} spp ...", flush=True)
    ref, t_mi = render(cfg.seed)
    halves = None
    if args.spp > 1:
        other, t_other = render(cfg.seed ^ 1)
        halves, ref, t_mi = (ref, other), (ref + other) / 2, t_mi + t_other
    spp = half * (1 + (halves is not None))

    comparison = compare_images(image, ref, mask=mask, halves=halves)
    name = tracer.title
    described = {**tracer.describe(), "spp": spp, "half_seeds": [cfg.seed, cfg.seed ^ 1] if halves else None,
                 "max_depth": args.max_depth, "load_seconds": t_load,
                 "render_seconds": t_mi}
    report = {
        "lightcuts_version": __version__,
        "config": str(Path(args.config)),
        "name": cfg.name,
        "seed": cfg.seed,
        "integrator": args.integrator,
        "resolution": [int(image.shape[1]), int(image.shape[0])],
        "crop": cfg.render.crop,
        "comparison": comparison,
        "emitter_mask": EMITTER_MASK,
        "path_tracer": described,
        **({tracer.report_key: described} if tracer.report_key else {}),
        **({"mitsuba_xml": _xml_mapping(cfg)} if cfg.scene.mitsuba is not None else {}),
        "lightcuts": {**lc, "direct_only": args.integrator == "direct"},
        "phong_approximated": not tracer.trait("exact_materials") and bool((scene.specular.max(axis=1) > 0).any()),
    }
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", ref)
        write_png(tmp_dir / f"{tracer.file}.png", ref, cfg.render.tonemap)
        write_exr(tmp_dir / "lightcuts.exr", image)
        write_png(tmp_dir / "lightcuts.png", image, cfg.render.tonemap)
        save_json(tmp_dir / "report.json", report)
        write_report(tmp_dir / "report.html", pages.reference(
            cfg, report, {"lightcuts": image, tracer.file: ref}, mask, tracer.file,
            [pages.comparison_table(comparison, name)]))
    print(f"{cfg.name}: {args.integrator}, {name} {spp} spp {t_mi:.2f} s, lightcuts {lc['render_seconds']:.2f} s")
    for line in comparison_lines(comparison, name):
        print(f"  {line}")
    print(f"-> {out_dir}")
    return report


#: How report.json describes the mask of pixels left out of the comparison's figures.
EMITTER_MASK = ("pixels that see an emitter (or the environment) directly, left out of the energy ratio and the "
                "errors: one pinhole ray through each pixel's centre and corners (lightcuts.integrators.primary)")


def comparison_lines(c: dict, name: str) -> list[str]:
    """The figures of :func:`lightcuts.report.images.compare_images` as lines for the terminal, each
    error beside the reference's own noise where it was measured."""
    noise = c.get("reference_noise", {})

    def pct(part: str, key: str) -> str:
        v = f"{100 * c[part][key]:.2f}%"
        if part not in noise:
            return v
        n = noise[part][key]  # |A - B| / (A + B) per pixel: 100% at most, so 100% means at least that
        return v + (" (noise >= 100%)" if n >= 1.0 else f" (noise {100 * n:.2f}%)")

    ratio = c["energy_ratio"]
    masked = c["masked_pixels"]
    lines = [(f"energy lightcuts/{name} {ratio:.4f}" if ratio is not None else f"the {name}'s image is black")
             + (f" +- {noise['energy_ratio']:.4f} (the {name}'s noise)" if noise.get("energy_ratio") else "")
             + f"; whole frame {c['energy_ratio_frame'] or 0:.4f}"
             + f"; {masked} pixels seeing an emitter directly left out of every figure"]
    lines.append(f"relative error per pixel: median {pct('pixel', 'median')}, p99 {pct('pixel', 'p99')}")
    if "block8" in c:
        lines.append(f"relative error of 8x8 block means: median {pct('block8', 'median')}, "
                     f"p99 {pct('block8', 'p99')}")
    if noise:
        lines.append(f"(noise: the error an exact image would show against this {name} image, from its two "
                     "independent halves)")
    return lines


def _run_curve(args, cfg, plan, out_dir: Path, tracer) -> dict:
    from lightcuts import __version__
    from lightcuts.pipeline.convergence import error_curve, long_reference
    from lightcuts.io import output_set, save_csv, save_json
    from lightcuts.report import pages
    from lightcuts.report.html import Table, write_report
    from lightcuts.report.images import write_exr, write_png
    from lightcuts.report.plots import loglog_panels

    scene = plan.scene()
    envmap = plan.environment()
    print(f"{cfg.name}: path tracer ({tracer.name}), {args.spp} spp (the long reference) ...", flush=True)
    ref, t_ref = long_reference(cfg, scene, envmap, args.spp, tracer=tracer)
    with plan.make_caster(scene) as caster:
        curve = error_curve(cfg, plan, scene, envmap, caster, ref, progress=not args.no_progress, tracer=tracer)
    image = curve.pop("image")
    rows = curve["rows"]
    series = {m: [r for r in rows if r["method"] == m] for m in ("lightcuts", tracer.label)}
    panels = [("seconds", f"{what} median relative error",
               [(m, [r["seconds"] for r in rs], [r[key] for r in rs]) for m, rs in series.items()])
              for what, key in (("per-pixel", "pixel_median"), ("8x8-block", "block8_median"))]
    settings = (f"compensation {'on' if cfg.render.compensation else 'off'}, {cfg.render.representatives} "
                f"representatives")
    report = {"lightcuts_version": __version__, "config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed,
              "resolution": [int(image.shape[1]), int(image.shape[0])], "crop": cfg.render.crop,
              "reference": {**tracer.describe(), "spp": args.spp, "seconds": t_ref},
              "lightcuts": {"passes": cfg.render.passes, "spp": cfg.render.spp, "eps": cfg.render.eps,
                            "compensation": cfg.render.compensation, "representatives": cfg.render.representatives},
              "emitter_mask": EMITTER_MASK, **curve}
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", ref)
        write_png(tmp_dir / f"{tracer.file}.png", ref, cfg.render.tonemap)
        write_exr(tmp_dir / "lightcuts.exr", image)
        write_png(tmp_dir / "lightcuts.png", image, cfg.render.tonemap)
        save_csv(tmp_dir / "curve.csv", rows, ["method", "passes", "spp", "seconds", "energy_ratio", "pixel_median",
                                               "block8_median"])
        loglog_panels(tmp_dir / "curve.png", panels, f"{cfg.name}: error against time ({settings}; "
                      f"reference {tracer.name} {args.spp} spp)", (10.0, 4.2))
        save_json(tmp_dir / "report.json", report)
        cols = [(k, k, None) for k in ("method", "passes", "spp", "seconds", "energy_ratio", "pixel_median",
                                       "block8_median")]
        write_report(tmp_dir / "report.html", pages.reference(
            cfg, report, {f"lightcuts, {cfg.render.passes} passes": image, f"{tracer.file}, {args.spp} spp": ref},
            reference_name=f"{tracer.file}, {args.spp} spp",
            tables=[Table("Error against time", cols, rows, "pixels that see an emitter directly left out")],
            plots=[("error against time", tmp_dir / "curve.png")]))
    s = curve["slope"]
    fmt = lambda v: "n/a" if v is None else f"{v:.2f}"  # noqa: E731
    print(f"{cfg.name}: lightcuts' error against time, slope per pixel {fmt(s['pixel_median'])}, "
          f"8x8 blocks {fmt(s['block8_median'])}; lower at each time (pixel/block8): "
          + ", ".join(f"{v['seconds']:.1f} s {v.get('pixel', '-')}/{v.get('block8', '-')}" for v in curve["verdict"])
          + f" -> {out_dir}")
    return report


def _write_split(args, cfg, out_dir: Path, split: dict, tracer) -> dict:
    from lightcuts import __version__
    from lightcuts.io import output_set, save_csv, save_json
    from lightcuts.report import pages
    from lightcuts.report.html import Table, write_report
    from lightcuts.report.images import write_exr, write_png

    images = split.pop("images")
    rows = [{**r, "overrides": " ".join(r["overrides"])} for r in split["rows"]]
    report = {"lightcuts_version": __version__, "config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed,
              "path_tracer": {**tracer.describe(), "spp": args.spp}, "emitter_mask": EMITTER_MASK, **split}
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", images["path"])
        write_png(tmp_dir / f"{tracer.file}.png", images["path"], cfg.render.tonemap)
        fields = ["label", "energy_ratio", "pixel_median", "block8_median", "seconds", "integrator", "diffuse",
                  "overrides"]
        save_csv(tmp_dir / "split.csv", rows, fields)
        save_json(tmp_dir / "report.json", report)
        write_report(tmp_dir / "report.html", pages.reference(
            cfg, report, {f"{tracer.file} ({key})": im for key, im in images.items()},
            tables=[Table("Energy split", [(k, k, None) for k in fields], rows,
                          "pixels that see an emitter directly left out")]))
    print(f"{cfg.name}: energy split written -> {out_dir}")
    return report
