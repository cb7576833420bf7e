r"""The run rendered once per builder (and metric), the 2008 paper's Fig. 8, in memory
(:class:`Comparison`); shared by :func:`lightcuts.compare` and ``lightcuts compare``.

Every row uses the same scene, lights and seed; only the trees differ. The scene, ray caster and
lights are made once; per row the trees are built (``Build``: the numba kernels are loaded or
compiled first, on a few lights, and not timed) and the image rendered (``Image time``: after a
one-pixel render that loads the render kernel). ``Preprocess total`` is the shared scene and light
time plus the row's build; ``Summed time`` adds the image time. The error is the per-pixel relative
luminance error against the integrator's brute-force reference (its ``reference`` trait)
on one seeded sample of pixels, the same for every row, over the sampled pixels brighter than 1% of
the sample's mean (:func:`lightcuts.report.images.relative_error`). Finished rows and the reference
go to a :class:`~lightcuts.report.compare_store.RowStore` when one is given.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lightcuts.config.schema import DEFAULT_BUILDER
from lightcuts.errors import LightcutsError

DEFAULT_PIXELS = 1024
#: Samples per pixel of the long Mitsuba path-traced render both equal-time images are measured against.
DEFAULT_MITSUBA_SPP = 1024
#: What a compare folder may hold (shell patterns): its own outputs and its row store.
ALLOWED = ("table.md", "table.csv", "report.json", "report.html", "cutsizes.png", "cutsize-*.png", "image-*.exr",
           "image-*.png", "rows", "mitsuba-*.exr", "mitsuba-*.png")
#: Lights per type on which each builder's kernels are loaded (or compiled) before the timed build.
_WARM_LIGHTS = 64


def names(text, key: str) -> list[str]:
    """Comma-separated names (or a list or tuple of them), none twice; LightcutsError naming ``key``."""
    if not isinstance(text, (str, list, tuple)) or not all(isinstance(t, str) for t in text):
        raise LightcutsError(f"{key} {text!r}: expected names, comma-separated or as a list of texts")
    items = text.split(",") if isinstance(text, str) else list(text)
    out = [b.strip() for b in items if b.strip()]
    if not out:
        raise LightcutsError(f"{key} {text!r}: no names given")
    if len(set(out)) != len(out):
        raise LightcutsError(f"{key} {text!r}: a name is given twice")
    return out


def default_builders() -> list[str]:
    """The default rows: the builders with a ``compare_row`` trait (the paper's four builders and
    the top-down SAOH), in that trait's order."""
    from lightcuts.trees.registry import BUILDERS

    rows = [e for e in BUILDERS.entries() if e.trait("compare_row") is not None]
    return [e.name for e in sorted(rows, key=lambda e: e.trait("compare_row"))]


def resolve_rows(cfg, builders=None, metrics=None, keys=("--builders", "--metrics")) -> list[tuple[str, object]]:
    """(label, TreeSpec) per row; each builder gets only the metric and c it reads; a builder that
    reads a metric gets one row per metric name, labelled ``builder/metric`` when there are several.
    builders, metrics : comma-separated names or sequences (None: :func:`default_builders`, the
    config's metric); keys : how errors name the two options. The rows differ only by their trees,
    so the config's integrator must render from them (its ``forest`` trait)."""
    from lightcuts.integrators.registry import INTEGRATORS
    from lightcuts.trees.spec import config_tree, tree_spec

    integrator = INTEGRATORS.resolve(cfg.render.integrator, "render.integrator")
    if not integrator.trait("forest", False):
        users = [e.name for e in INTEGRATORS.entries() if e.trait("forest", False)]
        raise LightcutsError(f"render.integrator: integrator {integrator.name!r} does not render the config's lights "
                             f"through their trees, which a compare's rows differ by; use render.integrator: "
                             f"{' or '.join(users)}")
    bkey, mkey = keys
    builders = names(builders, bkey) if builders is not None else default_builders()
    given = metrics is not None
    _, metric, c, cfg_keys = config_tree(cfg.tree)
    metrics = names(metrics, mkey) if given else [metric]
    spec_keys = {**cfg_keys, "builder": bkey, **({"metric": mkey} if given else {})}
    rows = []
    for b in builders:
        first = tree_spec(b, metrics[0], c, spec_keys, drop_unread=True)
        if first.metric is None or len(metrics) == 1:
            rows.append((b, first))
            continue
        for m in metrics:
            rows.append((f"{b}/{m}", tree_spec(b, m, c, spec_keys, drop_unread=True)))
    if given and not any(s.metric is not None for _, s in rows):
        raise LightcutsError(f"{mkey}: none of the builders ({', '.join(builders)}) reads a metric")
    return rows


def sample_pixels(width: int, height: int, crop, k: int, seed: int) -> np.ndarray:
    """(K, 2) int64 (x, y): ``k`` distinct pixels of the image (or of the crop window) drawn with
    ``seed``, in row-major order; all of them when the window has at most ``k``."""
    x0, y0, x1, y1 = (0, 0, width, height) if crop is None else crop
    n = (x1 - x0) * (y1 - y0)
    rng = np.random.default_rng([int(seed), 0x636F6D70])  # "comp": a stream of its own
    idx = np.arange(n) if k >= n else np.sort(rng.choice(n, size=k, replace=False))
    return np.stack([x0 + idx % (x1 - x0), y0 + idx // (x1 - x0)], axis=1).astype(np.int64)


@dataclass
class Comparison:
    """A compare run in memory, nothing written to disk until :meth:`save`.

    rows : one dict per row with the keys and order of table.csv
        (:data:`lightcuts.report.compare.CSV_FIELDS`; None where the CSV cell is blank)
    report : the dict ``lightcuts compare`` writes as report.json (every row's full dict, config, machine,
        ``cut_unit``: what the cut sizes count, the integrator's ``cut_unit`` trait)
    cut_sizes : label -> (H, W) float32 cut size per pixel, in ``report["cut_unit"]``
    images : label -> (H, W, 3) float32 linear RGB
    reference_pixels, reference_image : (K, 2) int64 (x, y) of the sampled pixels and (K, 3) the
        all-lights reference there, or None without the reference
    """

    config: object
    rows: list
    report: dict
    cut_sizes: dict
    images: dict
    mitsuba_images: dict | None = None
    reference_pixels: np.ndarray | None = None
    reference_image: np.ndarray | None = None

    def title(self) -> str:
        r = self.report["rows"][0]
        return (f"{self.config.name}: {sum(r['lights'].values()):,} lights, eps {self.config.render.eps:g}, "
                f"seed {self.config.seed}")

    def markdown(self) -> str:
        """table.md's text: the Fig. 8 table (and the Mitsuba section)."""
        from lightcuts.report.compare import format_markdown

        return format_markdown(self.report["rows"], self.title()) + self._extra()

    def _repr_markdown_(self) -> str:
        return self.markdown()

    def save(self, folder) -> Path:
        """Write the files ``lightcuts compare`` writes into ``folder`` (replaced as a whole, its
        ``rows/`` store kept): table.md, table.csv, image-<label>.exr / .png (one tone map, the
        config's, for every row), cutsize-<label>.png, cutsizes.png, report.json, report.html
        (:mod:`lightcuts.report.pages`) and mitsuba-*.exr / .png with the Mitsuba study. Returns the folder."""
        from lightcuts.io import check_output_dir, output_set, save_json
        from lightcuts.report import pages
        from lightcuts.report.compare import file_label, write_cut_images, write_tables
        from lightcuts.report.html import write_report
        from lightcuts.report.images import write_exr, write_png

        out = check_output_dir(folder, "folder", ALLOWED)
        report, rows = self.report, self.report["rows"]
        diff = tuple(report["diff"]) if report["diff"] else None
        with output_set(out, keep=("rows",)) as tmp:
            write_tables(tmp, rows, self.title(), self._extra())
            report["cut_scale_max"] = write_cut_images(tmp, {r["label"]: self.cut_sizes[r["label"]] for r in rows},
                                                       diff, self.title(), report.get("cut_unit"))
            for r in rows:
                write_exr(tmp / f"image-{file_label(r['label'])}.exr", self.images[r["label"]])
                write_png(tmp / f"image-{file_label(r['label'])}.png", self.images[r["label"]],
                          self.config.render.tonemap)
            for name, image in (self.mitsuba_images or {}).items():
                write_exr(tmp / f"mitsuba-{name}.exr", image)
                write_png(tmp / f"mitsuba-{name}.png", image, self.config.render.tonemap)
            save_json(tmp / "report.json", report)
            write_report(tmp / "report.html", pages.compare(self))
        return out

    def _extra(self) -> str:
        from lightcuts.report.compare import format_mitsuba

        return format_mitsuba(self.report["mitsuba"]) if "mitsuba" in self.report else ""


class _Shared:
    """The scene, ray caster, environment and lights of every row, made on first use (a compare
    whose rows are all stored needs none of them). ``warm``: start the child that compiles the render
    kernel (not when a cluster's workers render)."""

    def __init__(self, plan, warm: bool = True):
        self.plan = plan
        self.ready = False
        self.warm = warm
        self.warmup = None

    def get(self):
        if not self.ready:
            from lightcuts.pipeline.warmup import compile_seconds, start_render_warmup

            t0 = time.perf_counter()
            self.scene = self.plan.scene()
            if self.warm and self.plan.caster.trait("warm_render_kernel", False):
                self.warmup = start_render_warmup(self.plan.integrator.trait("kernels"))
            self.caster = self.plan.make_caster(self.scene)
            self.envmap = self.plan.environment()
            t1, c1 = time.perf_counter(), compile_seconds()
            self.lights = self.plan.lights(self.scene, self.caster, self.envmap)
            self.seconds = time.perf_counter() - t0
            self.lights_seconds = time.perf_counter() - t1 - (compile_seconds() - c1)
            self.ready = True
        return self


def compare_run(cfg, plans, labels, pixels, store, *, source: str | None = None, diff=None,
                mitsuba_spp: int | None = None, mitsuba_passes: int = 0, progress: bool = True,
                runner=None) -> Comparison:
    """Run the rows (one :class:`~lightcuts.pipeline.plan.Plan` and label each) and the reference on
    ``pixels`` ((K, 2) int64 or None: no error columns); ``store`` a RowStore; ``mitsuba_spp``: add
    the Mitsuba study with a long render of that many spp, and with ``mitsuba_passes`` > 0 the
    converging render of the study's row (:func:`converging_config`) at its own time; ``source``:
    recorded in the report; ``diff``: the two rows of the cut-size difference panel (None: chosen
    by :func:`default_diff` once the rows are done). ``runner``: computes the reference and the
    rows the store lacks on a cluster (``runner.compare_rows(cfg, plans, labels, shared, store, pixels, progress) ->
    (reference, results)``, :class:`lightcuts.distributed.runner.ClusterRunner`), their values those
    of this function's own; its ``record()`` becomes report.json's ``cluster``."""
    from lightcuts.pipeline.warmup import finish_warmup

    shared = _Shared(plans[0], warm=runner is None)
    try:
        if runner is not None:
            reference, results = runner.compare_rows(cfg, plans, labels, shared, store, pixels, progress)
        else:
            reference = None
            if pixels is not None:
                reference = _reference(cfg, shared, store, pixels, progress)
            results = [_row(cfg, plan, label, shared, store, pixels, reference, progress)
                       for plan, label in zip(plans, labels)]
        mitsuba = None
        if mitsuba_spp is not None:
            from lightcuts.mitsuba.study import equal_time_study

            i = next((k for k, r in enumerate(results) if r["row"]["label"] == DEFAULT_BUILDER), 0)
            s = shared.get()
            converging = _converging(plans[i], s, mitsuba_passes, progress) if mitsuba_passes else None
            from lightcuts.integrators.primary import emitter_mask

            mask = emitter_mask(s.scene, s.caster, cfg.render.crop, s.envmap is not None)
            mitsuba = equal_time_study(cfg, s.scene, s.envmap, results[i], mitsuba_spp, store, converging, mask)
    finally:
        if shared.warmup is not None:
            finish_warmup(shared.warmup, timeout=0)
    comparison = _comparison(cfg, source, results, reference, pixels, diff, mitsuba)
    if runner is not None:
        comparison.report["cluster"] = runner.record()
    return comparison


def converging_config(cfg, integrator, passes: int):
    """The config's converging settings: ``passes`` passes, and compensation with stochastic
    representatives where the integrator takes them (its ``converging`` trait)."""
    update = {"passes": int(passes)}
    if integrator.trait("converging", False):
        update.update(compensation=True, representatives="stochastic")
    return cfg.model_copy(update={"render": cfg.render.model_copy(update=update)})


def _converging(plan, shared, passes: int, progress: bool) -> dict:
    """The converging render of the row ``plan`` on the shared scene: {"label", "seconds", "image"}."""
    from lightcuts.pipeline.passes import render_passes
    from lightcuts.pipeline.plan import plan_run

    cfg = converging_config(plan.cfg, plan.integrator, passes)
    r = cfg.render
    cplan = plan_run(cfg, render=True, tree=plan.tree)
    result = render_passes(cfg, cplan, shared.scene, shared.caster, shared.envmap,
                           desc=f"{cfg.name}: converging", progress=progress)
    label = (f"{plan.tree.name}, {r.passes} passes" + (", compensation, stochastic" if r.compensation else ""))
    return {"label": label, "seconds": result.seconds, "image": result.image}


def reference_key(cfg, pixels) -> str:
    """The row store's key of the reference on ``pixels``."""
    from lightcuts import __version__
    from lightcuts.report.compare_store import shared_config, store_key

    return store_key(what="reference", config=shared_config(cfg), pixels=pixels.tolist(), version=__version__)


def stored_reference(store, key: str) -> dict | None:
    """The stored reference ({"image": (K, 3), "seconds", "shadow_rays"}), or None."""
    cached = store.load("reference", key)
    if cached is None:
        return None
    return {"image": cached["image"], "seconds": float(cached["seconds"]), "shadow_rays": int(cached["shadow_rays"])}


def save_reference(store, key: str, reference: dict) -> None:
    store.save("reference", key, image=reference["image"], seconds=np.array(reference["seconds"]),
               shadow_rays=np.array(reference["shadow_rays"]))


def _reference(cfg, shared, store, pixels, progress: bool) -> dict:
    """The all-lights reference on the pixel sample: {"image": (K, 3), "seconds", "shadow_rays"}."""
    from lightcuts.pipeline.timing import progress_bar
    from lightcuts.integrators.registry import make_integrator

    key = reference_key(cfg, pixels)
    cached = stored_reference(store, key)
    if cached is not None:
        return cached
    s = shared.get()
    with progress_bar(len(pixels), f"{cfg.name}: reference on {len(pixels)} pixels", not progress,
                      unit="px") as bar:
        t0 = time.perf_counter()
        reference = make_integrator(cfg, s.plan.integrator).reference()
        ref = reference.render(s.scene, s.caster, s.lights, None, envmap=s.envmap, seed=cfg.seed, pixels=pixels,
                               progress=bar.update)
        seconds = time.perf_counter() - t0
    result = {"image": ref.image[:, 0], "seconds": seconds, "shadow_rays": int(ref.shadow_rays)}
    save_reference(store, key, result)
    return result


def row_key(cfg, plan, pixels) -> str:
    """The row store's key of the row of ``plan``'s builder, metric and c."""
    from lightcuts import __version__
    from lightcuts.report.compare_store import shared_config, store_key

    spec = plan.tree
    return store_key(what="row", store=2, config=shared_config(cfg), builder=spec.name,
                     metric=spec.metric.name if spec.metric is not None else None, c=spec.c,
                     pixels=None if pixels is None else pixels.tolist(), version=__version__)


def stored_row(store, plan, label, key: str) -> dict | None:
    """The stored row {"row", "cut", "image"} of ``label``, or None."""
    from lightcuts.report.compare import file_label

    cached = store.load(file_label(label), key)
    if cached is None:
        return None
    return {"row": {**json.loads(str(cached["row"])), "plugins": plan.record(),
                    "cut_unit": plan.integrator.trait("cut_unit")},
            "cut": cached["cut"], "image": cached["image"]}


def compute_row(cfg, plan, label, scene, caster, lights, envmap, shared_seconds: float, lights_seconds: float,
                progress: bool, before_render=None) -> dict:
    """A row's trees and image: {"row", "cut", "image"} without the error columns (:func:`finish_row`).
    The builder's kernels are loaded on a few lights first (untimed), then the trees are built (timed)
    and the image rendered after a one-pixel load (:func:`~lightcuts.pipeline.timing.render_timed`);
    ``shared_seconds``: the scene's and lights' time; ``lights_seconds``: the lights' alone, compiling
    left out (the row's ``image_seconds`` is it, the trees' and the image's: report.json's
    ``image_seconds`` of a render); ``before_render()`` once before the image."""
    from lightcuts.pipeline.timing import render_timed
    from lightcuts.pipeline.plan import tree_meta
    from lightcuts.lights.lightset import LightSet
    from lightcuts.trees.build import build_tree

    spec = plan.tree
    for typ, ls in lights.items():  # load (or compile) the builder's kernels untimed
        k = min(len(ls), _WARM_LIGHTS)
        few = LightSet(ls.position[:k], ls.normal[:k], ls.intensity[:k], ls.type, ls.indirect[:k], dict(ls.meta))
        build_tree(few, spec, seed=cfg.seed)
    t0 = time.perf_counter()
    trees = {typ: build_tree(ls, spec, seed=cfg.seed) for typ, ls in lights.items()}
    t_build = time.perf_counter() - t0
    used = tree_meta(trees)
    if before_render is not None:
        before_render()
    result, t_image, _ = render_timed(cfg, scene, caster, lights, trees, envmap, f"{cfg.name}: {label}",
                                      not progress, plan.integrator)
    n_pixels = result.cut_size.size
    row = {"label": label, "builder": used["builder"], "metric": used["metric"], "c": used["c"],
           "lights": {typ: len(ls) for typ, ls in lights.items()},
           "build_s": t_build, "preprocess_s": shared_seconds + t_build, "image_s": t_image,
           "summed_s": shared_seconds + t_build + t_image, "image_seconds": lights_seconds + t_build + t_image,
           "cut_mean": float(result.cut_size.mean()), "cut_max": float(result.cut_size.max()),
           "cut_unit": plan.integrator.trait("cut_unit"),
           "shadow_rays_per_pixel": float(result.shadow_rays) / n_pixels,
           "err_median": None, "err_p99": None, "pixels_compared": 0, "plugins": plan.record()}
    return {"row": row, "cut": result.cut_size, "image": result.image}


def finish_row(cfg, computed: dict, pixels, reference, store, label, key: str) -> dict:
    """The row with its error against ``reference`` on ``pixels`` (None: no error columns), stored."""
    from lightcuts.report.compare import file_label
    from lightcuts.report.images import relative_error

    row, image = computed["row"], computed["image"]
    if reference is not None:
        crop = cfg.render.crop
        x0, y0 = (0, 0) if crop is None else crop[:2]
        sample = image[pixels[:, 1] - y0, pixels[:, 0] - x0]
        err = relative_error(sample[:, None], reference["image"][:, None])
        row.update(err_median=err["median"], err_p99=err["p99"], err_mean=err["mean"], err_max=err["max"],
                   pixels_compared=err["pixels"])
    store.save(file_label(label), key, row=np.array(json.dumps(row)), cut=computed["cut"], image=image)
    return computed


def _row(cfg, plan, label, shared, store, pixels, reference, progress: bool) -> dict:
    """One row: {"row": the table row, "cut": (H, W) cut sizes, "image"}, from the store or computed."""
    from lightcuts.pipeline.warmup import finish_warmup

    key = row_key(cfg, plan, pixels)
    cached = stored_row(store, plan, label, key)
    if cached is not None:
        return cached
    s = shared.get()

    def finish():
        finish_warmup(s.warmup)
        s.warmup = None

    computed = compute_row(cfg, plan, label, s.scene, s.caster, s.lights, s.envmap, s.seconds, s.lights_seconds,
                           progress, finish)
    return finish_row(cfg, computed, pixels, reference, store, label, key)


def baseline_row(rows: list[dict]) -> dict | None:
    """The row whose cut sizes the others' are divided by: its builder's ``compare_baseline`` trait
    (divisive-6d), under its own name (one metric); None without one."""
    from lightcuts.trees.registry import BUILDERS

    return next((r for r in rows if r["label"] == r["builder"] and r["builder"] in BUILDERS
                 and BUILDERS.entry(r["builder"]).trait("compare_baseline")), None)


def default_diff(labels: list[str], cuts: dict, baseline: str | None) -> tuple[tuple[str, str] | None, str]:
    """The rows of the cut-size difference panel when none are given, and why: the first row whose
    cut sizes differ from the ``baseline`` row's, minus the baseline; without a baseline row, the
    first row and the first later row whose cut sizes differ from it. Rows with the same cut sizes
    everywhere (agglomerative and agglomerative-heap build the same tree) would give a flat panel:
    no pair of them is chosen, and None when every row has the same cut sizes.
    cuts : label -> (H, W) cut sizes."""
    same = lambda a, b: np.array_equal(cuts[a], cuts[b])  # noqa: E731
    if baseline is not None:
        other = next((a for a in labels if a != baseline and not same(a, baseline)), None)
        if other is not None:
            return (other, baseline), f"the first row whose cut sizes differ from the baseline {baseline}'s"
    for i, a in enumerate(labels):
        other = next((b for b in labels[i + 1:] if not same(a, b)), None)
        if other is not None:
            return (a, other), "the first two rows whose cut sizes differ"
    return None, "every row has the same cut sizes: no difference panel"


def _comparison(cfg, source, results: list[dict], reference, pixels, diff, mitsuba) -> Comparison:
    """The Comparison of finished rows: the rows' ratio to divisive-6d's cut, the rows of the
    difference panel, the report dict."""
    from lightcuts.report.compare import CSV_FIELDS, cut_unit, machine

    rows = [dict(r["row"]) for r in results]
    base = baseline_row(rows)
    for r in rows:
        r["cut_vs_divisive_6d"] = r["cut_mean"] / base["cut_mean"] if base and base["cut_mean"] else None
    cuts = {r["label"]: x["cut"] for r, x in zip(rows, results)}
    why = "given"
    if diff is None:
        diff, why = default_diff([r["label"] for r in rows], cuts, base["label"] if base else None)
    report = {"config": source, "name": cfg.name, "seed": cfg.seed,
              "settings": cfg.model_dump(mode="json"), "machine": machine(), "cut_unit": cut_unit(rows), "rows": rows,
              "pixels": None if pixels is None else len(pixels), "diff": list(diff) if diff else None,
              "diff_chosen": why}
    if reference is not None:
        report["reference"] = {"seconds": reference["seconds"], "shadow_rays": reference["shadow_rays"]}
    images = None
    if mitsuba is not None:
        images = mitsuba.pop("images")
        report["mitsuba"] = mitsuba
    return Comparison(cfg, [{k: r.get(k) for k in CSV_FIELDS} for r in rows], report, cuts,
                      {r["label"]: x["image"] for r, x in zip(rows, results)}, images,
                      None if reference is None else pixels, None if reference is None else reference["image"])
