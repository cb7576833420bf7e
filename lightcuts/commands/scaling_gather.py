r"""``lightcuts scaling CONFIG --gather 1,4,16,64,256``: image time and cut size against the number of
gather points per pixel, the per-eye-ray lightcut against the multidimensional cut (Walter et al.
2006, its scaling in samples per pixel).

The config's own scene, lights (every type it asks for) and trees (its ``tree.builder``) are made
once; for every count G the image is rendered with both integrators: ``lightcuts`` at
``render.spp = G`` (a lightcut per eye ray) and ``multidimensional`` with G gather points per pixel
(the config's ``render.integrator`` parameters for the one it names, the defaults for the other), each
after an untimed one-pixel render that loads its kernel (:func:`lightcuts.pipeline.timing.render_timed`).
Both see the same eye rays, so their images differ only by their cuts' errors. Other settings
(eps, max_cut, clamping, crop) are the config's; ``render.max_cut`` is the budget per eye ray of
both (a multidimensional cut over G gather points holds up to max_cut x G pairs).

Per (G, integrator) a row of ``gather_scaling.csv`` (:data:`lightcuts.report.scaling.GATHER_CSV_FIELDS`):
``cut_per_pixel`` is what a pixel evaluates, light nodes over its G eye rays for ``lightcuts`` (its
mean cut per eye ray times G), (gather, light) pairs for ``multidimensional``; ``image_diff_*`` is
the relative luminance difference of the multidimensional image from the lightcut's at the same G
(:func:`lightcuts.report.images.relative_error`; blank on the lightcuts rows), 0 up to rounding at
G = 1, where both compute the same cut. ``gather_scaling.png``: log-log image time and cut per pixel
against G, each integrator's fitted exponent in the legend; ``report.html``. The files are the run's output set
(:func:`lightcuts.io.output_set`): they replace the folder's previous set, build scaling's included.

A study of its own: not combined with ``--sizes``, ``--render``, ``--builders`` or ``--repeats``
(one timed render per point), and not with a lens (``camera.aperture > 0``: the lightcuts
integrator renders a pinhole camera only).
"""

from __future__ import annotations

import json
from pathlib import Path

from lightcuts.errors import LightcutsError


def compared() -> list:
    """The integrators compared, in the CSV's order per gather count: those of
    lightcuts.integrators.registry.INTEGRATORS declaring ``cuts_per``, a cut per eye ray before a cut
    per pixel."""
    from lightcuts.integrators.registry import INTEGRATORS

    order = ("eye ray", "pixel")
    return sorted((e for e in INTEGRATORS.entries() if e.trait("cuts_per") in order),
                  key=lambda e: (order.index(e.trait("cuts_per")), e.name))
#: Options of build scaling that a gather run refuses.
_BUILD_OPTIONS = (("sizes", "--sizes"), ("render", "--render"), ("builders", "--builders"), ("repeats", "--repeats"))


def check_options(args) -> None:
    """LightcutsError naming ``--gather`` when a build-scaling option is given with it."""
    given = [flag for attr, flag in _BUILD_OPTIONS if getattr(args, attr, None) not in (None, False)]
    if given:
        raise LightcutsError(f"--gather: not combined with {', '.join(given)} (it renders the config's own lights "
                             f"through its tree.builder, one timed render per point)")


def plan_gather(config: str, overrides: list, gathers: list[int]) -> tuple[object, list]:
    """The base plan and [(G, integrator name, plan), ...] for every gather count and integrator,
    each config the base with ``render.spp = G`` and ``render.integrator`` set; LightcutsError
    before any work for a lens or a bad config."""
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    base = plan_run(load_config(config, overrides), render=True)
    entries = compared()
    pinhole = [e.name for e in entries if not e.trait("lens")]
    if base.cfg.camera.aperture > 0 and pinhole:
        raise LightcutsError(f"--gather: camera.aperture {base.cfg.camera.aperture:g}: the {pinhole[0]} integrator it "
                             f"is compared with renders a pinhole camera only; give --set camera.aperture=0")
    # the config's own integrator keeps its parameters; the others take their defaults
    specs = {e.name: base.integrator.record() if e is base.integrator.entry else {"type": e.name}
             for e in entries}
    points = []
    for g in gathers:
        for name in specs:
            cfg = load_config(config, list(overrides) + [f"render.spp={g}",
                                                         f"render.integrator={json.dumps(specs[name])}"])
            points.append((g, name, plan_run(cfg, render=True)))
    return base, points


def run_gather(args, gathers: list[int]) -> list[dict]:
    """The ``lightcuts scaling --gather`` study (args: config, overrides, out, no_progress); returns
    the rows (also written to ``gather_scaling.csv``)."""
    from lightcuts.pipeline.timing import progress_bar, render_timed
    from lightcuts.io import check_output_dir, output_set, save_csv
    from lightcuts.report import pages
    from lightcuts.report.html import write_report
    from lightcuts.report.images import relative_error
    from lightcuts.report.scaling import GATHER_CSV_FIELDS, format_gather_table, plot_gather_scaling

    check_options(args)
    overrides = list(args.overrides or [])
    base, points = plan_gather(args.config, overrides, gathers)
    cfg = base.cfg
    out = check_output_dir(Path(args.out) if args.out else Path("renders") / f"{cfg.name}-scaling",
                           "--out" if args.out else "name")
    scene = base.scene()
    with base.make_caster(scene) as caster:
        envmap = base.environment()
        lights = base.lights(scene, caster, envmap)
        trees = base.trees(lights)
        rows, pinhole = [], None  # the lightcut's image at the current G
        with progress_bar(len(points), "gather scaling", getattr(args, "no_progress", False), unit="image") as bar:
            for g, name, plan in points:
                bar.set_postfix_str(f"G={g} {name}")
                result, seconds, _ = render_timed(plan.cfg, scene, caster, lights, trees, envmap, no_progress=True,
                                                  integrator=plan.integrator)
                per_eye_ray = plan.integrator.trait("cuts_per") == "eye ray"
                per_pixel = float(result.cut_size.mean()) * (g if per_eye_ray else 1)
                max_pixel = float(result.cut_size.max()) * (g if per_eye_ray else 1)
                row = dict(gather=g, integrator=name, image_s=seconds, cut_per_pixel=per_pixel,
                           shadow_rays_per_pixel=result.shadow_rays / result.cut_size.size,
                           cut_per_gather=per_pixel / g, cut_max_per_pixel=max_pixel,
                           n_lights=sum(len(ls) for ls in lights.values()), image_diff_median=None,
                           image_diff_max=None)
                if per_eye_ray:
                    pinhole = result.image
                else:
                    diff = relative_error(result.image, pinhole)
                    row.update(image_diff_median=diff["median"], image_diff_max=diff["max"])
                rows.append(row)
                bar.update(1)
    title = (f"{cfg.name}: {scene.camera.width}x{scene.camera.height}, {rows[0]['n_lights']:,} lights, "
             f"eps {cfg.render.eps:g}")
    with output_set(out) as tmp:
        save_csv(tmp / "gather_scaling.csv", rows, GATHER_CSV_FIELDS)
        plot_gather_scaling(tmp / "gather_scaling.png", rows, title)
        write_report(tmp / "report.html", pages.scaling(cfg, [("Gather points", GATHER_CSV_FIELDS, rows)],
                                                        [("gather points", tmp / "gather_scaling.png")]))
    print(format_gather_table(rows))
    print(f"-> {out}")
    return rows
