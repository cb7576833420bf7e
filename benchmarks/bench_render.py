"""Lightcuts render time on the Cornell box: 512 x 512, 1 spp, 1,024 direct + 100,000 indirect lights.

Measured (medians of --repeats runs after a numba warm-up render of a small crop):

  full           the whole image with the agglomerative tree (divisive-6d if agglomerative is not
                 registered; the table says which): wall time, mean cut size, shadow rays per pixel
  no-visibility  the same with shadow rays skipped (every light visible): the cut without Embree
  eye-only       the same eye rays with no lights: camera rays, emitters and the kernel's overhead
  crop-lightcuts / crop-reference
                 a 64 x 64 crop at the image centre, lightcuts against the brute-force reference
                 (every light, one shadow ray each; one run: it is slow), and their speed-up and error
  cut-<builder>  mean cut size of the other builders on the same lights (one run each)

Time split (method): Embree's shadow-ray share is ``full - no-visibility``, the cut's is
``no-visibility - eye-only``, the rest ``eye-only``. Skipping shadow rays changes the cut a little
(every representative is visible, so estimates are larger and the cut stops earlier: both cut sizes
are printed); the split is an estimate, not an exact attribution. The in-kernel shadow-ray rate
(shadow rays / Embree share) is printed next to it.

The machine has 2 cores shared with other work: wall times are noisy, so the process CPU time (all
threads) is recorded too; CPU seconds / threads estimates the wall time on idle cores. The load
average at the start is printed and saved. Results go to benchmarks/results/render.csv.

    python benchmarks/bench_render.py [--size 512] [--direct 1024] [--indirect 100000] [--repeats 3] [--quick]

``--quick`` times only the full image and prints it (no CSV).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
sys.path.insert(0, str(ROOT / "benchmarks"))
from common import load_average, timed  # noqa: E402
from lightcuts.lights.direct import direct_lights  # noqa: E402
from lightcuts.lights.indirect import indirect_lights  # noqa: E402
from lightcuts.lights.lightset import LUMINANCE, LightSet  # noqa: E402
from lightcuts.integrators.lightcut import render_image, render_reference  # noqa: E402
from lightcuts.scene.cornell import cornell_box  # noqa: E402
from lightcuts.scene.scene import Camera  # noqa: E402
from lightcuts.trees import BUILDERS, build_tree  # noqa: E402

FIELDS = ("case", "builder", "resolution", "n_lights", "eps", "seconds", "cpu_seconds", "runs", "cut_size_mean",
          "shadow_rays_per_pixel", "threads", "load_avg", "notes")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--direct", type=int, default=1024)
    ap.add_argument("--indirect", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--crop", type=int, default=64, help="side of the centre crop rendered with the reference")
    ap.add_argument("--eps", type=float, default=0.02)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "render.csv"))
    ap.add_argument("--quick", action="store_true", help="only the full image (no split, crop or other builders)")
    args = ap.parse_args()

    load = load_average()
    threads = numba.get_num_threads()
    scene = cornell_box()
    c = scene.camera
    camera = Camera(c.position, c.look_at, c.up, c.fov, args.size, args.size)
    caster = make_caster(scene, "embree")
    t0 = time.perf_counter()
    lights = LightSet.concatenate([direct_lights(scene, args.direct, seed=1),
                                   indirect_lights(scene, caster, args.indirect, seed=2)])
    t_lights = time.perf_counter() - t0
    n = len(lights)
    builder = "agglomerative" if "agglomerative" in BUILDERS else "divisive-6d"
    t0 = time.perf_counter()
    tree = build_tree(lights, builder, seed=0)
    t_build = time.perf_counter() - t0
    sets, trees = {"oriented": lights}, {"oriented": tree}
    print(f"Cornell box {args.size}x{args.size}, 1 spp, {n} lights ({args.direct} direct + "
          f"{n - args.direct} indirect, generated in {t_lights:.1f} s), tree {builder} built in {t_build:.1f} s, "
          f"eps {args.eps}, {threads} threads, load average {load:.2f} at start")

    def render(**kw):
        return render_image(scene, caster, sets, trees, camera=camera, eps=args.eps, **kw)

    render(crop=(0, 0, 8, 8))  # numba warm-up (compile or load from the cache)
    rows = []
    pixels = args.size * args.size
    res = f"{args.size}x{args.size}"

    def row(case, timing, runs, notes="", b=builder, resolution=res):
        seconds, cpu, result = timing
        px = result.image.shape[0] * result.image.shape[1]
        rows.append(dict(case=case, builder=b, resolution=resolution, n_lights=n, eps=args.eps,
                         seconds=round(seconds, 4), cpu_seconds=round(cpu, 4), runs=runs,
                         cut_size_mean=round(float(result.cut_size.mean()), 2),
                         shadow_rays_per_pixel=round(result.shadow_rays / px, 2), threads=threads,
                         load_avg=round(load, 2), notes=notes))
        return rows[-1]

    full_t = timed(render, args.repeats)
    row("full", full_t, args.repeats)
    if args.quick:
        r = rows[-1]
        print(f"full {res}: {r['seconds']:.2f} s wall median of {args.repeats}, {r['cpu_seconds']:.2f} s CPU, "
              f"cut {r['cut_size_mean']:.1f}, {r['shadow_rays_per_pixel']:.1f} shadow rays/pixel (not saved)")
        caster.close()
        return
    novis_t = timed(lambda: render(visibility=False), args.repeats)
    row("no-visibility", novis_t, args.repeats, "shadow rays skipped (V = 1)")
    eye_t = timed(lambda: render_image(scene, caster, {}, {}, camera=camera), args.repeats)
    row("eye-only", eye_t, args.repeats, "no lights: eye rays, emitters, kernel overhead")
    t_full, t_novis, t_eye, full = full_t[0], novis_t[0], eye_t[0], full_t[2]

    h = args.size // 2 - args.crop // 2
    crop = (h, h, h + args.crop, h + args.crop)
    cres = f"{args.crop}x{args.crop} crop"
    crop_t = timed(lambda: render(crop=crop), args.repeats)
    row("crop-lightcuts", crop_t, args.repeats, resolution=cres)
    ref_t = timed(lambda: render_reference(scene, caster, sets, camera=camera, crop=crop), 1)
    (t_crop, _, lc), (t_ref, _, ref) = crop_t, ref_t
    a, b = lc.image @ LUMINANCE, ref.image @ LUMINANCE
    keep = b > 1e-3 * b.max()
    err = np.abs(a - b)[keep] / b[keep]
    row("crop-reference", ref_t, 1, f"speed-up {t_ref / t_crop:.0f}x; lightcuts error median "
        f"{100 * np.median(err):.2f}% p99 {100 * np.percentile(err, 99):.2f}%", b="-", resolution=cres)

    for other in ("agglomerative", "divisive-6d", "divisive-3d", "saoh"):
        if other == builder or other not in BUILDERS:
            continue
        t0 = time.perf_counter()
        other_tree = build_tree(lights, other, seed=0)
        t_other_build = time.perf_counter() - t0
        other_t = timed(lambda: render_image(scene, caster, sets, {"oriented": other_tree}, camera=camera,
                                             eps=args.eps), 1)
        row(f"cut-{other}", other_t, 1, f"tree built in {t_other_build:.1f} s", b=other)

    print()
    print(f"{'case':16s} {'builder':14s} {'resolution':14s} {'seconds':>8s} {'cpu s':>8s} {'runs':>4s} {'cut':>7s} "
          f"{'rays/px':>8s}  notes")
    for r in rows:
        print(f"{r['case']:16s} {r['builder']:14s} {r['resolution']:14s} {r['seconds']:8.2f} {r['cpu_seconds']:8.2f} "
              f"{r['runs']:4d} {r['cut_size_mean']:7.1f} {r['shadow_rays_per_pixel']:8.1f}  {r['notes']}")
    rays_s = t_full - t_novis
    print()
    print(f"{res} target <= 10 s: {t_full:.2f} s wall ({pixels / t_full / 1e3:.1f} K pixels/s), "
          f"{full_t[1]:.2f} s CPU over {threads} threads (about {full_t[1] / threads:.2f} s wall on idle cores)")
    print(f"time split of the full render (method in the docstring): shadow rays {rays_s:.2f} s "
          f"({100 * rays_s / t_full:.0f}%, {full.shadow_rays / max(rays_s, 1e-9) / 1e6:.1f} M rays/s in the cut), "
          f"cut evaluation {t_novis - t_eye:.2f} s ({100 * (t_novis - t_eye) / t_full:.0f}%), "
          f"eye rays and the rest {t_eye:.2f} s ({100 * t_eye / t_full:.0f}%)")
    print(f"crop {args.crop}x{args.crop}: lightcuts {t_crop:.3f} s, reference {t_ref:.2f} s, "
          f"speed-up {t_ref / t_crop:.0f}x")

    out = save_csv(args.out, rows, FIELDS)
    print(f"-> {out}")
    caster.close()


if __name__ == "__main__":
    main()
