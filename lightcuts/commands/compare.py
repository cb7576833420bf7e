r"""``lightcuts compare CONFIG``: the run rendered once per builder (and metric), the 2008 paper's Fig. 8.

Every row uses the same scene, lights and seed; only the trees differ. The scene, ray caster and
lights are made once; per row the trees are built (``Build``: the numba kernels are loaded or
compiled first, on a few lights, and not timed) and the image rendered (``Image time``: after a
one-pixel render that loads the render kernel). ``Preprocess total`` is the shared scene and light
time plus the row's build; ``Summed time`` adds the image time. The error is the per-pixel relative
luminance error against the all-lights reference (:func:`lightcuts.integrators.lightcut.render_reference`)
on one seeded sample of ``--pixels`` pixels, the same for every row (the reference over a whole
100K-light image would take half an hour), over the sampled pixels brighter than 1% of the sample's
mean (:func:`lightcuts.report.images.relative_error`).

Outputs in ``renders/<name>/compare/`` (or ``--out``): ``table.md``, ``table.csv``, ``report.json``
(rows, config, machine), per row ``image-<label>.exr`` / ``.png`` (the config's ``render.tonemap``
for every row) and ``cutsize-<label>.png``, ``cutsizes.png`` with the difference panel of two rows
(``--diff``; by default :func:`lightcuts.pipeline.comparing.default_diff`: two rows whose cut sizes
differ) (:mod:`lightcuts.report.compare`). Finished rows and the reference are kept in ``rows/`` as soon as
they are done (one .npz each, written atomically, with a key of everything they depend on), so an
interrupted compare keeps them and the next run with the same config and seed only computes what is
missing or changed; ``--force`` recomputes everything.

The run itself is :func:`lightcuts.compare`'s (:mod:`lightcuts.pipeline.comparing`: rows, reference,
writer; the store is :mod:`lightcuts.report.compare_store`, the Mitsuba study
:mod:`lightcuts.mitsuba.study`); this module parses the options, resolves the rows and checks
``--diff`` and the output folder before any work, then saves and prints the table. With ``--workers N``
or ``--scheduler ADDRESS`` the reference and the rows run as tasks on a Dask cluster
(:mod:`lightcuts.distributed.studies`), with the same values and the same row store.
"""

from __future__ import annotations

from pathlib import Path

from lightcuts.pipeline.comparing import (ALLOWED, DEFAULT_MITSUBA_SPP, DEFAULT_PIXELS,  # noqa: F401
                                     names, resolve_rows, sample_pixels)
from lightcuts.commands.common import add_set
from lightcuts.distributed.options import add_cluster_options, cluster_spec
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_PASSES, MAX_PIXELS, MAX_REFERENCE_SPP

#: Passes of compare --mitsuba's converging render.
DEFAULT_MITSUBA_PASSES = 8


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="render once per builder: the 2008 paper's Fig. 8 table, cut-size maps")
    p.add_argument("config")
    p.add_argument("--builders", default=None,
                   help="comma-separated builders (default: the paper's four and saoh, see default_builders)")
    p.add_argument("--metrics", default=None,
                   help="comma-separated metrics: a row per metric for each builder that reads one "
                        "(default the config's)")
    p.add_argument("--pixels", type=int, default=DEFAULT_PIXELS,
                   help=f"pixels in the seeded sample the error is measured on (default {DEFAULT_PIXELS}; 0: none)")
    p.add_argument("--diff", default=None,
                   help="a,b: the rows of the signed cut-size difference a - b (default: the first row whose cut sizes "
                        "differ from the baseline divisive-6d's, minus divisive-6d; see default_diff)")
    p.add_argument("--force", action="store_true", help="recompute rows already finished")
    p.add_argument("--mitsuba", action="store_true",
                   help="add Mitsuba 3's path tracer run for the agglomerative row's image time, both against "
                        "a long Mitsuba render (needs pip install 'lightcuts[mitsuba]')")
    p.add_argument("--mitsuba-spp", type=int, default=DEFAULT_MITSUBA_SPP,
                   help=f"samples per pixel of the long Mitsuba render (default {DEFAULT_MITSUBA_SPP})")
    p.add_argument("--mitsuba-passes", type=int, default=DEFAULT_MITSUBA_PASSES,
                   help="with --mitsuba: passes of the converging render (compensation and stochastic "
                        f"representatives where the integrator takes them) compared at its own time "
                        f"(default {DEFAULT_MITSUBA_PASSES}; 0: none)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/compare)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_set(p)
    add_cluster_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_compare(args)
    return 0


def run_compare(args) -> dict:
    """The ``lightcuts compare`` command; returns the report dict (also written to report.json)."""
    from lightcuts.pipeline.comparing import compare_run, converging_config
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.rendering import check_reference_lights
    from lightcuts.config import load_config
    from lightcuts.io import check_output_dir, run_dir
    from lightcuts.report.compare_store import RowStore
    from lightcuts.scene.build import image_size

    cfg = load_config(args.config, args.overrides)
    if not 0 <= args.pixels <= MAX_PIXELS:
        raise LightcutsError(f"--pixels {args.pixels}: must be from 0 to {MAX_PIXELS:,} (lightcuts.limits.MAX_PIXELS)")
    if args.mitsuba:
        from lightcuts.mitsuba import load_mitsuba

        if not 1 <= args.mitsuba_spp <= MAX_REFERENCE_SPP:
            raise LightcutsError(f"--mitsuba-spp {args.mitsuba_spp}: must be from 1 to {MAX_REFERENCE_SPP:,} "
                                 "(lightcuts.limits.MAX_REFERENCE_SPP)")
        if not 0 <= args.mitsuba_passes <= MAX_PASSES:
            raise LightcutsError(f"--mitsuba-passes {args.mitsuba_passes}: must be from 0 to {MAX_PASSES}")
        load_mitsuba()  # one line naming the install command if Mitsuba is missing
    rows = resolve_rows(cfg, args.builders, args.metrics)
    plans = [plan_run(cfg, render=True, tree=spec) for _, spec in rows]
    if args.pixels:
        check_reference_lights(cfg, f"--pixels {args.pixels}", "give --pixels 0 (no error columns) or ")
    if args.mitsuba and args.mitsuba_passes:  # the converging render's passes, checked as a render's
        try:
            plan_run(converging_config(cfg, plans[0].integrator, args.mitsuba_passes), render=True, tree=rows[0][1])
        except LightcutsError as exc:
            raise LightcutsError(f"--mitsuba-passes {args.mitsuba_passes}: the converging render's {exc}") from None
    labels = [label for label, _ in rows]
    diff = None  # chosen when the rows are done (lightcuts.pipeline.comparing.default_diff)
    if args.diff is not None:
        diff = tuple(names(args.diff, "--diff"))
        if len(diff) != 2 or any(d not in labels for d in diff):
            raise LightcutsError(f"--diff {args.diff!r}: expected two different rows of {', '.join(labels)}")
    out = check_output_dir(Path(args.out) if args.out else run_dir(cfg.name, args.overrides) / "compare",
                           "--out" if args.out else "name", ALLOWED)
    width, height = image_size(cfg)
    pixels = sample_pixels(width, height, cfg.render.crop, args.pixels, cfg.seed) if args.pixels else None
    spec = cluster_spec(args)

    def compare(runner=None):
        return compare_run(cfg, plans, labels, pixels, RowStore(out / "rows", args.force),
                           source=str(Path(args.config)), diff=diff,
                           mitsuba_spp=args.mitsuba_spp if args.mitsuba else None,
                           mitsuba_passes=args.mitsuba_passes, progress=not args.no_progress, runner=runner)

    if spec is None:
        result = compare()
    else:
        from lightcuts.distributed.runner import ClusterRunner
        from lightcuts.distributed.session import session_for

        with session_for(spec, plans[0].integrator.trait("kernels")) as session:
            runner = ClusterRunner(session)
            result = compare(runner)
    result.save(out)
    print(result.markdown(), end="")
    d = result.report["diff"]
    print(f"difference panel: {d[0]} - {d[1]} ({result.report['diff_chosen']})" if d else
          f"difference panel: none ({result.report['diff_chosen']})")
    print(f"-> {out}")
    return result.report
