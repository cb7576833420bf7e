"""``lightcuts render CONFIG``: config -> plan -> scene -> lights -> trees -> image, outputs and report.

Outputs in ``renders/<name>/`` (or ``--out``), written as one set (:func:`lightcuts.io.output_set`):
``image.exr`` (linear float RGB), ``image.png`` (sRGB, ``render.exposure`` stops), ``cutsize.png``
(false-colour cut size per pixel), ``report.json``; with ``--reference`` also ``reference.exr`` and
``reference.png``, and the lightcuts-vs-reference error in the report.
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

from lightcuts.commands.common import add_set, progress_bar, render_settings, render_timed
from lightcuts.config import load_config


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a YAML run to renders/<name>/")
    p.add_argument("config")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>)")
    p.add_argument("--reference", action="store_true",
                   help="also render the brute-force reference (every light, every pixel) and compare")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_render(args)
    return 0


def run_render(args) -> dict:
    """Run a render as the CLI does; returns the report dict (also written to report.json)."""
    from lightcuts.commands.plan import plan_run
    from lightcuts.commands.warmup import finish_warmup
    from lightcuts.io import check_output_dir

    cfg = load_config(args.config, args.overrides)  # every config error surfaces here, before any work
    plan = plan_run(cfg, render=True)
    out_dir = check_output_dir(Path(args.out) if args.out else Path("renders") / cfg.name,
                               "--out" if args.out else "name")
    warmup = []  # the child compiling the render kernel, if any
    try:
        return _run(args, cfg, plan, out_dir, warmup)
    finally:
        finish_warmup(warmup[0] if warmup else None, timeout=0)


def _run(args, cfg, plan, out_dir: Path, warmup: list) -> dict:
    from lightcuts import __version__
    from lightcuts.commands.plan import tree_meta
    from lightcuts.commands.warmup import finish_warmup, start_render_warmup
    from lightcuts.io import SUBRUN_FOLDERS, output_set, save_json
    from lightcuts.render.integrator import render_reference
    from lightcuts.report.images import relative_error, write_exr, write_heatmap, write_png

    t0 = time.perf_counter()
    scene = plan.scene()
    if plan.caster.trait("warm_render_kernel", False):
        warmup.append(start_render_warmup())  # None where the render kernel is cached
    caster = plan.make_caster(scene)
    envmap = plan.environment()
    light_sets = plan.lights(scene, caster, envmap)
    t_pre = time.perf_counter() - t0

    t0 = time.perf_counter()
    trees = plan.trees(light_sets)
    t_build = time.perf_counter() - t0
    used = tree_meta(trees)

    common = render_settings(cfg, scene.camera, envmap)
    # The wait for numba (the child compiling the render kernel, then loading it) is reported on its own.
    t0 = time.perf_counter()
    finish_warmup(warmup[0] if warmup else None)
    t_wait = time.perf_counter() - t0
    result, t_render, t_load = render_timed(cfg, scene, caster, light_sets, trees, envmap, f"{cfg.name}: lightcuts",
                                            args.no_progress)
    t_jit = t_wait + t_load
    rows = result.image.shape[0]

    n_pixels = result.image.shape[0] * result.image.shape[1]
    report = {
        "lightcuts_version": __version__,
        "config": str(Path(args.config)),
        "name": cfg.name,
        "seed": cfg.seed,
        "scene": {"name": scene.name, "triangles": scene.n_faces, "emitters": int(len(scene.emitters)),
                  "diagonal": scene.diagonal},
        "lights": {typ: len(ls) for typ, ls in light_sets.items()},
        "lights_indirect": int(sum(int(ls.indirect.sum()) for ls in light_sets.values())),
        "builder": used["builder"],
        "metric": used["metric"],
        "c": used["c"],
        "eps": cfg.render.eps,
        "max_cut": cfg.render.max_cut,
        "ray_caster": plan.caster.record(),
        "resolution": [int(result.image.shape[1]), int(result.image.shape[0])],
        "crop": cfg.render.crop,
        "spp": cfg.render.spp,
        "clamping": {"enabled": cfg.render.clamp.enabled, "min_distance": cfg.render.clamp.min_distance,
                     "clamped_energy_fraction": float(result.clamped_fraction)},
        "preprocess_seconds": t_pre,
        "jit_seconds": t_jit,
        "build_seconds": t_build,
        "render_seconds": t_render,
        "cut_size_mean": float(result.cut_size.mean()),
        "cut_size_max": float(result.cut_size.max()),
        "eye_rays": int(result.eye_rays),
        "shadow_rays": int(result.shadow_rays),
        "shadow_rays_per_pixel": float(result.shadow_rays) / n_pixels,
        "rays_per_second": float(result.eye_rays + result.shadow_rays) / max(t_render, 1e-9),
        "threads": _threads(),
        "machine": platform.machine(),
    }

    with output_set(out_dir, keep=SUBRUN_FOLDERS) as tmp_dir:
        write_exr(tmp_dir / "image.exr", result.image)
        write_png(tmp_dir / "image.png", result.image, cfg.render.exposure)
        write_heatmap(tmp_dir / "cutsize.png", result.cut_size,
                      title=f"{cfg.name}: {used['builder']}, eps {cfg.render.eps:g}, "
                            f"mean cut {report['cut_size_mean']:.0f}")

        if args.reference:
            with progress_bar(rows, f"{cfg.name}: reference", args.no_progress) as bar:
                t0 = time.perf_counter()
                ref = render_reference(scene, caster, light_sets, progress=bar.update, **common)
                t_ref = time.perf_counter() - t0
            write_exr(tmp_dir / "reference.exr", ref.image)
            write_png(tmp_dir / "reference.png", ref.image, cfg.render.exposure)
            report["reference"] = {"render_seconds": t_ref, "shadow_rays": int(ref.shadow_rays),
                                   "speedup": t_ref / max(t_render, 1e-9),
                                   "relative_error": relative_error(result.image, ref.image)}

        save_json(tmp_dir / "report.json", report)
    line = (f"{cfg.name}: {report['resolution'][0]}x{report['resolution'][1]}, "
            f"{sum(len(ls) for ls in light_sets.values())} lights, builder {used['builder']}: "
            f"cut {report['cut_size_mean']:.1f} avg / {report['cut_size_max']:.0f} max, "
            f"{report['shadow_rays_per_pixel']:.1f} shadow rays/pixel, "
            f"preprocess {t_pre:.2f} s, build {t_build:.2f} s, render {t_render:.2f} s")
    if args.reference:
        e = report["reference"]["relative_error"]
        line += (f"; vs reference: median {100 * e['median']:.2f}%, p99 {100 * e['p99']:.2f}%, "
                 f"speed-up {report['reference']['speedup']:.0f}x")
    print(f"{line} -> {out_dir}")
    return report


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())
