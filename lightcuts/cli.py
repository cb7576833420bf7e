"""Command line: ``lightcuts lights|tree|scaling|render CONFIG``.

User errors (LightcutsError) print one line ``error: ...`` and exit with status 2.
Heavy modules (numba kernels, colour, matplotlib) are imported inside the commands so that
``lightcuts --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from lightcuts.errors import LightcutsError


def _add_set(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set render.eps=0.01 (repeatable)")


def cmd_lights(args) -> int:
    from lightcuts.config import load_config
    from lightcuts.pipeline import make_lights, make_scene

    cfg = load_config(args.config, args.overrides)
    t0 = time.perf_counter()
    scene = make_scene(cfg)
    light_sets = make_lights(cfg, scene)
    dt = time.perf_counter() - t0
    out = Path(args.out)
    written = []
    for typ, ls in light_sets.items():
        path = out if len(light_sets) == 1 else out.with_name(f"{out.stem}-{typ}{out.suffix or '.npz'}")
        written.append(ls.save(path))
    counts = ", ".join(f"{len(ls)} {typ}" for typ, ls in light_sets.items())
    print(f"{cfg.name}: {counts} lights in {dt:.2f} s -> {', '.join(str(p) for p in written)}")
    return 0


def cmd_tree(args) -> int:
    from lightcuts.lights import LightSet
    from lightcuts.trees.build import build_tree
    from lightcuts.trees.registry import get_builder, get_metric

    cfg = None
    if not args.lights:
        if not args.config:
            raise LightcutsError("tree: give a CONFIG or --lights FILE")
        from lightcuts.config import load_config

        cfg = load_config(args.config, args.overrides)
    builder = args.builder or (cfg.tree.builder if cfg else "agglomerative")
    metric = args.metric or (cfg.tree.metric if cfg else "walter2008")
    c = args.c if args.c is not None else (cfg.tree.c if cfg else None)
    seed = args.seed if args.seed is not None else (cfg.seed if cfg else 0)
    get_builder(builder)  # unknown names fail here, before any work
    get_metric(metric)

    if args.lights:
        sets = {}
        for p in args.lights:
            ls = LightSet.load(p)
            sets[ls.type] = ls
        name = Path(args.lights[0]).stem
    else:
        from lightcuts.pipeline import make_lights, make_scene

        sets = make_lights(cfg, make_scene(cfg))
        name = cfg.name
    out = Path(args.out)
    for typ, ls in sets.items():
        t0 = time.perf_counter()
        tree = build_tree(ls, builder=builder, metric=metric, c=c, seed=seed)
        dt = time.perf_counter() - t0
        path = out if len(sets) == 1 else out.with_name(f"{out.stem}-{typ}{out.suffix or '.npz'}")
        tree.save(path)
        print(f"{name}: {typ} tree, {len(ls)} lights, builder {builder}, metric {metric}: "
              f"{tree.n_nodes} nodes, depth {tree.depth()}, built in {dt:.3f} s -> {path}")
    return 0


def cmd_scaling(args) -> int:
    from lightcuts.report.scaling import run_scaling

    run_scaling(args)
    return 0


def cmd_render(args) -> int:
    from lightcuts.render.run import run_render

    run_render(args)
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="lightcuts", description=__doc__.splitlines()[0])
    from lightcuts import __version__

    ap.add_argument("--version", action="version", version=f"lightcuts {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("lights", help="scene -> virtual point lights (.npz)")
    p.add_argument("config")
    p.add_argument("--out", default="lights.npz",
                   help="output .npz; with several light types, one file per type: <stem>-<type>.npz")
    _add_set(p)
    p.set_defaults(func=cmd_lights)

    p = sub.add_parser("tree", help="lights -> light tree (.npz)")
    p.add_argument("config", nargs="?")
    p.add_argument("--lights", nargs="+", metavar="FILE", help="light .npz file(s) instead of a config")
    p.add_argument("--builder", help="builder name (see lightcuts.trees.BUILDERS)")
    p.add_argument("--metric", help="clustering metric name")
    p.add_argument("--c", type=float, default=None, help="metric's cone-term scale (default: diagonal / 16)")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--out", default="tree.npz")
    _add_set(p)
    p.set_defaults(func=cmd_tree)

    p = sub.add_parser("scaling", help="build time of every builder against N (the 2008 paper's Fig. 9)")
    p.add_argument("config")
    p.add_argument("--sizes", default="50000,100000,200000,400000,800000",
                   help="comma-separated light counts")
    p.add_argument("--builders", default=None, help="comma-separated builder names (default: all but greedy)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs per point (median reported)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>-scaling)")
    _add_set(p)
    p.set_defaults(func=cmd_scaling)

    p = sub.add_parser("render", help="render a YAML run to renders/<name>/")
    p.add_argument("config")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>)")
    p.add_argument("--reference", action="store_true",
                   help="also render the brute-force reference (every light, every pixel) and compare")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_set(p)
    p.set_defaults(func=cmd_render)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except LightcutsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
