"""Stochastic lightcuts against the lightcut, a small demonstration (not a timing benchmark).

Per config at ``--size`` pixels wide, with the config's lights and trees (one set for every row):
the lightcut as configured, then ``stochastic-lightcuts`` at each ``--max-cut`` and ``--spp``, with
clamping as configured and off. Each row: render seconds (whole image, kernel loaded), shadow rays
and cut nodes per pixel; against the all-lights reference of the same lights, clamping and eye
rays on ``--pixels`` seeded pixels: the energy ratio (mean luminance row / reference) and the
per-pixel median relative error; against lightcuts' own path tracer (``--path-spp``, emitter pixels
left out): the energy ratio and the per-pixel and 8x8-block median relative errors, the path
tracer's own noise beside them.

With ``--direct``, direct light alone (no indirect VPLs): ``stochastic-lightcuts`` (the first
``--max-cut``, the last ``--spp``) over the emitting triangles (``lights.direct.source: triangles``)
and over the config's direct point lights, each against the path tracer's direct light
(``{type: path, max_depth: 1}``, ``--path-spp``).

    PYTHONPATH=. python benchmarks/bench_stochastic.py configs/cornell.yaml configs/kitchen.yaml
    PYTHONPATH=. python benchmarks/bench_stochastic.py configs/cornell.yaml configs/kitchen.yaml --direct
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main(argv=None) -> None:
    from lightcuts.config import load_config
    from lightcuts.integrators.path import Path as PathTracer
    from lightcuts.integrators.primary import emitter_mask
    from lightcuts.integrators.registry import make_integrator
    from lightcuts.lights.lightset import LUMINANCE
    from lightcuts.pipeline.comparing import sample_pixels
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.report.images import compare_images, relative_error

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("configs", nargs="+")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--max-cut", type=int, nargs="+", default=[8, 32])
    ap.add_argument("--spp", type=int, nargs="+", default=[1, 4])
    ap.add_argument("--pixels", type=int, default=1024)
    ap.add_argument("--path-spp", type=int, default=512)
    ap.add_argument("--direct", action="store_true", help="direct light: triangle lights against point lights")
    args = ap.parse_args(argv)
    if args.direct:
        return direct(args)

    for path in args.configs:
        size = _size(path, args.size)
        cfg = load_config(path, [f"camera.resolution={size}"])
        plan = plan_run(cfg, render=True)
        scene = plan.scene()
        with plan.make_caster(scene) as caster:
            lights = plan.lights(scene, caster)
            trees = plan.trees(lights)
            n = sum(len(ls) for ls in lights.values())
            sample = sample_pixels(size[0], size[1], None, args.pixels, cfg.seed)
            mask = emitter_mask(scene, caster)
            t0 = time.perf_counter()
            halves = [PathTracer(spp=(args.path_spp + 1) // 2).render(scene, caster, {}, None, seed=s).image
                      for s in (cfg.seed + 1, (cfg.seed + 1) ^ 1)]
            truth = (halves[0].astype(np.float64) + halves[1]) / 2
            print(f"{cfg.name} {size[0]}x{size[1]}, {n:,} lights; path tracer {args.path_spp} spp "
                  f"{time.perf_counter() - t0:.1f} s")
            rows = [("lightcuts", cfg)]
            for clamp in (cfg.render.clamp.enabled, not cfg.render.clamp.enabled):
                for k in args.max_cut:
                    for spp in args.spp:
                        c = cfg.model_copy(update={"render": cfg.render.model_copy(update={
                            "spp": spp, "integrator": {"type": "stochastic-lightcuts", "max_cut": k},
                            "clamp": cfg.render.clamp.model_copy(update={"enabled": clamp})})})
                        rows.append((f"slc {k} spp {spp}" + ("" if clamp else " unclamped"), c))
            references = {}
            print("| row | render s | rays/px | cut/px | energy vs all-lights | pixel err vs all-lights "
                  "| energy vs path | pixel / block8 err vs path |")
            print("| --- | --- | --- | --- | --- | --- | --- | --- |")
            for label, c in rows:
                integ = make_integrator(c)
                integ.render(scene, caster, lights, trees, crop=(0, 0, 1, 1))  # the kernel loaded
                t0 = time.perf_counter()
                r = integ.render(scene, caster, lights, trees, seed=c.seed)
                seconds = time.perf_counter() - t0
                key = (c.render.spp, c.render.clamp.enabled)
                if key not in references:
                    references[key] = integ.reference().render(scene, caster, lights, None, seed=c.seed,
                                                               pixels=sample).image[:, 0]
                ref = references[key]
                at = r.image[sample[:, 1], sample[:, 0]]
                energy = float((at @ LUMINANCE).sum() / (ref @ LUMINANCE).sum())
                err = relative_error(at[:, None], ref[:, None])["median"]
                vs = compare_images(r.image, truth, mask=mask, halves=tuple(halves))
                noise = vs["reference_noise"]
                print(f"| {label} | {seconds:.2f} | {r.shadow_rays / r.cut_size.size:.0f} | {r.cut_size.mean():.1f} "
                      f"| {energy:.4f} | {100 * err:.2f}% | {vs['energy_ratio']:.4f} "
                      f"| {100 * vs['pixel']['median']:.2f}% / {100 * vs['block8']['median']:.2f}% "
                      f"(noise {100 * noise['pixel']['median']:.2f}% / {100 * noise['block8']['median']:.2f}%) |",
                      flush=True)


def _size(path, width: int) -> list:
    from lightcuts.config import load_config

    w, h = load_config(path).camera.resolution or (512, 512)
    return [width, max(1, round(width * h / w))]


def direct(args) -> None:
    """The ``--direct`` rows (module docstring)."""
    from lightcuts.config import load_config
    from lightcuts.integrators.path import Path as PathTracer
    from lightcuts.integrators.primary import emitter_mask
    from lightcuts.integrators.registry import make_integrator
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.report.images import compare_images

    print("| scene | direct lights | lights | render s | energy vs path | pixel / block8 err vs path (path's noise) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for path in args.configs:
        size = _size(path, args.size)
        truth = None
        for source in ("triangles", "samples"):
            cfg = load_config(path, [f"camera.resolution={size}", "lights.indirect.count=0",
                                     f"lights.direct.source={source}", f"render.spp={args.spp[-1]}",
                                     f"render.integrator={{type: stochastic-lightcuts, max_cut: {args.max_cut[0]}}}"])
            plan = plan_run(cfg, render=True)
            scene = plan.scene()
            with plan.make_caster(scene) as caster:
                lights = plan.lights(scene, caster)
                trees = plan.trees(lights)
                if truth is None:
                    halves = [PathTracer(spp=(args.path_spp + 1) // 2, max_depth=1).render(
                        scene, caster, {}, None, seed=s).image for s in (cfg.seed + 1, (cfg.seed + 1) ^ 1)]
                    truth = (halves[0].astype(np.float64) + halves[1]) / 2
                    mask = emitter_mask(scene, caster)
                integ = make_integrator(cfg, plan.integrator)
                integ.render(scene, caster, lights, trees, crop=(0, 0, 1, 1))  # the kernel loaded
                t0 = time.perf_counter()
                r = integ.render(scene, caster, lights, trees, seed=cfg.seed)
                seconds = time.perf_counter() - t0
                vs = compare_images(r.image, truth, mask=mask, halves=tuple(halves))
                noise = vs["reference_noise"]
                print(f"| {cfg.name} {size[0]}x{size[1]} | {source} | {sum(len(ls) for ls in lights.values()):,} "
                      f"| {seconds:.2f} | {vs['energy_ratio']:.4f} | {100 * vs['pixel']['median']:.2f}% / "
                      f"{100 * vs['block8']['median']:.2f}% ({100 * noise['pixel']['median']:.2f}% / "
                      f"{100 * noise['block8']['median']:.2f}%) |", flush=True)


if __name__ == "__main__":
    main()
