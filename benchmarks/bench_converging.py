"""Converging lightcuts against a path tracer: energy, equal-time error, slope, cost.

Per config, at a reduced size (``--size`` pixels wide), against one long path-traced render
(``--spp``, seed + 1) by ``--renderer``: Mitsuba 3 (default) or lightcuts' own path tracer with the
exact BRDF (lightcuts.integrators.path):

* ``before``: the config as it is (one pass, no compensation, fixed representatives);
* ``after``: compensation, ``--representatives``, ``--passes`` passes;
  each row: energy ratio lightcuts / Mitsuba, per-pixel and 8x8-block median relative error, seconds;
* ``cost``: one compensated pass over one plain pass (lights, trees and image; median of
  ``--repeats`` interleaved pairs, plain first) and the render alone;
* with ``--curve``: passes 1, 2, 4, ... ``--curve-passes`` of the ``after`` settings and the path tracer
  at the same times (:func:`lightcuts.pipeline.convergence.error_curve`), the fitted slope of lightcuts' error
  against time, and both methods' errors at the curve points nearest 10 s and 60 s.

Prints a table and writes ``benchmarks/results/converging-<renderer>-<representatives>.csv`` (and
``converging-curve-<renderer>-<representatives>-<name>.csv``);
the long render is kept there and reused by later runs with the same config name, size and spp.

    PYTHONPATH=. python benchmarks/bench_converging.py configs/cornell.yaml configs/kitchen.yaml --curve
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def run(path, overrides):
    from lightcuts.config.schema import load_config
    from lightcuts.pipeline.plan import plan_run

    cfg = load_config(path, overrides)
    return cfg, plan_run(cfg, render=True)


def passes_image(cfg, plan, scene, envmap):
    from lightcuts.pipeline.passes import render_passes

    with plan.make_caster(scene) as caster:
        return render_passes(cfg, plan, scene, caster, envmap, progress=False)


def main() -> None:
    from lightcuts.pipeline.convergence import PathTracer, error_curve, long_reference, measures
    from lightcuts.io import save_csv

    p = argparse.ArgumentParser()
    p.add_argument("configs", nargs="+")
    p.add_argument("--size", type=int, default=128, help="image width in pixels (height keeps the aspect)")
    p.add_argument("--spp", type=int, default=4096, help="samples per pixel of the long path-traced render")
    p.add_argument("--renderer", default="mitsuba", choices=("mitsuba", "lightcuts"),
                   help="the path tracer: Mitsuba 3's or lightcuts' own (exact BRDF)")
    p.add_argument("--passes", type=int, default=16)
    p.add_argument("--representatives", default="stochastic", choices=("fixed", "stochastic"))
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--curve", action="store_true")
    p.add_argument("--curve-passes", type=int, default=64)
    p.add_argument("--set", dest="overrides", action="append", default=[])
    a = p.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for path in a.configs:
        cfg0, plan0 = run(path, a.overrides)
        cam = plan0.scene().camera
        size = [a.size, max(1, round(a.size * cam.height / cam.width))]
        base = list(a.overrides) + [f"camera.resolution={size}"]
        cfg, plan = run(path, base)
        scene, envmap = plan.scene(), plan.environment()
        tracer = PathTracer(a.renderer)
        tracer.check(cfg)
        cache = out / f"converging-reference-{a.renderer}-{cfg.name}-{size[0]}x{size[1]}-{a.spp}.npz"
        if cache.exists():  # the long render of an earlier run with the same config, size and spp
            with np.load(cache) as z:
                ref, t_ref = z["image"], float(z["seconds"])
        else:
            print(f"{cfg.name}: {a.renderer} {a.spp} spp at {size[0]}x{size[1]} ...", flush=True)
            ref, t_ref = long_reference(cfg, scene, envmap, a.spp, tracer=tracer)
            np.savez(cache, image=ref, seconds=t_ref)
        after = base + ["render.compensation=true", f"render.representatives={a.representatives}"]
        for label, ov in (("before", base), ("after", after + [f"render.passes={a.passes}"])):
            c, pl = run(path, ov)
            res = passes_image(c, pl, scene, envmap)
            rows.append({"config": cfg.name, "row": label, "passes": c.render.passes, "seconds": res.seconds,
                         **measures(res.image, ref), "reference_spp": a.spp, "reference_seconds": t_ref})
            print(rows[-1], flush=True)
        # cost of compensation per pass: interleaved pairs, the pass after the first (kernels loaded)
        plain, comp = [], []
        for _ in range(a.repeats):
            for ov, acc in ((base, plain), (after, comp)):
                c, pl = run(path, ov + ["render.passes=2"])
                acc.append(passes_image(c, pl, scene, envmap).records[1])
        for what, key in (("pass", "seconds"), ("render", "render_seconds")):
            rows.append({"config": cfg.name, "row": f"cost per {what}", "passes": 1,
                         "seconds": statistics.median(r[key] for r in comp),
                         "energy_ratio": statistics.median(r[key] for r in comp) /
                         statistics.median(r[key] for r in plain)})
            print(rows[-1], flush=True)
        if a.curve:
            c, pl = run(path, after + [f"render.passes={a.curve_passes}"])
            with pl.make_caster(scene) as caster:
                curve = error_curve(c, pl, scene, envmap, caster, ref, progress=False, tracer=tracer)
            save_csv(out / f"converging-curve-{a.renderer}-{a.representatives}-{cfg.name}.csv", curve["rows"])
            lc = [r for r in curve["rows"] if r["method"] == "lightcuts"]
            mi = [r for r in curve["rows"] if r["method"] != "lightcuts"]
            for target in (10.0, 60.0):
                i = min(range(len(lc)), key=lambda k: abs(lc[k]["seconds"] - target))
                for method, r in (("lightcuts", lc[i]), (tracer.label, mi[i])):
                    rows.append({"config": cfg.name, "row": f"equal time ~{target:.0f} s: {method}",
                                 "passes": r["passes"], "seconds": r["seconds"], "energy_ratio": r["energy_ratio"],
                                 "pixel_median": r["pixel_median"], "block8_median": r["block8_median"]})
                    print(rows[-1], flush=True)
            rows.append({"config": cfg.name, "row": "slope (pixel, block8)", "passes": a.curve_passes,
                         "pixel_median": curve["slope"]["pixel_median"],
                         "block8_median": curve["slope"]["block8_median"]})
            print(rows[-1], flush=True)
        tracer.close()
    fields = ["config", "row", "passes", "seconds", "energy_ratio", "pixel_median", "block8_median", "reference_spp",
              "reference_seconds"]
    save_csv(out / f"converging-{a.renderer}-{a.representatives}.csv", rows, fields)
    print()
    print("| config | row | passes | seconds | energy ratio (cost: ratio) | pixel median | block8 median |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    f = lambda v, s: "" if v is None else s.format(v)  # noqa: E731
    for r in rows:
        if r["row"].startswith("slope"):
            print(f"| {r['config']} | {r['row']} | {r['passes']} | | | {f(r['pixel_median'], '{:.2f}')} | "
                  f"{f(r['block8_median'], '{:.2f}')} |")
            continue
        print(f"| {r['config']} | {r['row']} | {f(r.get('passes'), '{}')} | {f(r.get('seconds'), '{:.2f}')} | "
              f"{f(r.get('energy_ratio'), '{:.4f}')} | {f(r.get('pixel_median'), '{:.2%}')} | "
              f"{f(r.get('block8_median'), '{:.2%}')} |")


if __name__ == "__main__":
    main()
