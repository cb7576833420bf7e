r"""The efficiency study (``lightcuts study``): rows of (integrator, builder) on one scene, each
rendered at a ladder of sample counts and measured against one long reference (:class:`Study`).

The scene, ray caster, environment and the mask of pixels that see an emitter are made once. The
reference is a reference renderer's path tracer (:data:`lightcuts.integrators.references.REFERENCES`)
at ``reference_spp`` samples per pixel, rendered as two independent halves (seeds of their own,
:func:`reference_seeds`, apart from every row's) whose mean is the reference and whose difference
estimates its own noise (:func:`lightcuts.report.efficiency.reference_figures`). Each row (resolved
by :mod:`lightcuts.pipeline.study_rows`) runs its ladder in this process: with ``passes``, pass p
(seed :func:`lightcuts.pipeline.passes.pass_seed`) makes its lights and trees and renders, and the
running mean after 1, 2, 4, ... passes is a point, its time the passes' summed :func:`image_seconds`
(so the point is the image of ``render.passes`` at that count, byte for byte); with ``spp``, each
point is its own render at ``render.spp`` = 1, 2, 4, ... The ladder stops at the first point whose
time reaches the budget (a ``passes`` ladder at that very pass, a point of its own), at the row's
largest count, or at the end of its given counts. Every point is measured
(:func:`lightcuts.report.efficiency.measure`); a row's figures are its last point's, its error at
each of ``times`` interpolated in log-log, and for rows that differ only by their builder the
relMSE over the best builder's at equal samples.

Nothing of numba's compiling is timed: a render kernel is loaded on one pixel first
(:func:`lightcuts.pipeline.timing.render_timed`), and the seconds numba spends compiling while
lights or trees are made are taken off (:func:`lightcuts.pipeline.warmup.compile_seconds`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: What a study folder may hold (shell patterns).
ALLOWED = ("table.md", "table.csv", "points.csv", "report.json", "report.html", "error-time.png", "reference.exr",
           "reference.png", "image-*.exr", "image-*.png")
#: Default times of the error at equal time, seconds.
DEFAULT_TIMES = (10.0, 60.0)
DEFAULT_REFERENCE_SPP = 1024
#: How report.json describes the mask.
EMITTER_MASK = ("pixels that see an emitter directly, left out of every figure: one pinhole ray through each "
                "pixel's centre and corners (lightcuts.integrators.primary)")


def image_seconds(parts: dict) -> float:
    """A point's time, from the loaded scene to the finished image, compile excluded: its lights',
    trees' and render's seconds (``lights_seconds``, ``build_seconds``, ``render_seconds``) summed.
    The one place that says what a row's time is."""
    return float(parts["lights_seconds"] + parts["build_seconds"] + parts["render_seconds"])


def reference_seeds(seed: int) -> tuple[int, int]:
    """The seeds of the reference's two halves, from a stream of their own: different from each
    other and from ``seed`` (the rows' first seed) even modulo 2^32 (Mitsuba's seeds are 32-bit)."""
    out, key = [], 0
    while len(out) < 2:
        s = np.random.SeedSequence(int(seed), spawn_key=(0x5354554459, key)).generate_state(2, np.uint32)
        key += 1
        v = ((int(s[0]) << 31) ^ int(s[1])) & ((1 << 62) - 1)
        if all(v % 2**32 != w % 2**32 for w in [int(seed), *out]):
            out.append(v)
    return out[0], out[1]


def ladder_counts(row) -> list[int]:
    """The counts a row may reach: its given ``samples``, else 1, 2, 4, ... up to its largest."""
    if row.samples is not None:
        return list(row.samples)
    return [1 << k for k in range(row.max_samples.bit_length()) if 1 << k <= row.max_samples]


@dataclass
class Study:
    """A study in memory, nothing written until :meth:`save`.

    rows : one dict per row (table.csv's columns, :func:`lightcuts.report.study.row_fields`, and
        ``row``: what it renders, :meth:`lightcuts.pipeline.study_rows.StudyRow.record`)
    points : one dict per ladder point (:data:`lightcuts.report.study.POINT_FIELDS`)
    report : report.json's dict; images : label -> the row's last image (H, W, 3) float32
    reference : (H, W, 3) the reference; mask : (H, W) bool, pixels that see an emitter directly
    """

    config: object
    rows: list
    points: list
    report: dict
    images: dict
    reference: np.ndarray
    mask: np.ndarray

    def markdown(self) -> str:
        from lightcuts.report.study import format_markdown

        return format_markdown(self.report)

    def save(self, folder) -> Path:
        """Write table.md, table.csv, points.csv, report.json, error-time.png, reference.exr / .png,
        image-<row>.exr / .png (each row's last image) and report.html into ``folder`` (replaced as a
        whole). Returns the folder."""
        from lightcuts.io import check_output_dir, output_set, save_csv, save_json
        from lightcuts.report import pages
        from lightcuts.report.compare import file_label
        from lightcuts.report.html import write_report
        from lightcuts.report.images import write_exr, write_png
        from lightcuts.report.study import POINT_FIELDS, error_time_plot, row_fields

        out = check_output_dir(folder, "folder", ALLOWED)
        tonemap = self.config.render.tonemap
        with output_set(out) as tmp:
            (tmp / "table.md").write_text(self.markdown())
            fields = row_fields(self.report["times"])
            save_csv(tmp / "table.csv", [{k: r.get(k) for k in fields} for r in self.rows], fields)
            save_csv(tmp / "points.csv", self.points, list(POINT_FIELDS))
            error_time_plot(tmp / "error-time.png", self.report)
            write_exr(tmp / "reference.exr", self.reference)
            write_png(tmp / "reference.png", self.reference, tonemap)
            for label, image in self.images.items():
                write_exr(tmp / f"image-{file_label(label)}.exr", image)
                write_png(tmp / f"image-{file_label(label)}.png", image, tonemap)
            save_json(tmp / "report.json", self.report)
            write_report(tmp / "report.html", pages.study(self, tmp / "error-time.png"))
        return out


class _Scene:
    """The scene, environment, ray casters (one per caster the rows name) and mask every row shares."""

    def __init__(self, plan):
        from lightcuts.integrators.primary import emitter_mask

        self.scene = plan.scene()
        self.envmap = plan.environment()
        self.casters = {}
        self.mask = emitter_mask(self.scene, self.caster(plan), plan.cfg.render.crop, self.envmap is not None)

    def caster(self, plan):
        key = repr(plan.caster.record())
        if key not in self.casters:
            self.casters[key] = plan.make_caster(self.scene)
        return self.casters[key]

    def close(self):
        for c in self.casters.values():
            c.close()


def study_run(cfg, plan, rows, *, reference: str, reference_spp: int, times=DEFAULT_TIMES, budget: float | None = None,
              epsilon: float | None = None, source: str | None = None, progress: bool = True, log=print) -> Study:
    """Run the study (module docstring): ``cfg``, ``plan`` the study's config and plan; ``rows``
    (:func:`lightcuts.pipeline.study_rows.resolve_rows`); ``reference`` a REFERENCES name at
    ``reference_spp`` (two halves of half each, rounded up); ``times`` the error at equal time's
    seconds; ``budget`` the seconds a row's ladder runs to (default the largest of ``times``);
    ``epsilon`` relMSE's (default :data:`lightcuts.report.efficiency.EPSILON`)."""
    from lightcuts import __version__
    from lightcuts.integrators.references import make_reference
    from lightcuts.report.compare import machine
    from lightcuts.report.efficiency import EPSILON, reference_figures

    epsilon = EPSILON if epsilon is None else float(epsilon)
    times = [float(t) for t in times]
    budget = max(times) if budget is None else float(budget)
    tracer = make_reference(reference)
    shared = _Scene(plan)
    try:
        half = max(1, (reference_spp + 1) // 2)
        render, half, t_load = tracer.prepare(cfg, shared.scene, shared.envmap, half)
        seeds = reference_seeds(cfg.seed)
        log(f"{cfg.name}: reference, {tracer.title} {2 * half} spp in two halves ...")
        a, t_a = render(seeds[0])
        b, t_b = render(seeds[1])
        ref = ((np.asarray(a, np.float64) + b) / 2.0).astype(np.float32)
        noise = reference_figures(a, b, shared.mask, epsilon)
        log(f"{cfg.name}: reference {t_a + t_b:.1f} s, its own relMSE {noise['relmse']:.3g}, 8x8 RMS "
            f"{_pct(noise['block8_rms'])}")
        points, images = [], {}
        for row in rows:
            pts, images[row.label] = _ladder(row, shared, ref, noise, epsilon, budget, progress, log)
            points += pts
    finally:
        shared.close()
        tracer.close()
    table = _rows(rows, points, times, noise)
    report = {"lightcuts_version": __version__, "config": source, "name": cfg.name, "seed": cfg.seed,
              "resolution": [int(ref.shape[1]), int(ref.shape[0])], "crop": cfg.render.crop,
              "epsilon": epsilon, "times": times, "budget": budget,
              "reference": {**tracer.describe(), "spp": 2 * half, "half_seeds": list(seeds), "load_seconds": t_load,
                            "render_seconds": t_a + t_b, **noise},
              "noise_handling": "the reference's own relMSE (from its two halves) is subtracted from every row's "
                                "(clamped at 0; relmse_raw keeps the measured value), its 8x8 RMS in quadrature",
              "emitter_mask": EMITTER_MASK, "masked_pixels": int(shared.mask.sum()),
              "rows": table, "points": points, "settings": cfg.model_dump(mode="json"), "machine": machine()}
    return Study(cfg, table, points, report, images, ref, shared.mask)


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.2f}%"


#: Lights per type of a row's untimed warm-up.
_WARM_LIGHTS = 64


def _warm(row, shared) -> None:
    """Load (or compile) the kernels of a row that uses light trees, untimed: its lights (at most
    :data:`_WARM_LIGHTS` of each kind) and trees are made once, so that its first timed pass does not
    pay numba's loading from the cache (compiling is taken off anyway); its render kernel is loaded
    on one pixel by the first timed render."""
    import dataclasses

    lc = row.cfg.lights
    few = {k: getattr(lc, k).model_copy(update={"count": min(getattr(lc, k).count, _WARM_LIGHTS)})
           for k in ("direct", "indirect", "environment") if getattr(lc, k) is not None}
    plan = dataclasses.replace(row.plan, cfg=row.cfg.model_copy(update={"lights": lc.model_copy(update=few)}))
    plan.trees(plan.lights(shared.scene, shared.caster(row.plan), shared.envmap))


def _ladder(row, shared, ref, noise, epsilon, budget, progress, log) -> tuple[list, np.ndarray]:
    """A row's points and its last image."""
    from lightcuts.report.efficiency import efficiency, measure

    counts = ladder_counts(row)
    if row.uses_trees:
        _warm(row, shared)
    points = []

    def point(samples, seconds, image, parts):
        m = measure(image, ref, noise, shared.mask, epsilon)
        points.append({"label": row.label, "samples": int(samples), "ladder": row.ladder, "seconds": seconds,
                       **m, "efficiency": efficiency(m["relmse"], seconds), **parts})
        log(f"  {row.label}: {samples} {row.ladder}, {seconds:.2f} s, relMSE {m['relmse']:.3g}, 8x8 RMS "
            f"{_pct(m['block8_rms'])}")

    if row.tracer is not None:
        image = _tracer_ladder(row, shared, counts, budget, point)
    elif row.ladder == "passes":
        image = _passes_ladder(row, shared, counts, budget, point, progress)
    else:
        image = _spp_ladder(row, shared, counts, budget, point, progress)
    return points, image


def _tracer_ladder(row, shared, counts, budget, point) -> np.ndarray:
    from lightcuts.integrators.references import make_reference

    tracer = make_reference(row.tracer)
    try:
        tracer.warm(row.cfg, shared.scene, shared.envmap)
        for k in counts:
            render, spp, _ = tracer.prepare(row.cfg, shared.scene, shared.envmap, k)
            image, seconds = render(row.cfg.seed)
            point(spp, seconds, image, {"lights_seconds": 0.0, "build_seconds": 0.0, "render_seconds": seconds})
            if seconds >= budget:
                break
    finally:
        tracer.close()
    return image


def _pass(row, shared, cfg, seed: int, load: bool, progress: bool):
    """One render of ``cfg`` (a pass or a ladder point), its lights and trees made first where the
    row uses them: (RenderResult, {"lights_seconds", "build_seconds", "render_seconds"})."""
    from lightcuts.pipeline.passes import pass_lights
    from lightcuts.pipeline.timing import render_timed

    caster = shared.caster(row.plan)
    lights, trees, t_lights, t_build = pass_lights(row.plan, shared.scene, caster, shared.envmap, seed)
    result, t_render, _ = render_timed(cfg, shared.scene, caster, lights, trees, shared.envmap,
                                       f"{cfg.name}: {row.label}", not progress, row.plan.integrator, load=load)
    return result, {"lights_seconds": t_lights, "build_seconds": t_build, "render_seconds": t_render}


def _passes_ladder(row, shared, counts, budget, point, progress) -> np.ndarray:
    from lightcuts.pipeline.passes import PassMean, pass_seed

    cfg = row.cfg
    marks = set(counts)
    mean = PassMean(counts[-1])
    total = {"lights_seconds": 0.0, "build_seconds": 0.0, "render_seconds": 0.0}
    image = None
    for p in range(counts[-1]):
        seed = pass_seed(cfg.seed, p)
        pcfg = cfg if p == 0 else cfg.model_copy(update={"seed": seed})
        result, parts = _pass(row, shared, pcfg, seed, p == 0, progress)
        mean.add(p, seed, result, parts["lights_seconds"], parts["build_seconds"], parts["render_seconds"])
        total = {k: total[k] + parts[k] for k in total}
        seconds = image_seconds(total)
        if p + 1 in marks or seconds >= budget:
            image = result.image if p == 0 else (mean.acc / (p + 1)).astype(np.float32)
            point(p + 1, seconds, image, dict(total))
        if seconds >= budget:
            break
    return image


def _spp_ladder(row, shared, counts, budget, point, progress) -> np.ndarray:
    cfg = row.cfg
    for i, k in enumerate(counts):
        kcfg = cfg.model_copy(update={"render": cfg.render.model_copy(update={"spp": int(k)})})
        result, parts = _pass(row, shared, kcfg, cfg.seed, i == 0, progress)
        seconds = image_seconds(parts)
        point(k, seconds, result.image, parts)
        if seconds >= budget:
            break
    return result.image


def _rows(rows, points, times, noise: dict) -> list[dict]:
    """The table's rows: each row's last point, its error at each time, its ratio to the best builder;
    ``noise``: the reference's own figures."""
    from lightcuts.report.efficiency import at_time, ratios_at_equal_samples, subtract, subtract_rms
    from lightcuts.report.study import at_key

    out = []
    for row in rows:
        pts = [p for p in points if p["label"] == row.label]
        last = pts[-1]
        r = {"label": row.label, "group": row.group, "tracer": row.tracer,
             "integrator": None if row.plan is None else row.plan.integrator.name, "builder": row.builder,
             "ladder": row.ladder, "samples": last["samples"], "seconds": last["seconds"],
             **{k: last[k] for k in ("relmse", "relmse_raw", "block8_rms", "block8_rms_raw", "efficiency")},
             "row": row.record()}
        secs = [p["seconds"] for p in pts]
        for t in times:  # the measured values interpolated, then the reference's share taken off
            raw = at_time(secs, [p["relmse_raw"] for p in pts], t)
            rms = at_time(secs, [p["block8_rms_raw"] for p in pts], t)
            r[at_key("relmse", t)] = None if raw is None else subtract(raw, noise["relmse"])
            r[at_key("block8_rms", t)] = (None if rms is None or noise["block8_rms"] is None
                                          else subtract_rms(rms, noise["block8_rms"]))
        r["ratio_best_builder"] = r["ratio_samples"] = None
        out.append(r)
    groups = {}
    for row in rows:
        groups.setdefault(row.group, []).append(row.label)
    for labels in groups.values():
        if len(labels) < 2:
            continue
        curves = {label: {p["samples"]: p["relmse"] for p in points if p["label"] == label} for label in labels}
        n, ratios = ratios_at_equal_samples(curves)
        for r in out:
            if r["label"] in ratios:
                r["ratio_best_builder"], r["ratio_samples"] = ratios[r["label"]], n
    return out
