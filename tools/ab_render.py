"""A/B render timing of two versions of lightcuts in one process, alternating.

On cores shared with other work, the same render varies by 15-40% within minutes, so two versions
timed in separate processes, even back to back, cannot show a 5% difference. Here both versions
are imported into one process (each copied to a temporary folder under its own package name) and
render the same crop in turn, so that a slow phase of the machine slows both alike; the figure is
the median over pairs of the ratio B / A. A null run (the same version twice) gave ratios of
0.99 +- 0.05 over 8-12 pairs; a change of 4% showed as 1.04 in repeated runs.

    python tools/ab_render.py OTHER_CHECKOUT [--pairs 12] [--crop 192,192,320,320]
        [--indirect 100000] [--threads N] [--out benchmarks/results/ab_render.csv]

A is this checkout, B the other one (a folder holding ``lightcuts/``, e.g. a ``git worktree``). The
scene is ``cornell.yaml``'s: 1,024 direct + --indirect VPLs, the agglomerative tree, 512 x 512
camera, of which the crop is rendered. Both versions must render the same image (checked).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import re
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numba

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.io import save_csv  # noqa: E402

MODULES = ("accel", "lights.direct", "lights.indirect", "lights.lightset", "scene.cornell", "scene.scene",
           "trees.build")
#: The module of ``render_image``: its name in this checkout, else in older ones.
RENDER_MODULES = ("render.lightcut", "render.integrator")


def copy_as(src: Path, dst: Path, name: str) -> None:
    """Copy the package ``src`` (a ``lightcuts/`` folder) to ``dst/name`` with its imports renamed."""
    shutil.copytree(src, dst / name, ignore=shutil.ignore_patterns("__pycache__"))
    for path in (dst / name).rglob("*.py"):
        text = path.read_text()
        text = re.sub(r"\blightcuts\.", f"{name}.", text)
        text = re.sub(r"\b(from|import) lightcuts\b", rf"\1 {name}", text)
        path.write_text(text)


def setup(pkg: str, n_indirect: int):
    m = {name: importlib.import_module(f"{pkg}.{name}") for name in MODULES}
    render_image = next(importlib.import_module(f"{pkg}.{name}") for name in RENDER_MODULES
                        if importlib.util.find_spec(f"{pkg}.{name}") is not None).render_image
    scene = m["scene.cornell"].cornell_box()
    c = scene.camera
    camera = m["scene.scene"].Camera(c.position, c.look_at, c.up, c.fov, 512, 512)
    caster = m["accel"].make_caster(scene, "embree")
    lights = m["lights.lightset"].LightSet.concatenate([m["lights.direct"].direct_lights(scene, 1024, seed=1),
                                                        m["lights.indirect"].indirect_lights(scene, caster, n_indirect,
                                                                                             seed=2)])
    tree = m["trees.build"].build_tree(lights, "agglomerative", "walter2008", seed=3)

    def render(crop):
        return render_image(scene, caster, {"oriented": lights}, {"oriented": tree}, camera=camera, crop=crop)
    return render


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", help="the other checkout (a folder holding lightcuts/)")
    ap.add_argument("--pairs", type=int, default=12)
    ap.add_argument("--crop", default="192,192,320,320", help="x0,y0,x1,y1 of the 512 x 512 image")
    ap.add_argument("--indirect", type=int, default=100_000)
    ap.add_argument("--threads", type=int, default=numba.config.NUMBA_NUM_THREADS)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "ab_render.csv"))
    args = ap.parse_args()
    other = Path(args.other).resolve() / "lightcuts"
    if not (other / "__init__.py").is_file():
        sys.exit(f"error: {args.other}: no lightcuts/ package there")
    crop = tuple(int(v) for v in args.crop.split(","))
    numba.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory() as tmp:
        copy_as(ROOT / "lightcuts", Path(tmp), "lightcuts_a")
        copy_as(other, Path(tmp), "lightcuts_b")
        sys.path.insert(0, tmp)
        renders = {}
        for pkg in ("lightcuts_a", "lightcuts_b"):
            renders[pkg] = setup(pkg, args.indirect)
            renders[pkg]((0, 0, 32, 32))        # compile (cold: each copy has its own cache)
        times = {pkg: [] for pkg in renders}
        images = {}
        for p in range(args.pairs):
            order = list(renders) if p % 2 == 0 else list(renders)[::-1]
            for pkg in order:
                t0 = time.perf_counter()
                result = renders[pkg](crop)
                times[pkg].append(time.perf_counter() - t0)
                images[pkg] = result.image
    same = images["lightcuts_a"].tobytes() == images["lightcuts_b"].tobytes()
    ratios = [b / a for a, b in zip(times["lightcuts_a"], times["lightcuts_b"])]
    a_med, b_med = statistics.median(times["lightcuts_a"]), statistics.median(times["lightcuts_b"])
    r_med = statistics.median(ratios)
    print(f"crop {crop}, {args.threads} threads, {args.pairs} pairs")
    print(f"A {ROOT}: median {a_med:.3f} s")
    print(f"B {Path(args.other).resolve()}: median {b_med:.3f} s")
    print(f"B / A per pair: median {r_med:.3f} (min {min(ratios):.3f}, max {max(ratios):.3f}); "
          f"images {'identical' if same else 'DIFFER'}")
    common = dict(crop=args.crop, threads=args.threads, pairs=args.pairs, same_image=same)
    save_csv(args.out, [dict(version="A", checkout=str(ROOT), median_s=a_med, ratio_b_over_a=1.0, **common),
                        dict(version="B", checkout=str(Path(args.other).resolve()), median_s=b_med,
                             ratio_b_over_a=r_med, **common)])
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
