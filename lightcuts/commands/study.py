r"""``lightcuts study CONFIG``: the efficiency study, rows of (integrator, builder) on one scene
against one long reference (:mod:`lightcuts.pipeline.study`).

A command of its own rather than a ``compare`` option: compare's rows share one set of lights and
differ only by their trees, and are measured against the integrator's brute-force reference of that
same light set on a sample of pixels; a study's rows are different estimators (other integrators,
Mitsuba's path tracer, the same integrator on other builders), each redrawing its own samples, timed
over a ladder of sample counts and measured over the whole image against a path tracer's long render
whose own noise is estimated. Nothing of compare's row store, cut maps or difference panel applies.

Rows (:mod:`lightcuts.pipeline.study_rows`): ``--row 'SPEC [KEY=VALUE ...]'`` (repeatable) and/or
``--rows FILE.yaml``; default ``lightcuts`` (with its converging settings) and ``path``. ``--builders``
crosses the rows that use light trees with builders. Every row is loaded and planned before any
work; a bad one is one line naming it. The reference: ``--renderer NAME`` (default ``lightcuts``,
the project's exact path tracer; ``mitsuba`` for Mitsuba 3) at ``--reference-spp`` in two halves.
Each row's ladder runs until its time reaches ``--budget`` (default the largest of ``--times``).

Outputs in ``renders/<name>/study/`` (or ``--out``): table.md, table.csv, points.csv, report.json,
error-time.png, reference.exr / .png, image-<row>.exr / .png, report.html; the table is printed.
"""

from __future__ import annotations

import math
from pathlib import Path

from lightcuts.commands.common import add_set
from lightcuts.errors import LightcutsError
from lightcuts.pipeline.study import DEFAULT_REFERENCE_SPP, DEFAULT_TIMES

#: Rows when none are given.
DEFAULT_ROWS = ("lightcuts", "path")
#: The reference renderer when none is given: exact materials.
DEFAULT_STUDY_REFERENCE = "lightcuts"
#: The longest budget and equal time, seconds (a week).
MAX_SECONDS = 7 * 24 * 3600.0


def add_parser(sub) -> None:
    p = sub.add_parser("study", help="efficiency of (integrator, builder) rows against a long reference: relMSE, "
                                     "8x8 RMS, relMSE x seconds, error at equal time, variance ratio of builders")
    p.add_argument("config")
    p.add_argument("--row", dest="rows", action="append", default=[], metavar="'SPEC [KEY=VALUE ...]'",
                   help="a row: SPEC is an integrator NAME or NAME:PARAM=VALUE,... or tracer:NAME (a reference "
                        "renderer's path tracer); dotted KEY=VALUE are the row's config overrides, plain ones its "
                        "options label=, builders=A,B, ladder=passes|spp, samples=1,4,16, converging=false "
                        f"(repeatable; default {' and '.join(DEFAULT_ROWS)})")
    p.add_argument("--rows", dest="rows_file", default=None, metavar="FILE.yaml",
                   help="rows from a YAML file: a list of row texts or mappings (integrator or tracer, set, options)")
    p.add_argument("--builders", default=None,
                   help="comma-separated builders crossed with every row that uses light trees and names none "
                        "(default the config's tree.builder)")
    p.add_argument("--renderer", default=DEFAULT_STUDY_REFERENCE,
                   help="the reference's renderer, as lightcuts reference's (`lightcuts plugins references`; default "
                        f"{DEFAULT_STUDY_REFERENCE}, the exact BRDF; mitsuba: Mitsuba 3)")
    p.add_argument("--reference-spp", type=int, default=DEFAULT_REFERENCE_SPP,
                   help=f"the reference's samples per pixel, in two independent halves (default {DEFAULT_REFERENCE_SPP})")
    p.add_argument("--times", default=",".join(f"{t:g}" for t in DEFAULT_TIMES),
                   help="comma-separated seconds of the error at equal time (default 10,60)")
    p.add_argument("--budget", type=float, default=None,
                   help="seconds each row's ladder runs to (default the largest of --times)")
    p.add_argument("--epsilon", type=float, default=None, help="relMSE's epsilon (default 0.01)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/study)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_study(args)
    return 0


def parse_times(text) -> list[float]:
    """``--times``: comma-separated positive seconds, increasing, at most MAX_POINTS."""
    from lightcuts.limits import MAX_POINTS

    try:
        times = [float(t) for t in str(text).split(",")]
    except ValueError:
        raise LightcutsError(f"--times {text!r}: expected comma-separated seconds, e.g. 10,60") from None
    if (not times or len(times) > MAX_POINTS or any(not (0 < t <= MAX_SECONDS) for t in times)
            or any(b <= a for a, b in zip(times, times[1:]))):
        raise LightcutsError(f"--times {text!r}: expected 1 to {MAX_POINTS} increasing seconds, each above 0 and "
                             f"at most {MAX_SECONDS:g}")
    return times


def run_study(args) -> dict:
    """The ``lightcuts study`` command; returns the report dict (also written to report.json)."""
    from lightcuts.config import load_config
    from lightcuts.integrators.references import make_reference
    from lightcuts.io import check_output_dir, run_dir
    from lightcuts.limits import MAX_REFERENCE_SPP
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.study import ALLOWED, study_run
    from lightcuts.pipeline.study_rows import parse_row, read_rows, resolve_rows

    cfg = load_config(args.config, args.overrides)
    plan = plan_run(cfg, render=True)
    times = parse_times(args.times)
    budget = max(times) if args.budget is None else args.budget
    if not (0 < budget <= MAX_SECONDS):
        raise LightcutsError(f"--budget {args.budget}: expected seconds above 0 and at most {MAX_SECONDS:g}")
    if args.epsilon is not None and not (0 < args.epsilon < math.inf):
        raise LightcutsError(f"--epsilon {args.epsilon}: expected a positive number")
    if not 2 <= args.reference_spp <= MAX_REFERENCE_SPP:
        raise LightcutsError(f"--reference-spp {args.reference_spp}: must be from 2 to {MAX_REFERENCE_SPP:,} "
                             "(lightcuts.limits.MAX_REFERENCE_SPP; two halves)")
    tracer = make_reference(args.renderer)
    try:
        tracer.check(cfg, "path")
    finally:
        tracer.close()
    given = [(f"--row {text!r}", parse_row(text, f"--row {text!r}")) for text in args.rows]
    if args.rows_file is not None:
        given += read_rows(args.rows_file)
    if not given:
        given = [(f"default row {text!r}", parse_row(text, f"default row {text!r}")) for text in DEFAULT_ROWS]
    rows = resolve_rows(args.config, args.overrides, given, args.builders)
    out = check_output_dir(Path(args.out) if args.out else run_dir(cfg.name, args.overrides) / "study",
                           "--out" if args.out else "name", ALLOWED)
    result = study_run(cfg, plan, rows, reference=args.renderer, reference_spp=args.reference_spp, times=times,
                       budget=budget, epsilon=args.epsilon, source=str(Path(args.config)),
                       progress=not args.no_progress)
    result.save(out)
    print(result.markdown(), end="")
    print(f"-> {out}")
    return result.report
