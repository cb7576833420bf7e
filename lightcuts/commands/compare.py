r"""``lightcuts compare CONFIG``: the run rendered once per builder (and metric), the 2008 paper's Fig. 8.

Every row uses the same scene, lights and seed; only the trees differ. The scene, ray caster and
lights are made once; per row the trees are built (``Build``: the numba kernels are loaded or
compiled first, on a few lights, and not timed) and the image rendered (``Image time``: after a
one-pixel render that loads the render kernel). ``Preprocess total`` is the shared scene and light
time plus the row's build; ``Summed time`` adds the image time. The error is the per-pixel relative
luminance error against the all-lights reference (:func:`lightcuts.render.integrator.render_reference`)
on one seeded sample of ``--pixels`` pixels, the same for every row (the reference over a whole
100K-light image would take half an hour), over the sampled pixels brighter than 1% of the sample's
mean (:func:`lightcuts.report.images.relative_error`).

Outputs in ``renders/<name>/compare/`` (or ``--out``): ``table.md``, ``table.csv``, ``report.json``
(rows, config, machine), ``cutsize-<label>.png`` per row and ``cutsizes.png``
(:mod:`lightcuts.report.compare`). Finished rows and the reference are kept in ``rows/`` as soon as
they are done (one .npz each, written atomically, with a key of everything they depend on), so an
interrupted compare keeps them and the next run with the same config and seed only computes what is
missing or changed; ``--force`` recomputes everything.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np

from lightcuts.commands.common import add_set, progress_bar, render_settings, render_timed
from lightcuts.errors import LightcutsError

#: The default rows: the paper's four builders and today's top-down SAOH.
DEFAULT_BUILDERS = ("agglomerative-heap", "agglomerative", "divisive-6d", "divisive-3d", "saoh")
DEFAULT_PIXELS = 1024
#: Samples per pixel of the long Mitsuba path-traced render both equal-time images are measured against.
DEFAULT_MITSUBA_SPP = 1024
#: What a compare folder may hold (shell patterns): its own outputs and its row store.
ALLOWED = ("table.md", "table.csv", "report.json", "cutsizes.png", "cutsize-*.png", "rows", "mitsuba-*.exr",
           "mitsuba-*.png")
#: Lights per type on which each builder's kernels are loaded (or compiled) before the timed build.
_WARM_LIGHTS = 64


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="render once per builder: the 2008 paper's Fig. 8 table, cut-size maps")
    p.add_argument("config")
    p.add_argument("--builders", default=None, help=f"comma-separated builders (default {','.join(DEFAULT_BUILDERS)})")
    p.add_argument("--metrics", default=None,
                   help="comma-separated metrics: a row per metric for each builder that reads one "
                        "(default the config's)")
    p.add_argument("--pixels", type=int, default=DEFAULT_PIXELS,
                   help=f"pixels in the seeded sample the error is measured on (default {DEFAULT_PIXELS}; 0: none)")
    p.add_argument("--diff", default=None, help="a,b: the rows of the signed cut-size difference (default the first two)")
    p.add_argument("--force", action="store_true", help="recompute rows already finished")
    p.add_argument("--mitsuba", action="store_true",
                   help="add Mitsuba 3's path tracer run for the agglomerative row's image time, both against "
                        "a long Mitsuba render (needs pip install 'lightcuts[mitsuba]')")
    p.add_argument("--mitsuba-spp", type=int, default=DEFAULT_MITSUBA_SPP,
                   help=f"samples per pixel of the long Mitsuba render (default {DEFAULT_MITSUBA_SPP})")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/compare)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_compare(args)
    return 0


def _names(text: str, key: str) -> list[str]:
    names = [b.strip() for b in str(text).split(",") if b.strip()]
    if not names:
        raise LightcutsError(f"{key} {text!r}: no names given")
    if len(set(names)) != len(names):
        raise LightcutsError(f"{key} {text!r}: a name is given twice")
    return names


def resolve_rows(args, cfg) -> list[tuple[str, object]]:
    """(label, TreeSpec) per row; each builder gets only the metric and c it reads; a builder that
    reads a metric gets one row per ``--metrics`` name, labelled ``builder/metric`` when there are
    several."""
    from lightcuts.trees.spec import tree_spec

    builders = _names(args.builders, "--builders") if args.builders is not None else list(DEFAULT_BUILDERS)
    metrics = _names(args.metrics, "--metrics") if args.metrics is not None else [cfg.tree.metric]
    keys = {"builder": "--builders", "metric": "--metrics" if args.metrics is not None else "tree.metric"}
    rows = []
    for b in builders:
        first = tree_spec(b, metrics[0], cfg.tree.c, keys, drop_unread=True)
        if first.metric is None or len(metrics) == 1:
            rows.append((b, first))
            continue
        for m in metrics:
            rows.append((f"{b}/{m}", tree_spec(b, m, cfg.tree.c, keys, drop_unread=True)))
    if args.metrics is not None and not any(s.metric is not None for _, s in rows):
        raise LightcutsError(f"--metrics: none of the builders ({', '.join(builders)}) reads a metric")
    return rows


def sample_pixels(width: int, height: int, crop, k: int, seed: int) -> np.ndarray:
    """(K, 2) int64 (x, y): ``k`` distinct pixels of the image (or of the crop window) drawn with
    ``seed``, in row-major order; all of them when the window has at most ``k``."""
    x0, y0, x1, y1 = (0, 0, width, height) if crop is None else crop
    n = (x1 - x0) * (y1 - y0)
    rng = np.random.default_rng([int(seed), 0x636F6D70])  # "comp": a stream of its own
    idx = np.arange(n) if k >= n else np.sort(rng.choice(n, size=k, replace=False))
    return np.stack([x0 + idx % (x1 - x0), y0 + idx // (x1 - x0)], axis=1).astype(np.int64)


def _key(**parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:32]


def _shared_config(cfg) -> dict:
    """Everything of the config that the scene, lights, reference and images depend on."""
    data = cfg.model_dump(mode="json")
    data.pop("tree", None)
    data.pop("name", None)
    data["base_dir"] = str(Path(cfg.base_dir).resolve())
    return data


def _load_cached(path: Path, key: str) -> dict | None:
    """The arrays of a row store file if its key matches, else None (a damaged file counts as absent)."""
    from lightcuts.io import read_npz

    if not path.is_file():
        return None
    try:
        z = read_npz(path, "compare row")
    except LightcutsError:
        return None
    return z if str(z.get("key")) == key else None


def run_compare(args) -> dict:
    """The ``lightcuts compare`` command; returns the report dict (also written to report.json)."""
    from lightcuts.commands.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.io import check_output_dir
    from lightcuts.scene.build import image_size

    cfg = load_config(args.config, args.overrides)
    if args.pixels < 0:
        raise LightcutsError(f"--pixels {args.pixels}: must be >= 0")
    if args.mitsuba:
        from lightcuts.mitsuba import load_mitsuba

        if args.mitsuba_spp < 1:
            raise LightcutsError(f"--mitsuba-spp {args.mitsuba_spp}: must be at least 1")
        load_mitsuba()  # one line naming the install command if Mitsuba is missing
    rows = resolve_rows(args, cfg)
    plans = [plan_run(cfg, render=True, tree=spec) for _, spec in rows]
    labels = [label for label, _ in rows]
    if args.diff is None:
        diff = tuple(labels[:2]) if len(labels) >= 2 else None
    else:
        diff = tuple(_names(args.diff, "--diff"))
        if len(diff) != 2 or any(d not in labels for d in diff):
            raise LightcutsError(f"--diff {args.diff!r}: expected two different rows of {', '.join(labels)}")
    out = check_output_dir(Path(args.out) if args.out else Path("renders") / cfg.name / "compare",
                           "--out" if args.out else "name", ALLOWED)
    width, height = image_size(cfg)
    pixels = sample_pixels(width, height, cfg.render.crop, args.pixels, cfg.seed) if args.pixels else None
    return _run(args, cfg, plans, labels, out, pixels, diff)


class _Shared:
    """The scene, ray caster, environment and lights of every row, made on first use (a compare
    whose rows are all stored needs none of them)."""

    def __init__(self, plan):
        self.plan = plan
        self.ready = False
        self.warmup = None

    def get(self):
        if not self.ready:
            from lightcuts.commands.warmup import start_render_warmup

            t0 = time.perf_counter()
            self.scene = self.plan.scene()
            if self.plan.caster.trait("warm_render_kernel", False):
                self.warmup = start_render_warmup()
            self.caster = self.plan.make_caster(self.scene)
            self.envmap = self.plan.environment()
            self.lights = self.plan.lights(self.scene, self.caster, self.envmap)
            self.seconds = time.perf_counter() - t0
            self.ready = True
        return self


def _run(args, cfg, plans, labels, out: Path, pixels, diff) -> dict:
    from lightcuts.commands.warmup import finish_warmup

    store = out / "rows"
    shared = _Shared(plans[0])
    try:
        reference = None
        if pixels is not None:
            reference = _reference(args, cfg, shared, store, pixels)
        results = [_row(args, cfg, plan, label, shared, store, pixels, reference)
                   for plan, label in zip(plans, labels)]
        mitsuba = _mitsuba(args, cfg, shared, store, results) if args.mitsuba else None
    finally:
        if shared.warmup is not None:
            finish_warmup(shared.warmup, timeout=0)
    return _write(args, cfg, out, results, reference, pixels, diff, mitsuba)


def _reference(args, cfg, shared, store: Path, pixels) -> dict:
    """The all-lights reference on the pixel sample: {"image": (K, 3), "seconds", "shadow_rays"}."""
    from lightcuts import __version__
    from lightcuts.io import save_npz
    from lightcuts.render.integrator import render_reference

    key = _key(what="reference", config=_shared_config(cfg), pixels=pixels.tolist(), version=__version__)
    path = store / "reference.npz"
    cached = None if args.force else _load_cached(path, key)
    if cached is not None:
        return {"image": cached["image"], "seconds": float(cached["seconds"]),
                "shadow_rays": int(cached["shadow_rays"])}
    s = shared.get()
    with progress_bar(len(pixels), f"{cfg.name}: reference on {len(pixels)} pixels", args.no_progress,
                      unit="px") as bar:
        t0 = time.perf_counter()
        settings = {**render_settings(cfg, s.scene.camera, s.envmap), "crop": None}
        ref = render_reference(s.scene, s.caster, s.lights, progress=bar.update, pixels=pixels, **settings)
        seconds = time.perf_counter() - t0
    image = ref.image[:, 0]
    store.mkdir(parents=True, exist_ok=True)
    save_npz(path, key=np.array(key), image=image, seconds=np.array(seconds), shadow_rays=np.array(ref.shadow_rays))
    return {"image": image, "seconds": seconds, "shadow_rays": int(ref.shadow_rays)}


def _row(args, cfg, plan, label, shared, store: Path, pixels, reference) -> dict:
    """One row: {"row": the table row, "cut": (H, W) cut sizes}, from the store or computed."""
    from lightcuts import __version__
    from lightcuts.commands.plan import tree_meta
    from lightcuts.commands.warmup import finish_warmup
    from lightcuts.io import save_npz
    from lightcuts.lights.lightset import LightSet
    from lightcuts.report.compare import file_label
    from lightcuts.report.images import relative_error
    from lightcuts.trees.build import build_tree

    spec = plan.tree
    key = _key(what="row", store=2, config=_shared_config(cfg), builder=spec.name,
               metric=spec.metric.name if spec.metric is not None else None, c=spec.c,
               pixels=None if pixels is None else pixels.tolist(), version=__version__)
    path = store / f"{file_label(label)}.npz"
    cached = None if args.force else _load_cached(path, key)
    if cached is not None:
        return {"row": json.loads(str(cached["row"])), "cut": cached["cut"], "image": cached["image"]}

    s = shared.get()
    for typ, ls in s.lights.items():  # load (or compile) the builder's kernels untimed
        k = min(len(ls), _WARM_LIGHTS)
        few = LightSet(ls.position[:k], ls.normal[:k], ls.intensity[:k], ls.type, ls.indirect[:k], dict(ls.meta))
        build_tree(few, spec, seed=cfg.seed)
    t0 = time.perf_counter()
    trees = {typ: build_tree(ls, spec, seed=cfg.seed) for typ, ls in s.lights.items()}
    t_build = time.perf_counter() - t0
    used = tree_meta(trees)

    finish_warmup(s.warmup)
    s.warmup = None
    result, t_image, _ = render_timed(cfg, s.scene, s.caster, s.lights, trees, s.envmap, f"{cfg.name}: {label}",
                                      args.no_progress)
    crop = cfg.render.crop
    x0, y0 = (0, 0) if crop is None else crop[:2]

    n_pixels = result.cut_size.size
    row = {"label": label, "builder": used["builder"], "metric": used["metric"], "c": used["c"],
           "lights": {typ: len(ls) for typ, ls in s.lights.items()},
           "build_s": t_build, "preprocess_s": s.seconds + t_build, "image_s": t_image,
           "summed_s": s.seconds + t_build + t_image,
           "cut_mean": float(result.cut_size.mean()), "cut_max": float(result.cut_size.max()),
           "shadow_rays_per_pixel": float(result.shadow_rays) / n_pixels,
           "err_median": None, "err_p99": None, "pixels_compared": 0}
    if reference is not None:
        sample = result.image[pixels[:, 1] - y0, pixels[:, 0] - x0]
        err = relative_error(sample[:, None], reference["image"][:, None])
        row.update(err_median=err["median"], err_p99=err["p99"], err_mean=err["mean"], err_max=err["max"],
                   pixels_compared=err["pixels"])
    store.mkdir(parents=True, exist_ok=True)
    save_npz(path, key=np.array(key), row=np.array(json.dumps(row)), cut=result.cut_size, image=result.image)
    return {"row": row, "cut": result.cut_size, "image": result.image}


def _mitsuba(args, cfg, shared, store: Path, results: list[dict]) -> dict:
    """Lightcuts against Mitsuba's path tracer at equal time: the agglomerative row's image (the
    first row's without one) and a Mitsuba render with the spp that fills that row's image time,
    each against a ``--mitsuba-spp`` Mitsuba render (energy ratio, per-pixel and 8x8-block error)."""
    from lightcuts.io import save_npz
    from lightcuts.mitsuba.render import mitsuba_version, render_mitsuba, spp_for_seconds
    from lightcuts.report.images import compare_images

    base = next((r for r in results if r["row"]["label"] == "agglomerative"), results[0])
    key = _key(what="mitsuba", config=_shared_config(cfg), spp=args.mitsuba_spp, version=mitsuba_version())
    path = store / "mitsuba-reference.npz"
    cached = None if args.force else _load_cached(path, key)
    s = shared.get()
    if cached is None:
        print(f"{cfg.name}: Mitsuba path tracer, {args.mitsuba_spp} spp (the long reference)", flush=True)
        long_image, long_s = render_mitsuba(cfg, s.scene, s.envmap, spp=args.mitsuba_spp, integrator="path",
                                            seed=cfg.seed + 1)
        save_npz(path, key=np.array(key), image=long_image, seconds=np.array(long_s))
    else:
        long_image, long_s = cached["image"], float(cached["seconds"])
    budget = base["row"]["image_s"]
    spp = spp_for_seconds(cfg, s.scene, s.envmap, budget, "path")
    image, seconds = render_mitsuba(cfg, s.scene, s.envmap, spp=spp, integrator="path", seed=cfg.seed)
    return {"version": mitsuba_version(), "reference_spp": args.mitsuba_spp, "reference_seconds": long_s,
            "lightcuts_row": base["row"]["label"], "budget_s": budget,
            "equal_time": {"spp": spp, "seconds": seconds, **compare_images(image, long_image)},
            "lightcuts": {"seconds": budget, **compare_images(base["image"], long_image)},
            "images": {"reference": long_image, "equal_time": image}}


def _write(args, cfg, out: Path, results: list[dict], reference, pixels, diff, mitsuba=None) -> dict:
    from lightcuts.io import output_set, save_json
    from lightcuts.report.compare import format_markdown, format_mitsuba, machine, write_cut_images, write_tables
    from lightcuts.report.images import write_exr, write_png

    rows = [dict(r["row"]) for r in results]
    base = next((r["cut_mean"] for r in rows if r["label"] == "divisive-6d"), None)
    for r in rows:
        r["cut_vs_divisive_6d"] = r["cut_mean"] / base if base else None
    title = (f"{cfg.name}: {sum(rows[0]['lights'].values()):,} lights, eps {cfg.render.eps:g}, "
             f"seed {cfg.seed}")
    report = {"config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed,
              "settings": cfg.model_dump(mode="json"), "machine": machine(), "rows": rows,
              "pixels": None if pixels is None else len(pixels), "diff": list(diff) if diff else None}
    if reference is not None:
        report["reference"] = {"seconds": reference["seconds"], "shadow_rays": reference["shadow_rays"]}
    extra = ""
    if mitsuba is not None:
        images = mitsuba.pop("images")
        report["mitsuba"] = mitsuba
        extra = format_mitsuba(mitsuba)
    with output_set(out, keep=("rows",)) as tmp:
        write_tables(tmp, rows, title, extra)
        report["cut_scale_max"] = write_cut_images(tmp, {r["label"]: x["cut"] for r, x in zip(rows, results)},
                                                   diff, title)
        if mitsuba is not None:
            for name, image in images.items():
                write_exr(tmp / f"mitsuba-{name}.exr", image)
                write_png(tmp / f"mitsuba-{name}.png", image, cfg.render.exposure)
        save_json(tmp / "report.json", report)
    print(format_markdown(rows, title) + extra, end="")
    print(f"-> {out}")
    return report
