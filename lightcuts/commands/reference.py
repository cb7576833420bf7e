"""``lightcuts reference CONFIG``: the run rendered by Mitsuba 3 and by lightcuts, and compared.

Needs the optional extra (``pip install 'lightcuts[mitsuba]'``); without it the command stops with
one line naming that command, exit status 2, before any work. The lightcuts side is rendered here
from the same config (the plan's stages and ``render_image``, as ``lightcuts render`` does), so
both images come from the one config and its ``--set`` overrides; an existing
``renders/<name>/image.exr`` is not reused. With ``--integrator direct`` the lightcuts side runs
with ``lights.indirect.count: 0`` (no indirect VPLs; direct lights, sun and environment kept), so
both compute direct light only; with ``path`` lightcuts renders the config as given (its indirect
VPLs are clamped, and they carry only the emitters' light: a sun or sky lights nothing indirectly).

Outputs in ``renders/<name>/reference/`` (or ``--out``), one set (:func:`lightcuts.io.output_set`;
``lightcuts render`` keeps it when it replaces ``renders/<name>/``): ``mitsuba.exr``,
``mitsuba.png``, ``lightcuts.exr``, ``lightcuts.png`` (the image compared, rendered here) and
``report.json``: the comparison (:func:`lightcuts.report.images.compare_images`: energy ratio =
mean luminance lightcuts / Mitsuba; relative error per pixel and on 8x8 block means: mean, median,
p99, max), Mitsuba's spp, integrator, max depth, seconds, version and variant, lightcuts' lights,
eps, spp and seconds, and whether any Phong material was approximated.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lightcuts.commands.common import add_set
from lightcuts.config import load_config
from lightcuts.errors import LightcutsError


def add_parser(sub) -> None:
    p = sub.add_parser("reference", help="render a YAML run with Mitsuba 3 and compare lightcuts' image with it")
    p.add_argument("config")
    p.add_argument("--spp", type=int, default=64, help="Mitsuba's samples per pixel (default 64)")
    p.add_argument("--integrator", choices=("path", "direct"), default="path",
                   help="path: full light transport; direct: direct light only, lightcuts without indirect VPLs")
    p.add_argument("--max-depth", type=int, default=-1, help="path length limit of the path tracer (-1: none)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/reference)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_reference(args)
    return 0


def run_reference(args) -> dict:
    """Run the command as the CLI does; returns the report dict (also written to report.json)."""
    from lightcuts.commands.plan import plan_run
    from lightcuts.commands.warmup import finish_warmup
    from lightcuts.io import check_output_dir
    from lightcuts.mitsuba import load_mitsuba

    overrides = list(args.overrides) + (["lights.indirect.count=0"] if args.integrator == "direct" else [])
    cfg = load_config(args.config, overrides)
    plan = plan_run(cfg, render=True)
    if args.spp < 1:
        raise LightcutsError(f"--spp: {args.spp} must be a positive integer")
    if not (args.max_depth == -1 or args.max_depth >= 1):
        raise LightcutsError(f"--max-depth: {args.max_depth} must be -1 (unbounded) or >= 1")
    out_dir = check_output_dir(Path(args.out) if args.out else Path("renders") / cfg.name / "reference",
                               "--out" if args.out else "name")
    load_mitsuba()
    warmup = []
    try:
        return _run(args, cfg, plan, out_dir, warmup)
    finally:
        finish_warmup(warmup[0] if warmup else None, timeout=0)


def _lightcuts_image(args, cfg, plan, scene, envmap, warmup: list) -> tuple[np.ndarray, dict]:
    """lightcuts' image of the run and its figures (lights, seconds)."""
    from lightcuts.commands.warmup import finish_warmup, start_render_warmup
    from lightcuts.commands.common import render_timed

    t0 = time.perf_counter()
    if plan.caster.trait("warm_render_kernel", False):
        warmup.append(start_render_warmup(plan.integrator.trait("kernels")))
    with plan.make_caster(scene) as caster:
        light_sets = plan.lights(scene, caster, envmap)
        trees = plan.trees(light_sets)
        t_pre = time.perf_counter() - t0
        finish_warmup(warmup[0] if warmup else None)
        result, t_render, _ = render_timed(cfg, scene, caster, light_sets, trees, envmap, f"{cfg.name}: lightcuts",
                                           args.no_progress)
    return result.image, {"lights": {typ: len(ls) for typ, ls in light_sets.items()},
                          "lights_indirect": int(sum(int(ls.indirect.sum()) for ls in light_sets.values())),
                          "eps": cfg.render.eps, "spp": cfg.render.spp, "preprocess_seconds": t_pre,
                          "render_seconds": t_render, "cut_size_mean": float(result.cut_size.mean())}


def _run(args, cfg, plan, out_dir: Path, warmup: list) -> dict:
    from lightcuts import __version__
    from lightcuts.io import output_set, save_json
    from lightcuts.mitsuba.render import load_scene, mitsuba_version, render_loaded, sample_count
    from lightcuts.report.images import compare_images, write_exr, write_png

    scene = plan.scene()
    envmap = plan.environment()
    image, lc = _lightcuts_image(args, cfg, plan, scene, envmap, warmup)

    t0 = time.perf_counter()
    mi_scene = load_scene(cfg, scene, envmap, spp=args.spp, integrator=args.integrator, max_depth=args.max_depth)
    t_load = time.perf_counter() - t0
    spp = sample_count(mi_scene)
    print(f"{cfg.name}: Mitsuba {args.integrator}, {spp} spp ...", flush=True)
    ref, t_mi = render_loaded(mi_scene, cfg.seed)

    comparison = compare_images(image, ref)
    report = {
        "lightcuts_version": __version__,
        "config": str(Path(args.config)),
        "name": cfg.name,
        "seed": cfg.seed,
        "integrator": args.integrator,
        "resolution": [int(image.shape[1]), int(image.shape[0])],
        "crop": cfg.render.crop,
        "comparison": comparison,
        "mitsuba": {**mitsuba_version(), "spp": spp, "max_depth": args.max_depth,
                    "load_seconds": t_load, "render_seconds": t_mi},
        "lightcuts": {**lc, "direct_only": args.integrator == "direct"},
        "phong_approximated": bool((scene.specular.max(axis=1) > 0).any()),
    }
    with output_set(out_dir) as tmp_dir:
        write_exr(tmp_dir / "mitsuba.exr", ref)
        write_png(tmp_dir / "mitsuba.png", ref, cfg.render.exposure)
        write_exr(tmp_dir / "lightcuts.exr", image)
        write_png(tmp_dir / "lightcuts.png", image, cfg.render.exposure)
        save_json(tmp_dir / "report.json", report)
    ratio = comparison["energy_ratio"]
    e, b = comparison["pixel"], comparison.get("block8")
    line = (f"{cfg.name}: {args.integrator}, Mitsuba {spp} spp {t_mi:.2f} s, lightcuts {lc['render_seconds']:.2f} s; "
            + (f"energy lightcuts/Mitsuba {ratio:.4f}" if ratio is not None else "Mitsuba's image is black"))
    line += f"; relative error per pixel median {100 * e['median']:.2f}% p99 {100 * e['p99']:.2f}%"
    if b is not None:
        line += f", 8x8 blocks median {100 * b['median']:.2f}% p99 {100 * b['p99']:.2f}%"
    print(f"{line} -> {out_dir}")
    return report
