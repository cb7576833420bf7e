"""``lightcuts render CONFIG``: config -> plan -> scene -> lights -> trees -> image, outputs and report.

Outputs in ``renders/<name>/`` (or ``--out``), written as one set (:func:`lightcuts.io.output_set`):
``image.exr`` (linear float RGB), ``image.png`` (sRGB, ``render.exposure`` stops), ``cutsize.png``
(false-colour cut size per pixel), ``report.json``; with ``--reference`` also ``reference.exr`` and
``reference.png``, and the lightcuts-vs-reference error in the report. The run itself is
:func:`lightcuts.render`'s (:mod:`lightcuts.pipeline.rendering`); this module parses the options, checks the
output folder before any work, saves and prints the summary line. With ``--workers N`` or
``--scheduler ADDRESS`` the image is rendered as tiles on a Dask cluster (:mod:`lightcuts.distributed`),
the same bytes.
"""

from __future__ import annotations

from pathlib import Path

from lightcuts.commands.common import add_set
from lightcuts.config import load_config
from lightcuts.distributed.options import add_cluster_options, cluster_spec


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a YAML run to renders/<name>/")
    p.add_argument("config")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>)")
    p.add_argument("--reference", action="store_true",
                   help="also render the brute-force reference (every light, every pixel) and compare")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set(p)
    add_cluster_options(p, tiles=True)
    p.set_defaults(func=run)


def run(args) -> int:
    run_render(args)
    return 0


def run_render(args) -> dict:
    """Run a render as the CLI does; returns the report dict (also written to report.json)."""
    from lightcuts.pipeline.rendering import check_reference, render_run
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.io import check_output_dir, run_dir

    cfg = load_config(args.config, args.overrides)  # every config error surfaces here, before any work
    plan = plan_run(cfg, render=True)
    if args.reference:
        check_reference(cfg, plan.integrator)
    out_dir = check_output_dir(Path(args.out) if args.out else run_dir(cfg.name, args.overrides),
                               "--out" if args.out else "name")
    spec = cluster_spec(args)
    if spec is None:
        result = render_run(cfg, plan, str(Path(args.config)), args.reference, not args.no_progress)
    else:
        from lightcuts.distributed.runner import ClusterRunner
        from lightcuts.distributed.session import session_for

        with session_for(spec, plan.integrator.trait("kernels")) as session:
            runner = ClusterRunner(session, spec.tile_size)
            result = render_run(cfg, plan, str(Path(args.config)), args.reference, not args.no_progress, runner)
    result.save(out_dir)
    print(f"{result.summary()} -> {out_dir}")
    return result.report
