"""The path integrator's light samplers side by side: the noise of each at equal spp (a
demonstration, not a timing study).

Per scene and sampler (``power``, ``uniform``, ``tree`` with ``agglomerative``, ``divisive-3d``, ``saoh``),
the path integrator renders the image with two seeds at ``--spp``; from the two luminance images
a, b the per-pixel variance estimate is (a - b)^2 / 2. Printed: the median over pixels of that
variance over the pixel's squared mean (heavy-tailed samplers look good on it: most pixels never
see their rare large samples), the image's variance, (a - b)^2 / 2 averaged over the pixels, over
its squared mean luminance (the figure the README quotes), the mean luminance, the render seconds
of one image (the second of two; indicative only on shared cores) and for a tree its build seconds
and bytes per light.

Scenes: the shipped configs ``--configs`` (``cornell``: two emitting triangles; ``mesh-gallery``:
208; ``kitchen``: 320; ``rooms``: 1,232) at --size x --size, every bounce; the test scene of six
emitters over the floor the camera sees and 2,000 a hundred times farther with 30 times their power
(tests/integrators/lamps.py), direct light alone (max_depth 1) and every bounce; and 306 emitters
at one to six times the near distance, direct light alone.

    PYTHONPATH=. python benchmarks/bench_path_samplers.py [--size 64] [--spp 16] [--configs cornell,kitchen]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "integrators"))

SAMPLERS = (("power", None), ("uniform", None), ("tree", "agglomerative"), ("tree", "divisive-3d"), ("tree", "saoh"))


def two_seeds(scene, sampler: str, builder, spp: int, max_depth: int):
    """The two seeds' luminance images, the sampler's record and one image's render seconds."""
    from lightcuts.accel import make_caster
    from lightcuts.integrators.path import Path as PathIntegrator
    from lightcuts.lights.lightset import LUMINANCE
    from lightcuts.trees.spec import tree_spec

    integ = PathIntegrator(spp=spp, max_depth=max_depth, light_sampler=sampler,
                           tree=tree_spec(builder) if builder else None)
    images, seconds = [], 0.0
    with make_caster(scene) as caster:
        forest = integ.forest({}, None, scene)
        integ.render(scene, caster, {}, None, forest=forest, crop=(0, 0, 1, 1))  # the kernel loaded
        for seed in (1, 2):
            t0 = time.perf_counter()
            r = integ.render(scene, caster, {}, None, forest=forest, seed=seed)
            seconds = time.perf_counter() - t0
            images.append(r.image.astype(np.float64) @ LUMINANCE)
    return images, forest.record, seconds


def show(label: str, scene, spp: int, max_depth: int) -> None:
    for sampler, builder in SAMPLERS:
        (a, b), rec, seconds = two_seeds(scene, sampler, builder, spp, max_depth)
        mean, var = (a + b) / 2, (a - b) ** 2 / 2
        lit = mean > 0
        extra = (f", build {rec['build_seconds']:.3f} s, {rec['bytes_per_light']:.0f} B/light"
                 if sampler == "tree" else "")
        print(f"{label}, max_depth {max_depth}: {sampler} {builder or ''}: median pixel var/mean^2 "
              f"{np.median(var[lit] / mean[lit] ** 2):.4f}, image var/mean^2 {var.mean() / mean.mean() ** 2:.4f}, "
              f"mean {mean.mean():.5f}, render {seconds:.2f} s{extra}", flush=True)


def main() -> None:
    import lightcuts
    from lamps import lamp_scene
    from lightcuts.pipeline.plan import plan_run

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=64, help="image side, pixels")
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--configs", default="cornell,mesh-gallery,kitchen,rooms", help="shipped configs, comma-separated")
    args = p.parse_args()
    n = args.size
    for name in args.configs.split(","):
        cfg = lightcuts.load_config(ROOT / "configs" / f"{name}.yaml", **{"camera.resolution": [n, n]})
        show(name, plan_run(cfg, render=True).scene(), args.spp, 64)
    lamps = lamp_scene(n_far=2000, far_power=30.0, width=n, height=n)
    show("6 near + 2000 far", lamps, args.spp, 1)
    show("6 near + 2000 far", lamps, args.spp, 64)
    show("306 at 1-6x", lamp_scene(n_far=300, far_radius=(1.0, 6.0), far_power=3.0, width=n, height=n), args.spp, 1)


if __name__ == "__main__":
    main()
