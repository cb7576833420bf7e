"""Tree quality at matched error: cut size against the reference error, per builder and cone weight c.

Lightcuts stops refining when every cluster's error bound is <= eps times the pixel's estimate, so
two trees rendered at the same eps do not give the same error: a tree whose bounds are looser near
the stop spends more of the budget. Comparing mean cut sizes at one eps (``bench_render.py``'s
``cut-<builder>`` rows) therefore mixes tree quality with error. This script renders a crop of the
Cornell box (cornell.yaml's lights) at several eps for each builder and each cone weight c
(``c = factor * diagonal / 16``, the metric's default), measures the error against the brute-force
reference, and interpolates each curve (log cut against log error) at a common mean error: the
cut size a tree needs for that error.

Measured 2026-11-22 (128 x 128 camera, the centre 64 x 64 crop, 101,592 lights; 45 s):

- ``agglomerative``: c at 4x the default shrinks the cut at eps 0.02 by 16% (212 -> 178) but raises
  the mean error from 0.93% to 1.27%; at a matched 1% mean error the cut is 202 / 200 / 216 for
  c = 1x / 2x / 4x the default, so the default is as good as any;
- at 1% mean error and the default c: agglomerative 202, divisive-6d 274, divisive-3d 315 (26% and
  36% smaller), where eps 0.02 shows 212 / 227 / 234 (7% and 9%); divisive-6d improves with a larger
  c (235 at 2x, 213 at 4x), divisive-3d does not use c.

    python benchmarks/bench_cone_weight.py [--size 128] [--crop 64] [--factors 1,4]
        [--builders agglomerative,divisive-6d,divisive-3d,saoh] [--eps 0.01,0.015,0.02,0.03,0.04]
        [--at-error 0.01] [--indirect 100000]

Results (one row per builder, factor and eps, and the interpolated rows with eps empty) go to
benchmarks/results/cone_weight.csv.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
from lightcuts.lights.direct import direct_lights  # noqa: E402
from lightcuts.lights.indirect import indirect_lights  # noqa: E402
from lightcuts.lights.lightset import LUMINANCE, LightSet  # noqa: E402
from lightcuts.integrators.lightcut import render_image, render_reference  # noqa: E402
from lightcuts.scene.cornell import cornell_box  # noqa: E402
from lightcuts.scene.scene import Camera  # noqa: E402
from lightcuts.trees import build_tree, default_c, tree_spec  # noqa: E402

FIELDS = ("builder", "c_factor", "eps", "n_lights", "pixels", "cut_size_mean", "shadow_rays_per_pixel",
          "error_mean", "error_median", "error_p99")


def at_error(errors: list[float], cuts: list[float], target: float) -> float:
    """Cut size at mean error ``target``, interpolated linearly in log-log (nan outside the range)."""
    order = np.argsort(errors)
    e, c = np.log(np.asarray(errors)[order]), np.log(np.asarray(cuts)[order])
    t = np.log(target)
    return float(np.exp(np.interp(t, e, c))) if e[0] <= t <= e[-1] else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128, help="camera resolution (square)")
    ap.add_argument("--crop", type=int, default=64, help="side of the centre crop rendered and checked")
    ap.add_argument("--factors", default="1,4", help="c as multiples of the default (diagonal / 16)")
    ap.add_argument("--builders", default="agglomerative,divisive-6d,divisive-3d,saoh")
    ap.add_argument("--eps", default="0.01,0.015,0.02,0.03,0.04")
    ap.add_argument("--at-error", type=float, default=0.01, help="mean relative error the curves are compared at")
    ap.add_argument("--indirect", type=int, default=100_000)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "cone_weight.csv"))
    args = ap.parse_args()
    factors = [float(f) for f in args.factors.split(",")]
    epses = [float(e) for e in args.eps.split(",")]

    scene = cornell_box()
    cam = scene.camera
    camera = Camera(cam.position, cam.look_at, cam.up, cam.fov, args.size, args.size)
    caster = make_caster(scene, "embree")
    lights = LightSet.concatenate([direct_lights(scene, 1024, seed=1),
                                   indirect_lights(scene, caster, args.indirect, seed=2)])
    c0 = default_c(lights)
    sets = {"oriented": lights}
    h = args.size // 2 - args.crop // 2
    crop = (h, h, h + args.crop, h + args.crop)
    ref = render_reference(scene, caster, sets, camera=camera, crop=crop).image @ LUMINANCE
    keep = ref > 1e-3 * ref.max()
    print(f"Cornell box, {args.size}x{args.size} camera, centre {args.crop}x{args.crop} crop, {len(lights)} lights, "
          f"default c = {c0:.1f} (diagonal / 16)")
    print(f"{'builder':>14} {'c/def':>6} {'eps':>6} {'cut':>7} {'rays/px':>8} {'err mean':>9} {'median':>7} "
          f"{'p99':>7}")
    rows, summary = [], []
    for builder in args.builders.split(","):
        done = {}  # the renders of a tree already seen: a builder that reads no c returns the same tree
        for f in factors:
            tree = build_tree(lights, tree_spec(builder, c=c0 * f, drop_unread=True), seed=0)
            key = (tree.left.tobytes(), tree.right.tobytes(), tree.rep.tobytes())
            trees = {"oriented": tree}
            errors, cuts = [], []
            for eps in epses:
                if (key, eps) not in done:
                    done[key, eps] = render_image(scene, caster, sets, trees, camera=camera, crop=crop, eps=eps)
                res = done[key, eps]
                err = np.abs(res.image @ LUMINANCE - ref)[keep] / ref[keep]
                row = dict(builder=builder, c_factor=f, eps=eps, n_lights=len(lights), pixels=int(keep.sum()),
                           cut_size_mean=round(float(res.cut_size.mean()), 2),
                           shadow_rays_per_pixel=round(res.shadow_rays / res.cut_size.size, 2),
                           error_mean=round(float(err.mean()), 5), error_median=round(float(np.median(err)), 5),
                           error_p99=round(float(np.percentile(err, 99)), 5))
                rows.append(row)
                errors.append(float(err.mean()))
                cuts.append(float(res.cut_size.mean()))
                print(f"{builder:>14} {f:>6g} {eps:>6g} {row['cut_size_mean']:>7.1f} "
                      f"{row['shadow_rays_per_pixel']:>8.1f} {100 * err.mean():>8.2f}% "
                      f"{100 * np.median(err):>6.2f}% {100 * np.percentile(err, 99):>6.2f}%", flush=True)
            cut = at_error(errors, cuts, args.at_error)
            summary.append((builder, f, cut))
            rows.append(dict(builder=builder, c_factor=f, eps="", n_lights=len(lights), pixels=int(keep.sum()),
                             cut_size_mean=round(cut, 2), shadow_rays_per_pixel="", error_mean=args.at_error,
                             error_median="", error_p99=""))
    print(f"\ncut size at {100 * args.at_error:g}% mean error (interpolated):")
    for builder, f, cut in summary:
        shown = f"{cut:7.1f}" if np.isfinite(cut) else "outside the errors of --eps"
        print(f"{builder:>14} c = {f:g} x default: {shown}")
    print(f"-> {save_csv(args.out, rows, FIELDS)}")
    caster.close()


if __name__ == "__main__":
    main()
