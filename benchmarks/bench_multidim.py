"""Multidimensional lightcuts against per-eye-ray lightcuts on a config at a reduced size.

Times (kernels loaded on one pixel first, untimed): lightcuts at 1 spp and at N spp, multidimensional
at N gather points (the config's thin lens, if any: lightcuts renders a pinhole), in wall and in CPU
seconds (all threads; the ratios of CPU times move less with a shared machine's load); pairs per pixel;
shadow rays per second of the multidimensional kernel, over its whole time and over the time
visibility adds to it (the image again without shadow rays, whose cut differs a little); per-pixel
luminance error of the N-spp images against the N-point brute-force reference (the same eye rays)
on a seeded sample of lit pixels (lit in the 1-spp lightcut image, so the sample does not depend on
the image measured; ``--pixels 0``: no errors; ``--no-lightcuts-n``: no N-spp lightcut image).

    PYTHONPATH=. python benchmarks/bench_multidim.py configs/cornell.yaml --size 128 --spp 16 --pixels 200
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config.schema import load_config
    from lightcuts.lights.lightset import LUMINANCE
    from lightcuts.integrators.lightcut import render_image
    from lightcuts.integrators.multidim import render_multidimensional, render_multidimensional_reference
    from lightcuts.scene.scene import Camera

    p = argparse.ArgumentParser()
    p.add_argument("config")
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--pixels", type=int, default=200)
    p.add_argument("--set", dest="overrides", action="append", default=[])
    p.add_argument("--no-lightcuts-n", action="store_true",
                   help="skip the N-spp lightcut image (its time and error): the two ratios to the 1-spp image only")
    a = p.parse_args()
    cfg = load_config(a.config, a.overrides)
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    c = scene.camera
    w = a.size
    h = max(1, round(a.size * c.height / c.width))
    camera = Camera(c.position, c.look_at, c.up, c.fov, w, h)
    caster = plan.make_caster(scene)
    lights = plan.lights(scene, caster, None)
    t0 = time.perf_counter()
    trees = plan.trees(lights)
    print(f"lights {sum(len(v) for v in lights.values())}, trees {time.perf_counter() - t0:.1f} s")
    clamp = cfg.render.clamp
    common = dict(camera=camera, seed=cfg.seed, clamp=clamp.enabled, clamp_vpls=clamp.vpls,
                  clamp_min_distance=clamp.min_distance if clamp.mode == "diagonal" else None)
    cut = dict(eps=cfg.render.eps, max_cut=cfg.render.max_cut)
    # The multidimensional integrator's parameters from the config (render.integrator: {type:
    # multidimensional, representatives: R, gather_representatives: RG}), its defaults otherwise.
    md_params = dict(plan.integrator.params) if plan.integrator.name == "multidimensional" else {}
    md_params.update(aperture=cfg.camera.aperture, focus_distance=cfg.camera.focus_distance)

    def timed(fn, *args, **kw):
        """fn's result, its wall time and the process's CPU time (all threads) over it."""
        fn(*args, **{**kw, "crop": (0, 0, 1, 1)})  # load the kernel
        t, c = time.perf_counter(), time.process_time()
        r = fn(*args, **kw)
        return r, time.perf_counter() - t, time.process_time() - c

    lc1, t1, c1 = timed(render_image, scene, caster, lights, trees, spp=1, **common, **cut)
    md, tm, cm = timed(render_multidimensional, scene, caster, lights, trees, spp=a.spp, **common, **cut, **md_params)
    print(f"lightcuts 1 spp {t1:.2f} s (cut {lc1.cut_size.mean():.0f}); multidimensional {a.spp} {tm:.2f} s "
          f"(pairs per pixel {md.cut_size.mean():.0f}, shadow rays per pixel {md.shadow_rays / (w * h):.0f})")
    # On a shared machine the CPU-time ratios move less with the load than the wall-time ones.
    print(f"time ratios: md/lc1 {tm / t1:.2f} (CPU time: {cm / c1:.2f})")
    lcn = None
    if not a.no_lightcuts_n:
        lcn, tn, cn = timed(render_image, scene, caster, lights, trees, spp=a.spp, **common, **cut)
        print(f"lightcuts {a.spp} spp {tn:.2f} s (cut per eye ray {lcn.cut_size.mean():.0f}, per pixel "
              f"{a.spp * lcn.cut_size.mean():.0f}): lc{a.spp}/md {tn / tm:.2f} (CPU time: {cn / cm:.2f})")
    _, tv, cv = timed(render_multidimensional, scene, caster, lights, trees, spp=a.spp, **common, **cut, **md_params,
                      visibility=False)
    print(f"multidimensional shadow rays {md.shadow_rays}: {md.shadow_rays / tm / 1e6:.2f} M/s over the image, "
          f"{md.shadow_rays / max(tm - tv, 1e-9) / 1e6:.2f} M/s over the {tm - tv:.2f} s visibility adds; per CPU "
          f"second {md.shadow_rays / cm / 1e6:.2f} M and {md.shadow_rays / max(cm - cv, 1e-9) / 1e6:.2f} M "
          f"(lightcuts 1 spp: {lc1.shadow_rays / t1 / 1e6:.2f} M/s, {lc1.shadow_rays / c1 / 1e6:.2f} M per CPU second)")
    if a.pixels <= 0:
        caster.close()
        return
    lum = lc1.image @ LUMINANCE
    rng = np.random.default_rng(cfg.seed)
    lit = np.argwhere(lum > 1e-3 * lum.max())
    pick = lit[rng.choice(len(lit), min(a.pixels, len(lit)), replace=False)]
    pix = pick[:, ::-1].copy()  # (x, y)
    t = time.perf_counter()
    lens = dict(aperture=cfg.camera.aperture, focus_distance=cfg.camera.focus_distance)
    ref = render_multidimensional_reference(scene, caster, lights, spp=a.spp, pixels=pix, **common, **lens)
    print(f"reference on {len(pix)} pixels: {time.perf_counter() - t:.1f} s")
    r = (ref.image[:, 0] @ LUMINANCE).astype(np.float64)
    for name, img in (("multidimensional", md.image), (f"lightcuts {a.spp} spp", None if lcn is None else lcn.image)):
        if img is None:
            continue
        v = (img[pick[:, 0], pick[:, 1]] @ LUMINANCE).astype(np.float64)
        err = np.abs(v - r) / r
        print(f"{name}: error median {np.median(err):.4f}, p99 {np.percentile(err, 99):.4f}, max {err.max():.4f}")
    caster.close()


if __name__ == "__main__":
    main()
