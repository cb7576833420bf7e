"""``lightcuts tree CONFIG`` or ``lightcuts tree --lights FILE...``: lights -> light tree (.npz)."""

from __future__ import annotations

import time
from pathlib import Path

from lightcuts.commands.common import add_set, per_type_path
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_SEED


def add_parser(sub) -> None:
    p = sub.add_parser("tree", help="lights -> light tree (.npz)")
    p.add_argument("config", nargs="?")
    p.add_argument("--lights", nargs="+", metavar="FILE", help="light .npz file(s) instead of a config")
    p.add_argument("--builder", help="builder name (default: the config's, else agglomerative)")
    p.add_argument("--metric", help="clustering metric name, for builders that read one")
    p.add_argument("--c", type=float, default=None,
                   help="cone-term scale, for builders that read it (default: scene diagonal / 16)")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--out", default="tree.npz")
    add_set(p)
    p.set_defaults(func=run)


def _spec(args, cfg):
    """The TreeSpec of the options over the config's tree section. An option replaces its key and is
    refused where the builder does not read it; with ``--builder``, the config's metric and c are
    kept only where the new builder reads them."""
    from lightcuts.trees.spec import config_tree, tree_spec

    builder, metric, c, keys = config_tree(cfg.tree) if cfg is not None else (None, None, None, {})
    if args.builder is not None:
        spec = tree_spec(args.builder, metric, c, {**keys, "builder": "--builder"}, drop_unread=True)
        builder, metric, c = spec.builder, (spec.metric.name if spec.metric else None), spec.c
        keys["builder"] = "--builder"
    if args.metric is not None:
        metric, keys["metric"] = args.metric, "--metric"
    if args.c is not None:
        c, keys["c"] = args.c, "--c"
    return tree_spec(builder, metric, c, keys)


def run(args) -> int:
    from lightcuts.lights import LightSet
    from lightcuts.trees.build import build_tree

    cfg = None
    if not args.lights:
        if not args.config:
            raise LightcutsError("tree: give a CONFIG or --lights FILE")
        from lightcuts.config import load_config

        cfg = load_config(args.config, args.overrides)
    from lightcuts.io import check_output_file

    spec = _spec(args, cfg)  # every name and combination fails here, before any work
    check_output_file(args.out, "--out")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise LightcutsError(f"--seed {args.seed}: must be in [0, {MAX_SEED}]")
    seed = args.seed if args.seed is not None else (cfg.seed if cfg else 0)

    if args.lights:
        from lightcuts.trees.checks import check_lights

        sets = {}
        for p in args.lights:
            ls = LightSet.load(p)
            check_lights(ls, str(p))  # what the build checks, named by the file, before any tree is built
            sets[ls.type] = ls
        name = Path(args.lights[0]).stem
    else:
        from lightcuts.pipeline.plan import plan_run

        plan = plan_run(cfg, tree=spec)
        sets = plan.lights(plan.scene())
        name = cfg.name
    for ls in sets.values():
        spec.check_size(len(ls), "--builder" if args.builder else "tree.builder")
    out = Path(args.out)
    for typ, ls in sets.items():
        t0 = time.perf_counter()
        tree = build_tree(ls, spec, seed=seed)
        dt = time.perf_counter() - t0
        path = per_type_path(out, typ, len(sets))
        tree.save(path)
        used = ", ".join(f"{k} {tree.meta[k]:.6g}" if k == "c" else f"{k} {tree.meta[k]}"
                         for k in ("builder", "metric", "c") if k in tree.meta)
        print(f"{name}: {typ} tree, {len(ls)} lights, {used}: "
              f"{tree.n_nodes} nodes, depth {tree.depth()}, built in {dt:.3f} s -> {path}")
    return 0
