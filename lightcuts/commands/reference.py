"""``lightcuts reference CONFIG``: the run rendered by a path tracer and by lightcuts, and compared.

The path tracer (``--renderer``) is Mitsuba 3's (default; an independent renderer, the optional
extra ``pip install 'lightcuts[mitsuba]'``: without it the command stops with one line naming
that command, exit status 2, before any work; Phong is approximated there) or lightcuts' own
(:mod:`lightcuts.render.path`: the exact BRDF, emitting triangles only, every bounce). The
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
seconds, and whether any Phong material was approximated.

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
    from lightcuts.render.references import DEFAULT_REFERENCE

    p.add_argument("--renderer", default=DEFAULT_REFERENCE,
                   help="the path tracer, a reference renderer (`lightcuts plugins references`): mitsuba, Mitsuba 3 "
                        "(independent; Phong approximated) or lightcuts, lightcuts' own (lightcuts.render.path: "
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
    from lightcuts.render.references import REFERENCES, make_reference
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.io import check_output_dir
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
    out_dir = check_output_dir(Path(args.out) if args.out else Path("renders") / cfg.name / "reference",
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


def _lightcuts_image(args, cfg, plan, scene, envmap, warmup: list) -> tuple[np.ndarray, dict]:
    """lightcuts' image of the run (all its passes) and its figures (lights, seconds)."""
    from lightcuts.pipeline.passes import render_passes
    from lightcuts.pipeline.warmup import finish_warmup, start_render_warmup

    t0 = time.perf_counter()
    if plan.caster.trait("warm_render_kernel", False):
        warmup.append(start_render_warmup(plan.integrator.trait("kernels")))
    with plan.make_caster(scene) as caster:
        light_sets = plan.lights(scene, caster, envmap)
        trees = plan.trees(light_sets)
        t_pre = time.perf_counter() - t0
        result = render_passes(cfg, plan, scene, caster, envmap, desc=f"{cfg.name}: lightcuts",
                               progress=not args.no_progress, lights=light_sets, trees=trees,
                               before_render=lambda: finish_warmup(warmup[0] if warmup else None))
    return result.image, {"lights": {typ: len(ls) for typ, ls in light_sets.items()},
                          "lights_indirect": int(sum(int(ls.indirect.sum()) for ls in light_sets.values())),
                          "eps": cfg.render.eps, "spp": cfg.render.spp, "compensation": cfg.render.compensation,
                          "continuation_rays": cfg.render.continuation_rays, "representatives": cfg.render.representatives, "passes": cfg.render.passes,
                          "preprocess_seconds": t_pre, "render_seconds": result.render_seconds,
                          "seconds": result.seconds, "cut_size_mean": float(result.cut_size.mean())}


def _run(args, cfg, plan, out_dir: Path, warmup: list, tracer) -> dict:
    from lightcuts import __version__
    from lightcuts.io import output_set, save_json
    from lightcuts.report.images import compare_images, write_exr, write_png

    scene = plan.scene()
    envmap = plan.environment()
    image, lc = _lightcuts_image(args, cfg, plan, scene, envmap, warmup)

    ref, spp, t_load, t_mi = tracer.long_render(cfg, scene, envmap, args.spp, args.integrator, args.max_depth,
                                                log=lambda line: print(line, flush=True))

    comparison = compare_images(image, ref)
    described = {**tracer.describe(), "spp": spp, "max_depth": args.max_depth, "load_seconds": t_load,
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
        "path_tracer": described,
        **({tracer.report_key: described} if tracer.report_key else {}),
        "lightcuts": {**lc, "direct_only": args.integrator == "direct"},
        "phong_approximated": not tracer.trait("exact_materials") and bool((scene.specular.max(axis=1) > 0).any()),
    }
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", ref)
        write_png(tmp_dir / f"{tracer.file}.png", ref, cfg.render.exposure)
        write_exr(tmp_dir / "lightcuts.exr", image)
        write_png(tmp_dir / "lightcuts.png", image, cfg.render.exposure)
        save_json(tmp_dir / "report.json", report)
    ratio = comparison["energy_ratio"]
    e, b = comparison["pixel"], comparison.get("block8")
    name = tracer.title
    line = (f"{cfg.name}: {args.integrator}, {name} {spp} spp {t_mi:.2f} s, lightcuts {lc['render_seconds']:.2f} s; "
            + (f"energy lightcuts/{name} {ratio:.4f}" if ratio is not None else f"the {name}'s image is black"))
    line += f"; relative error per pixel median {100 * e['median']:.2f}% p99 {100 * e['p99']:.2f}%"
    if b is not None:
        line += f", 8x8 blocks median {100 * b['median']:.2f}% p99 {100 * b['p99']:.2f}%"
    print(f"{line} -> {out_dir}")
    return report


def _run_curve(args, cfg, plan, out_dir: Path, tracer) -> dict:
    from lightcuts import __version__
    from lightcuts.pipeline.convergence import error_curve, long_reference
    from lightcuts.io import output_set, save_csv, save_json
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
              **curve}
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", ref)
        write_png(tmp_dir / f"{tracer.file}.png", ref, cfg.render.exposure)
        write_exr(tmp_dir / "lightcuts.exr", image)
        write_png(tmp_dir / "lightcuts.png", image, cfg.render.exposure)
        save_csv(tmp_dir / "curve.csv", rows, ["method", "passes", "spp", "seconds", "energy_ratio", "pixel_median",
                                               "block8_median"])
        loglog_panels(tmp_dir / "curve.png", panels, f"{cfg.name}: error against time ({settings}; "
                      f"reference {tracer.name} {args.spp} spp)", (10.0, 4.2))
        save_json(tmp_dir / "report.json", report)
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
    from lightcuts.report.images import write_exr, write_png

    images = split.pop("images")
    rows = [{**r, "overrides": " ".join(r["overrides"])} for r in split["rows"]]
    report = {"lightcuts_version": __version__, "config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed,
              "path_tracer": {**tracer.describe(), "spp": args.spp}, **split}
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / f"{tracer.file}.exr", images["path"])
        write_png(tmp_dir / f"{tracer.file}.png", images["path"], cfg.render.exposure)
        save_csv(tmp_dir / "split.csv", rows, ["label", "energy_ratio", "pixel_median", "block8_median", "seconds",
                                               "integrator", "diffuse", "overrides"])
        save_json(tmp_dir / "report.json", report)
    print(f"{cfg.name}: energy split written -> {out_dir}")
    return report
