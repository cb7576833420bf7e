r"""What each command's ``report.html`` shows (:class:`lightcuts.report.html.Page`), from the data
the command writes anyway: its images, rows, plots, config and report.json.

* ``render``: the image, the all-lights reference (``--reference``; the error view's default), the
  cut-size map; the run's figures.
* ``compare``: each row's image and cut-size map (one colour scale), the difference of the two
  ``--diff`` rows' maps, Mitsuba's images; the error view against the all-lights reference where it
  exists, at the sampled pixels only (squares over the dimmed image), or against another row's
  image; the Fig. 8 table.
* ``reference``: lightcuts' and the path tracer's images, the mask of pixels that see an emitter;
  the figures beside the path tracer's own noise; with ``--curve`` the curve's rows and plot, with
  ``--split`` its rows.
* ``study``: the reference and each row's last image, the mask; the rows, their error against time
  (plot) and the ladders' points.
* ``accel`` and ``scaling``: their tables and plots (no images).
"""

from __future__ import annotations

from lightcuts.report.html import Layer, Page, Scale, Table


def _origin(cfg) -> tuple:
    crop = cfg.render.crop
    return (0, 0) if crop is None else (crop[0], crop[1])


def _common(cfg, record: dict | None) -> dict:
    from lightcuts.report.compare import machine

    return {"config": cfg.model_dump(mode="json"), "machine": machine(), "record": record,
            "tonemap": cfg.render.tonemap, "origin": _origin(cfg)}


def render(r) -> Page:
    """The page of ``lightcuts render`` (a :class:`lightcuts.pipeline.rendering.Render`)."""
    rep = r.report
    layers = [Layer("image", r.image)]
    if r.reference is not None:
        layers.append(Layer("reference (all lights)", r.reference))
    layers.append(Layer("cut size", r.cut_size, "cut"))
    row = {"resolution": f"{rep['resolution'][0]}x{rep['resolution'][1]}", "lights": sum(rep["lights"].values()),
           **{k: rep[k] for k in ("builder", "cut_size_mean", "cut_size_max", "shadow_rays_per_pixel",
                                  "preprocess_seconds", "build_seconds", "render_seconds", "image_seconds")}}
    cols = [("resolution", "Resolution", None), ("lights", "Lights", "{:,}"), ("builder", "Builder", None),
            ("cut_size_mean", "Avg cut", "{:.1f}"), ("cut_size_max", "Max cut", "{:.0f}"),
            ("shadow_rays_per_pixel", "Shadow rays / pixel", "{:.1f}"), ("preprocess_seconds", "Preprocess (s)",
                                                                          "{:.2f}"),
            ("build_seconds", "Build (s)", "{:.2f}"), ("render_seconds", "Render (s)", "{:.2f}"),
            ("image_seconds", "Image time (s)", "{:.2f}")]
    if "reference" in rep:
        e = rep["reference"]["relative_error"]
        row.update(err_median=e["median"], err_p99=e["p99"], speedup=rep["reference"]["speedup"])
        cols += [("err_median", "Error median", "{:.3%}"), ("err_p99", "Error p99", "{:.3%}"),
                 ("speedup", "Speed-up over the reference", "{:.0f}x")]
    return Page(f"{rep['name']}: render", r.summary(), layers=layers,
                scales={"cut": Scale(max(1.0, float(r.cut_size.max())), f"cut size ({rep['cut_size_unit']})")},
                reference=1 if r.reference is not None else None, tables=[Table("Run", cols, [row])],
                **_common(r.config, rep))


def compare(c) -> Page:
    """The page of ``lightcuts compare`` (a :class:`lightcuts.pipeline.comparing.Comparison`). The
    difference panel of ``cutsizes.png`` is a layer of its own (the PNG is not embedded: the viewer
    shows each of its maps)."""
    import numpy as np

    from lightcuts.report.compare import COLUMNS, cut_unit, shared_max

    rep, rows = c.report, c.report["rows"]
    unit = cut_unit(rows)
    labels = [r["label"] for r in rows]
    layers = [Layer(label, c.images[label]) for label in labels]
    layers += [Layer(f"cut: {label}", c.cut_sizes[label], "cut") for label in labels]
    scales = {"cut": Scale(shared_max(c.cut_sizes), f"cut size ({unit or 'nodes'})")}
    d = rep.get("diff")
    if d:
        diff = c.cut_sizes[d[0]].astype(np.float64) - c.cut_sizes[d[1]]
        lim = max(1.0, float(np.abs(diff).max()))
        layers.append(Layer(f"cut: {d[0]} - {d[1]}", diff, "diff"))
        scales["diff"] = Scale(lim, f"cut size difference ({unit or 'nodes'})", "RdBu_r", -lim)
    layers += [Layer(f"mitsuba: {name}", image) for name, image in (c.mitsuba_images or {}).items()]
    notes = []
    sample = None
    if c.reference_image is not None:
        x0, y0 = _origin(c.config)
        sample = (c.reference_pixels - [x0, y0], c.reference_image)
        notes.append(f"The all-lights reference is known at {len(c.reference_pixels):,} sampled pixels (the table's "
                     "error columns): the error view against 'reference' shows them as squares.")
    notes.append(f"Difference panel: {d[0]} - {d[1]} ({rep['diff_chosen']})." if d else
                 f"No difference panel ({rep.get('diff_chosen')}).")
    tables = [Table(c.title(), [(k, f"{h} ({unit})" if unit and k in ("cut_mean", "cut_max") else h, f)
                                for k, h, f in COLUMNS], rows)]
    if "mitsuba" in rep:
        tables.append(_mitsuba_table(rep["mitsuba"]))
    return Page(f"{c.config.name}: compare", c.title(), notes=notes, layers=layers, scales=scales, sample=sample,
                tables=tables, **_common(c.config, rep))


def _mitsuba_table(m: dict) -> Table:
    rows = [{"renderer": f"lightcuts ({m['lightcuts_row']})", **m["lightcuts"]},
            {"renderer": f"Mitsuba path, {m['equal_time']['spp']} spp", **m["equal_time"]}]
    if "converging" in m:
        rows += [{"renderer": f"lightcuts ({m['converging']['label']})", **m["converging"]},
                 {"renderer": f"Mitsuba path, {m['converging_equal_time']['spp']} spp", **m["converging_equal_time"]}]
    for r in rows:
        r.update({f"{part}_{k}": r.get(part, {}).get(k) for part in ("pixel", "block8") for k in ("median", "p99")})
    cols = [("renderer", "Renderer", None), ("seconds", "Image time (s)", "{:.2f}"),
            ("energy_ratio", "Energy ratio", "{:.4f}")]
    cols += [(f"{p}_{k}", f"{n} {k}", "{:.2%}") for p, n in (("pixel", "Pixel"), ("block8", "8x8"))
             for k in ("median", "p99")]
    return Table(f"Against Mitsuba's path tracer at {m['reference_spp']} spp, at equal time", cols, rows)


def comparison_table(c: dict, name: str) -> Table:
    """The figures of :func:`lightcuts.report.images.compare_images`, each beside the reference's noise."""
    noise = c.get("reference_noise", {})
    rows = [{"figure": "energy ratio (pixels that see an emitter left out)", "value": c["energy_ratio"],
             "noise": noise.get("energy_ratio")},
            {"figure": "energy ratio, whole frame", "value": c["energy_ratio_frame"]}]
    for part, what in (("pixel", "per pixel"), ("block8", "of 8x8 block means")):
        for k in ("median", "p99"):
            if part in c:
                rows.append({"figure": f"relative error {what}, {k}", "value": c[part][k],
                             "noise": noise.get(part, {}).get(k)})
    note = (f"{c['masked_pixels']:,} pixels that see an emitter directly are left out of every figure but the "
            f"whole-frame ratio. The noise column: what an exact image would show against the {name}'s image, "
            "from its two independent halves (an energy ratio's: its relative standard deviation).")
    return Table(f"lightcuts against the {name}", [("figure", "Figure", None), ("value", "Value", "{:.4g}"),
                                                   ("noise", f"The {name}'s noise", "{:.4g}")], rows, note)


def reference(cfg, report: dict, images: dict, mask=None, reference_name: str | None = None, tables=(),
              plots=()) -> Page:
    """The page of ``lightcuts reference`` (plain, ``--curve`` or ``--split``): ``images`` name ->
    (H, W, 3), in viewer order; ``reference_name``: the one the error view compares with."""
    names = list(images)
    layers = [Layer(n, images[n]) for n in names]
    tracer = report.get("path_tracer", report.get("reference", {})).get("renderer", "")
    return Page(f"{cfg.name}: reference", f"against {tracer} path tracing", layers=layers,
                reference=names.index(reference_name) if reference_name else None,
                mask=mask, tables=list(tables), plots=list(plots), **_common(cfg, report))


def study(s, plot) -> Page:
    """The page of ``lightcuts study`` (a :class:`lightcuts.pipeline.study.Study`): the reference and
    each row's last image (the error view against the reference, emitter pixels grey), the table, the
    plot of error against time (``plot``: its PNG) and the ladder's points."""
    from lightcuts.report.study import POINT_FIELDS, columns, notes, title

    rep = s.report
    layers = [Layer(f"reference ({rep['reference']['renderer']}, {rep['reference']['spp']} spp)", s.reference)]
    layers += [Layer(f"{label} ({r['samples']} {r['ladder']})", s.images[label])
               for label, r in zip(s.images, rep["rows"])]
    formats = {"seconds": "{:.3f}", "samples": "{}"}
    points = Table("Points of the ladders", [(k, k, formats.get(k, None if k in ("label", "ladder") else "{:.4g}"))
                                              for k in POINT_FIELDS], rep["points"])
    return Page(f"{s.config.name}: study", title(rep), notes=notes(rep), layers=layers, reference=0, mask=s.mask,
                tables=[Table("Rows", columns(rep["times"]), rep["rows"]), points],
                plots=[("error against time", plot)], **_common(s.config, rep))


def accel(cfg, report: dict, plots=()) -> Page:
    """The page of ``lightcuts accel`` (and ``--sweep``)."""
    from lightcuts.report.accel import COLUMNS

    rows = [dict(r) for r in report["rows"]]
    for r in rows:
        if r.get("build_tris_per_s") is not None:
            r["build_tris_per_s"] /= 1e6
        if r.get("memory_bytes") is not None:
            r["memory_bytes"] /= 2 ** 20
    cols = [(k, h, f or "{:.2f}") for k, h, f in COLUMNS if any(r.get(k) is not None for r in rows)]
    if "rooms" in report:
        cols.insert(1, ("rooms", "Rooms", "{}"))
    return Page(f"{cfg.name}: ray casters", f"repeats {report['repeats']}", tables=[Table("Ray casters", cols, rows)],
                plots=list(plots), **_common(cfg, report))


def scaling(cfg, tables: list, plots: list) -> Page:
    """The page of ``lightcuts scaling`` (and ``--render``, ``--gather``): ``tables`` (title, fields, rows)."""
    return Page(f"{cfg.name}: scaling", tables=[Table(t, [(k, k, None) for k in fields], rows)
                                               for t, fields, rows in tables], plots=plots,
                **_common(cfg, None))
