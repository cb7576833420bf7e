r"""``lightcuts accel CONFIG``: the ray casters side by side on the config's scene (the 2008 paper's Fig. 6).

Per caster: its build time (the constructor, after an untimed build on a tiny mesh that loads its
numba kernels), what its ``stats()`` reports (for BVHs E(boxes), E(tris), E(cost), nodes; for grids
voxels, nu_1, depth, references per item; memory in bytes), and the times of two images at the
config's resolution through the caster's batch API (median of ``--repeats``):

- *eye*: one eye ray per pixel (the pixel centre's stratum, the renderer's ray), closest hit;
- *shadows*: 16 eye rays per pixel (closest hit) and, from each hit, one shadow ray (occlusion) to a
  light drawn uniformly, with the config's seed, from the config's lights (direct lights, VPLs, sun,
  environment samples), offset as the renderer offsets its shadow rays.

Every caster answers the same rays; the rays whose hit triangle (or occlusion) differs from the
first caster's are counted (``eye_mismatch``, ``shadow_mismatch``), so a faster caster cannot be a
wrong one. Outputs in ``renders/<name>/accel/`` (or ``--out``), one set: ``table.md``,
``table.csv``, ``report.json`` (rows, config, machine), ``report.html``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lightcuts.commands.common import add_set
from lightcuts.pipeline.timing import progress_bar
from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_REPEATS

#: Eye rays per pixel of the shadows image, each with one shadow ray.
SHADOW_SPP = 16
ALLOWED = ("table.md", "table.csv", "report.json", "report.html", "sweep.csv", "sweep.png")
#: Room counts of ``--sweep rooms``.
SWEEP_ROOMS = "1,2,4,6,8"
#: The casters of ``--sweep rooms`` by default: the 1995 paper's structures, the BVHs and Embree.
SWEEP_CASTERS = ("embree", "hug", "grid", "recursive-grid-50", "recursive-grid-100", "recursive-grid-150",
                 "octree-50", "octree-100", "octree-150", "bvh-agglomerative", "bvh-agglomerative-heap", "bvh-sah")


def add_parser(sub) -> None:
    p = sub.add_parser("accel", help="ray casters side by side: build, SAH statistics, eye and shadow images")
    p.add_argument("config")
    p.add_argument("--casters", default=None,
                   help="comma-separated ray casters or aliases (default: every kernel-callable caster, embree first; "
                        "a caster with aliases as its aliases' variants, e.g. recursive-grid-50, -100, -150)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs of each image (median reported)")
    p.add_argument("--out", default=None, help="output folder (default renders/<name>/accel)")
    p.add_argument("--sweep", choices=("rooms",), default=None,
                   help="rooms: the study on the config's rooms scene at every --rooms count (the 1995 paper's "
                        "growing scenes), with time and memory plotted against triangles")
    p.add_argument("--rooms", default=SWEEP_ROOMS, help=f"room counts of --sweep rooms (default {SWEEP_ROOMS})")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_set(p)
    p.set_defaults(func=run)


def run(args) -> int:
    run_accel(args)
    return 0


def resolve_casters(text: str | None) -> list:
    """(label, Resolved) pairs from ``--casters`` (default every kernel-callable caster, ``embree``
    first, a caster with aliases as its aliases' variants); a label is the name as given, so an
    alias (``recursive-grid-150``) names its row."""
    from lightcuts.accel.registry import RAY_CASTERS

    if text is None:
        # A caster whose aliases fix its parameters (the paper's MAXP sweep) is run as those variants.
        aliases = RAY_CASTERS.aliases()
        labels = sorted(label for e in RAY_CASTERS.entries() if e.trait("kernel_callable", False)
                        for label in ([a for a, n in aliases.items() if n == e.name] or [e.name]))
        return [(n, RAY_CASTERS.resolve(n, "--casters")) for n in sorted(labels, key=lambda n: n != "embree")]
    names = [n.strip() for n in str(text).split(",") if n.strip()]
    if not names or len(set(names)) != len(names):
        raise LightcutsError(f"--casters {text!r}: expected distinct comma-separated caster names")
    return [(n, RAY_CASTERS.resolve(n, "--casters")) for n in names]


def run_accel(args) -> dict:
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.io import check_output_dir, run_dir

    cfg = load_config(args.config, args.overrides)
    if not 1 <= args.repeats <= MAX_REPEATS:
        raise LightcutsError(f"--repeats {args.repeats}: must be from 1 to {MAX_REPEATS} "
                             "(lightcuts.limits.MAX_REPEATS)")
    sweep = getattr(args, "sweep", None)
    entries = resolve_casters(args.casters if args.casters is not None or sweep is None else ",".join(SWEEP_CASTERS))
    plan = plan_run(cfg)
    if sweep == "rooms":
        if plan.scene_type is None or "rooms" not in plan.scene_type.params:
            raise LightcutsError(f"--sweep rooms: {args.config} is not a rooms scene (scene.procedural.type: rooms, "
                                 "e.g. configs/rooms.yaml)")
        for n in parse_counts(args.rooms):  # every count's scene checked before any work
            plan_run(load_config(args.config, list(args.overrides) + [f"scene.procedural.rooms={n}"]))
    out = check_output_dir(Path(args.out) if args.out else run_dir(cfg.name, args.overrides) / "accel",
                           "--out" if args.out else "name", ALLOWED)
    if sweep == "rooms":
        return _run_sweep(args, cfg, entries, out)
    return _run(args, cfg, plan, entries, out)


def scene_rays(cfg, plan) -> dict:
    """The scene and the rays of both images, cast by Embree where rays depend on hits (the shadow
    rays start at the eye rays' hits): eye (org, dirs), shadow-image eye rays and shadow rays."""
    from lightcuts.accel.registry import make_caster
    from lightcuts.integrators.camera import eye_rays
    from lightcuts.integrators.driver import shadow_ray_offset

    scene = plan.scene()
    cam = scene.camera
    eo, ed = eye_rays(cam, 1, cfg.seed, cfg.render.crop)
    so, sd = eye_rays(cam, SHADOW_SPP, cfg.seed, cfg.render.crop)
    eo, ed, so, sd = (a.reshape(-1, 3) for a in (eo, ed, so, sd))
    with make_caster(scene, "embree") as embree:
        lights = plan.lights(scene, embree, plan.environment())
        t, prim = embree.intersect(so, sd, 0.0, np.inf)
    hit = prim >= 0
    p = so[hit] + t[hit, None] * sd[hit]
    n = scene.face_normals[prim[hit]]
    n = np.where((np.einsum("ij,ij->i", n, sd[hit]) > 0)[:, None], -n, n)  # the side the eye ray came from
    targets = [(ls.position, ls.type == "directional") for ls in lights.values() if len(ls)]
    if not targets:
        raise LightcutsError(f"{cfg.name}: the config has no lights to cast shadow rays to")
    pos = np.concatenate([q for q, _ in targets])
    directional = np.concatenate([np.full(len(q), d) for q, d in targets])
    pick = np.random.default_rng([cfg.seed, 0x61636365]).integers(0, len(pos), len(p))  # "acce"
    offset = shadow_ray_offset(scene)
    org = p + offset * n
    dirs = np.where(directional[pick, None], pos[pick], pos[pick] - org)
    tfar = np.where(directional[pick], np.inf, 1.0 - offset / np.maximum(np.linalg.norm(dirs, axis=1), 1e-300))
    return {"scene": scene, "eye": (eo, ed), "shadow_eye": (so, sd), "shadow": (org, dirs, np.maximum(tfar, 0.0))}


def _median_seconds(fn, repeats: int) -> tuple[float, object]:
    times, value = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), value


def _warm(caster) -> None:
    """Load (or compile) a caster's kernels, untimed, on a small mesh with objects of several sizes
    (so that structures with levels, like the HUG's, take every path of their build and traversal)."""
    from lightcuts.accel.registry import make_caster

    rng = np.random.default_rng(0)
    centres = rng.uniform(-1, 1, (300, 1, 3))
    sizes = np.repeat([0.5, 0.05, 0.005], 100)[:, None, None]
    v = (centres + sizes * rng.normal(size=(300, 3, 3))).reshape(-1, 3)
    f = np.arange(len(v)).reshape(-1, 3)
    with make_caster((v, f), caster) as c:
        o, d = rng.uniform(-2, 2, (64, 3)), rng.normal(size=(64, 3))
        c.intersect(o, d, 0.0, np.inf)
        c.occluded(o, d, 0.0, np.inf)


def measure(args, cfg, plan, entries) -> tuple[list[dict], object]:
    """(rows, scene): every caster of ``entries`` ((label, Resolved) pairs) built and timed on the
    config's scene."""
    from lightcuts.accel.registry import make_caster

    rays = scene_rays(cfg, plan)
    scene = rays["scene"]
    rows, first = [], None
    with progress_bar(len(entries), f"{cfg.name}: casters", args.no_progress, unit="caster") as bar:
        for label, spec in entries:
            bar.set_postfix_str(label)
            _warm(spec)
            t0 = time.perf_counter()
            caster = make_caster(scene, spec)
            build = time.perf_counter() - t0
            stats = dict(caster.stats()) if hasattr(caster, "stats") else {}
            if "build_s" in stats:  # the caster's own timing of its structure alone
                stats["structure_build_s"] = stats.pop("build_s")
            stats.pop("caster", None)
            eye_s, (_, eye_prim) = _median_seconds(lambda: caster.intersect(*rays["eye"], 0.0, np.inf), args.repeats)

            def shadows():
                _, prim = caster.intersect(*rays["shadow_eye"], 0.0, np.inf)
                return prim, caster.occluded(*rays["shadow"][:2], 0.0, rays["shadow"][2])

            shadow_s, (s_prim, blocked) = _median_seconds(shadows, args.repeats)
            caster.close()
            if first is None:
                first = (eye_prim, s_prim, blocked)
            n_eye, n_shadow = len(eye_prim), len(s_prim) + len(blocked)
            rows.append({
                "caster": label, "triangles": scene.n_faces, "build_s": build,
                "build_tris_per_s": scene.n_faces / max(build, 1e-12), **stats,
                "eye_s": eye_s, "eye_mrays_per_s": n_eye / eye_s / 1e6, "shadows_s": shadow_s,
                "shadows_mrays_per_s": n_shadow / shadow_s / 1e6,
                "eye_mismatch": int((eye_prim != first[0]).sum()),
                "shadow_mismatch": int((s_prim != first[1]).sum() + (blocked != first[2]).sum()),
                "eye_rays": n_eye, "shadow_image_rays": n_shadow})
            bar.update(1)
    base = rows[0]
    for r in rows:
        r["eye_vs_first"] = r["eye_s"] / base["eye_s"]
        r["shadows_vs_first"] = r["shadows_s"] / base["shadows_s"]
    return rows, scene


def _title(cfg, scene) -> str:
    return f"{cfg.name}: {scene.n_faces:,} triangles, {scene.camera.width}x{scene.camera.height}"


def _run(args, cfg, plan, entries, out: Path) -> dict:
    from lightcuts.io import output_set, save_json
    from lightcuts.report import pages
    from lightcuts.report.accel import format_markdown, write_tables
    from lightcuts.report.html import write_report
    from lightcuts.report.compare import machine

    rows, scene = measure(args, cfg, plan, entries)
    title = _title(cfg, scene)
    report = {"config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed,
              "settings": cfg.model_dump(mode="json"), "machine": machine(), "repeats": args.repeats,
              "shadow_spp": SHADOW_SPP, "rows": rows}
    with output_set(out) as tmp:
        write_tables(tmp, rows, title)
        save_json(tmp / "report.json", report)
        write_report(tmp / "report.html", pages.accel(cfg, report))
    print(format_markdown(rows, title), end="")
    print(f"-> {out}")
    return report


def _run_sweep(args, cfg, entries, out: Path) -> dict:
    """The 1995 paper's growing scenes: the study at every ``--rooms`` count of a ``rooms`` scene."""
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.io import atomic_path, output_set, save_csv, save_json
    from lightcuts.report import pages
    from lightcuts.report.accel import format_markdown, format_sweep, plot_sweep
    from lightcuts.report.html import write_report
    from lightcuts.report.compare import machine

    counts = parse_counts(args.rooms)
    tables, rows = [], []
    for n in counts:
        cfg_n = load_config(args.config, list(args.overrides) + [f"scene.procedural.rooms={n}"])
        got, scene = measure(args, cfg_n, plan_run(cfg_n), entries)
        for r in got:
            r["rooms"] = n
        rows += got
        tables.append(format_markdown(got, f"{n} room{'s' if n > 1 else ''}: " + _title(cfg_n, scene)))
    summary = format_sweep(rows)
    report = {"config": str(Path(args.config)), "name": cfg.name, "seed": cfg.seed, "sweep": "rooms",
              "rooms": counts, "settings": cfg.model_dump(mode="json"), "machine": machine(),
              "repeats": args.repeats, "shadow_spp": SHADOW_SPP, "rows": rows}
    with output_set(out) as tmp:
        with atomic_path(tmp / "table.md") as path:
            path.write_text(summary + "\n" + "\n".join(tables))
        keys = list(dict.fromkeys(k for r in rows for k in r))
        save_csv(tmp / "sweep.csv", [{k: r.get(k) for k in keys} for r in rows], keys)
        plot_sweep(tmp / "sweep.png", rows, f"{cfg.name}: growing scenes ({', '.join(map(str, counts))} rooms)")
        save_json(tmp / "report.json", report)
        write_report(tmp / "report.html", pages.accel(cfg, report, [("growing scenes", tmp / "sweep.png")]))
    print(summary, end="")
    print(f"-> {out}")
    return report


def parse_counts(text: str) -> list[int]:
    """``"1,2,4"`` -> [1, 2, 4]; LightcutsError for anything but positive integers."""
    try:
        counts = [int(v) for v in str(text).replace(" ", "").split(",") if v]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise LightcutsError(f"--rooms {text!r}: expected comma-separated positive integers")
    return sorted(set(counts))
