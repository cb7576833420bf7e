r"""``lightcuts scaling CONFIG``: light-tree build time against the number of lights (the 2008 paper's Fig. 9).

For every size N, the config's scene gets N indirect VPLs (``lights.indirect.count = N``, no direct
lights, no sun or environment); every builder builds a tree over them (``build_tree``: topology plus
bounds, cones, intensities and representatives), once to warm up numba and then ``repeats`` timed
runs, of which the median is reported. Each builder gets only the config's metric and c that it
reads. Outputs, written as one set (:func:`lightcuts.io.output_set`) to ``--out`` (default
``renders/<name>-scaling/``):

- ``scaling.csv``: n_requested, n_lights, builder, median_s, min_s, repeats, depth;
- ``scaling.png``: log-log build time against N per builder, O(N) and O(N^2) trend lines, and each
  builder's fitted exponent in the legend;
- ``report.html``: the tables and plots, config and machine (:mod:`lightcuts.report.pages`).

With ``--render`` (default sizes 10K, 30K, 100K, 300K and 1M) every tree also renders the config's
image (after an untimed one-pixel render that loads the render kernel), the 2005 paper's point that
the cut grows far slower than N; added to the set:

- ``render_scaling.csv``: n_requested, n_lights, builder, cut_mean, cut_max, shadow_rays_per_pixel,
  render_s;
- ``render_scaling.png``: log-log average cut size and render time against N, with fitted exponents.

The particle tracer returns about N VPLs (its paths end by Russian roulette), so the plots use the
actual count. Timings are wall-clock on a possibly shared machine: compare builders within a run.

With ``--gather 1,4,16,64,256`` the command instead renders the config's own image at each number
of gather points per pixel with the lightcuts and the multidimensional integrator
(:mod:`lightcuts.commands.scaling_gather`): ``gather_scaling.csv`` and ``gather_scaling.png``.

With ``--workers N`` or ``--scheduler ADDRESS`` (not with ``--gather``) the points run as tasks on a
Dask cluster (:func:`lightcuts.distributed.studies.scaling_points`): the VPLs of each count traced on a
worker, each (count, builder) timed there with the worker's share of the cores; counts, depths and
cuts are those of the local run.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from lightcuts.commands.common import add_set
from lightcuts.pipeline.timing import progress_bar
from lightcuts.distributed.options import add_cluster_options, cluster_spec
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_LIGHTS, MAX_POINTS, MAX_REPEATS, MAX_SPP


BUILD_SIZES = "50000,100000,200000,400000,800000"
REPEATS = 3
RENDER_SIZES = "10000,30000,100000,300000,1000000"


def add_parser(sub) -> None:
    p = sub.add_parser("scaling", help="build time of every builder against N (the 2008 paper's Fig. 9)")
    p.add_argument("config")
    p.add_argument("--sizes", default=None,
                   help=f"comma-separated light counts (default {BUILD_SIZES}; with --render {RENDER_SIZES})")
    p.add_argument("--render", action="store_true",
                   help="also render each tree: cut size, shadow rays and render time against N")
    p.add_argument("--gather", default=None,
                   help="comma-separated gather points per pixel, e.g. 1,4,16,64,256: instead of build scaling, "
                        "the config's image with the lightcuts and the multidimensional integrator at each count")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--builders", default=None,
                   help="comma-separated builder names (default: every builder without a size limit)")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"timed builds per point (median reported; default {REPEATS})")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>-scaling)")
    add_set(p)
    add_cluster_options(p)
    p.set_defaults(func=run)


def parse_sizes(text: str, option: str = "--sizes", hi: int = MAX_LIGHTS, what: str = "lights",
                limit: str = "MAX_LIGHTS") -> list[int]:
    """``"50000,100000"`` -> [50000, 100000] (sorted, each once); LightcutsError naming ``option``
    for anything but positive integers, for a value above ``hi`` (``what``, the name of the limit
    ``limit`` in lightcuts.limits) and for more than MAX_POINTS values."""
    try:
        sizes = [int(s) for s in str(text).replace(" ", "").split(",") if s]
    except ValueError:
        raise LightcutsError(f"{option} {text!r}: expected comma-separated positive integers") from None
    if not sizes or min(sizes) < 1:
        raise LightcutsError(f"{option} {text!r}: expected comma-separated positive integers")
    if max(sizes) > hi:
        raise LightcutsError(f"{option}: {max(sizes):,} is more than {hi:,} {what} (lightcuts.limits.{limit})")
    sizes = sorted(set(sizes))
    if len(sizes) > MAX_POINTS:
        raise LightcutsError(f"{option}: {len(sizes)} values, more than {MAX_POINTS} points "
                             "(lightcuts.limits.MAX_POINTS)")
    return sizes


def resolve_specs(text: str | None, cfg) -> list:
    """TreeSpecs from ``--builders`` (default: every builder without a ``max_lights`` limit), each
    with the config's metric and c where it reads them."""
    from lightcuts.trees.registry import BUILDERS
    from lightcuts.trees.spec import config_tree, tree_spec

    if text is None:
        names = [e.name for e in BUILDERS.entries() if e.trait("max_lights") is None]
    else:
        names = [b.strip() for b in text.split(",") if b.strip()]
        if not names:
            raise LightcutsError("--builders: no builder names given")
    _, metric, c, keys = config_tree(cfg.tree)
    return [tree_spec(b, metric, c, {**keys, "builder": "--builders"}, drop_unread=True) for b in names]


def time_builder(lights, spec, repeats: int, seed: int) -> tuple[float, float, object]:
    """(median s, min s, tree) of ``repeats`` timed build_tree calls (the caller warms up numba)."""
    from lightcuts.trees.build import build_tree

    times = []
    tree = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        tree = build_tree(lights, spec, seed=seed)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), tree


def run(args) -> int:
    run_scaling(args)
    return 0


def run_scaling(args) -> list[dict]:
    """The ``lightcuts scaling`` command (args: config, overrides, sizes, builders, repeats, out;
    gather: the gather-point study instead, :func:`lightcuts.commands.scaling_gather.run_gather`).

    Returns the table rows (also written to ``scaling.csv``; with gather, ``gather_scaling.csv``).
    """
    if getattr(args, "gather", None) is not None:
        from lightcuts.commands.scaling_gather import run_gather

        if cluster_spec(args) is not None:
            raise LightcutsError("--gather: the gather study runs on this machine only; leave out --workers and "
                                 "--scheduler")

        return run_gather(args, parse_sizes(args.gather, "--gather", MAX_SPP, "gather points per pixel", "MAX_SPP"))
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.io import check_output_dir, output_set, save_csv
    from lightcuts.report import pages
    from lightcuts.report.html import write_report
    from lightcuts.report.scaling import (CSV_FIELDS, RENDER_CSV_FIELDS, format_render_table, format_table,
                                          plot_render_scaling, plot_scaling)

    render = bool(getattr(args, "render", False))
    sizes = parse_sizes(args.sizes if args.sizes is not None else (RENDER_SIZES if render else BUILD_SIZES))
    repeats = int(args.repeats) if args.repeats is not None else REPEATS
    if not 1 <= repeats <= MAX_REPEATS:
        raise LightcutsError(f"--repeats {repeats}: must be from 1 to {MAX_REPEATS} (lightcuts.limits.MAX_REPEATS)")
    overrides = list(args.overrides or [])
    base = overrides + ["lights.direct.count=0", "lights.sun=null", "lights.environment=null"]
    cfg = load_config(args.config, base + [f"lights.indirect.count={sizes[0]}"])
    specs = resolve_specs(args.builders, cfg)
    for spec in specs:
        spec.check_size(max(sizes), "--builders")
    plan = plan_run(cfg, render=render, tree=specs[0])
    if render and not plan.uses_trees:
        raise LightcutsError(f"render.integrator: integrator {plan.integrator.name!r} does not render from the "
                             "config's light trees, whose cut and render time --render measures against N; use "
                             "render.integrator: lightcuts (or another integrator that renders through light trees)")
    out = check_output_dir(Path(args.out) if args.out else Path("renders") / f"{cfg.name}-scaling",
                           "--out" if args.out else "name")
    point_cfgs = [load_config(args.config, base + [f"lights.indirect.count={n}"]) for n in sizes]
    spec_cluster = cluster_spec(args)
    point = functools.partial(scaling_point, repeats=repeats, render=render)
    no_progress = getattr(args, "no_progress", False)
    scene = plan.scene()
    if spec_cluster is None:
        caster = plan.make_caster(scene)
        points = []
        warmed = set()
        with progress_bar(len(sizes) * len(specs), "scaling", no_progress, unit="tree") as bar:
            for pcfg in point_cfgs:
                bar.set_postfix_str(f"tracing {pcfg.lights.indirect.count} VPLs")
                lights = point_lights(pcfg, scene, caster)
                for spec in specs:
                    bar.set_postfix_str(f"N={len(lights)} {spec.name}")
                    points.append(point(pcfg, scene, caster, lights, spec, spec.name not in warmed))
                    warmed.add(spec.name)
                    bar.update(1)
    else:
        from lightcuts.distributed.runner import ClusterRunner
        from lightcuts.distributed.session import session_for

        with session_for(spec_cluster, plan.integrator.trait("kernels") if render else None) as session:
            runner = ClusterRunner(session)
            points = runner.scaling_points(cfg, scene, point_cfgs, specs, point_lights, point, not no_progress)
    rows = [p[0] for p in points]
    render_rows = [p[1] for p in points if p[1] is not None]
    metric = next((s.metric.name for s in specs if s.metric is not None), None)
    with output_set(out) as tmp:
        save_csv(tmp / "scaling.csv", rows, CSV_FIELDS)
        plot_scaling(tmp / "scaling.png", rows, f"{cfg.name}: light tree build time"
                     f"{f' ({metric})' if metric else ''}, median of {repeats}")
        if render:
            save_csv(tmp / "render_scaling.csv", render_rows, RENDER_CSV_FIELDS)
            plot_render_scaling(tmp / "render_scaling.png", render_rows,
                                f"{cfg.name}: {scene.camera.width}x{scene.camera.height}, eps {cfg.render.eps:g}")
        tables = [("Build time", CSV_FIELDS, rows)] + ([("Render", RENDER_CSV_FIELDS, render_rows)] if render else [])
        plots = [("build time", tmp / "scaling.png")] + ([("render", tmp / "render_scaling.png")] if render else [])
        write_report(tmp / "report.html", pages.scaling(cfg, tables, plots))
    print(format_table(rows))
    if render:
        print(format_render_table(render_rows))
    print(f"-> {out}")
    return rows + render_rows


def point_lights(point_cfg, scene, caster):
    """The oriented VPLs of one light count (``point_cfg``: the config with that
    ``lights.indirect.count``)."""
    from lightcuts.pipeline.plan import plan_run

    return plan_run(point_cfg).lights(scene, caster)["oriented"]


def scaling_point(point_cfg, scene, caster, lights, spec, warm: bool, repeats: int, render: bool) -> tuple:
    """One (light count, builder) point: (scaling.csv row, render_scaling.csv row or None). ``warm``:
    build once untimed first (numba compiles or loads the builder's kernels on its first call)."""
    seed = point_cfg.seed
    if warm:
        time_builder(lights, spec, 1, seed)
    med, best, tree = time_builder(lights, spec, repeats, seed)
    n = point_cfg.lights.indirect.count
    row = dict(n_requested=n, n_lights=len(lights), builder=spec.name, median_s=med, min_s=best, repeats=repeats,
               depth=tree.depth())
    if not render:
        return row, None
    return row, dict(n_requested=n, n_lights=len(lights), builder=spec.name,
                     **_render_stats(point_cfg, scene, caster, lights, tree))


def _render_stats(cfg, scene, caster, lights, tree) -> dict:
    """Average and largest cut, shadow rays per pixel and render seconds of the config's image
    lit by ``lights`` through ``tree``."""
    from lightcuts.pipeline.timing import render_timed

    result, seconds, _ = render_timed(cfg, scene, caster, {lights.type: lights}, {lights.type: tree},
                                      no_progress=True)
    return dict(cut_mean=float(result.cut_size.mean()), cut_max=float(result.cut_size.max()),
                shadow_rays_per_pixel=result.shadow_rays / result.cut_size.size, render_s=seconds)
