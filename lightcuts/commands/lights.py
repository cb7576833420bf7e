"""``lightcuts lights CONFIG``: scene -> virtual point lights, one ``.npz`` per light type."""

from __future__ import annotations

import time
from pathlib import Path

from lightcuts.commands.common import add_set, per_type_path


def add_parser(sub) -> None:
    p = sub.add_parser("lights", help="scene -> virtual point lights (.npz)")
    p.add_argument("config")
    p.add_argument("--out", default="lights.npz",
                   help="output .npz; with several light types, one file per type: <stem>-<type>.npz")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    from lightcuts.io import check_output_file

    plan = plan_run(load_config(args.config, args.overrides))
    check_output_file(args.out, "--out")
    t0 = time.perf_counter()
    light_sets = plan.lights(plan.scene())
    dt = time.perf_counter() - t0
    out = Path(args.out)
    written = [ls.save(per_type_path(out, typ, len(light_sets))) for typ, ls in light_sets.items()]
    counts = ", ".join(f"{len(ls)} {typ}" for typ, ls in light_sets.items())
    print(f"{plan.cfg.name}: {counts} lights in {dt:.2f} s -> {', '.join(str(p) for p in written)}")
    return 0
