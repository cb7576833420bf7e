"""The sampling tree per builder over a scene's emitting triangles: build time, bytes per light,
the cost of a draw, and the variance of next-event estimation at equal samples.

For a config's scene (default: the city at 10^5 emitting triangles) the emitting triangles become
a light set (lightcuts.lights.triangles), each builder clusters it and the light sampler lays the
tree out (lightcuts.integrators.light_sampler). Per builder:

  tree_s       build_tree wall clock (median of --repeats, after one warm-up build)
  sampler_s    build_light_sampler wall clock (the records, boxes refitted to the triangles)
  bytes/light  the sampler's records over the number of lights (the lights themselves not counted)
  draw_ns      wall ns per draw (one walk from the root) over --points shading points x --draws
  rel_var      next-event estimation's relative variance at equal samples, unshadowed: at each
               shading point (uniform by area over the non-emitting triangles, their face normal)
               the estimate Le cos_l |cos_r| / d^2 / p(point) of one drawn triangle and a uniform
               point on it, its variance over --draws draws divided by its squared mean, the median
               over the points; 'power' (triangles drawn by power) and 'uniform' rows for contrast
  ratio        rel_var over the best builder's

Shadows are left out (the same for every builder, and a ray cast per draw would hide the tree's
share); the rendered comparison is lightcuts' study command. Writes CSV to
benchmarks/results/light_sampler.csv (or --csv).

    python benchmarks/bench_light_sampler.py [--config configs/city-100k.yaml] [--builders a,b]
        [--points 256] [--draws 256] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from common import load_average, timed  # noqa: E402

from lightcuts.api import load_config  # noqa: E402
from lightcuts.integrators.importance import sample_light  # noqa: E402
from lightcuts.integrators.light_sampler import build_light_sampler  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
from lightcuts.lights.lightset import LUMINANCE  # noqa: E402
from lightcuts.lights.triangles import triangle_lights  # noqa: E402
from lightcuts.scene.build import scene_from_config  # noqa: E402
from lightcuts.trees import build_tree  # noqa: E402

FIELDS = ("config", "n_lights", "builder", "tree_s", "sampler_s", "bytes_per_light", "draw_ns", "rel_var", "ratio",
          "load_avg")
BUILDERS = ("agglomerative", "agglomerative-heap", "divisive-3d", "divisive-6d", "saoh")


@njit(cache=True)
def _tree_estimates(rec, axis, child, roots, root_type, points, normals, u, p0, e1, e2, area, le, out):
    """out[i, j]: the unshadowed estimate at point i from draw j (u[i, j, 0..2])."""
    for i in range(points.shape[0]):
        x0, x1, x2 = points[i, 0], points[i, 1], points[i, 2]
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        for j in range(u.shape[1]):
            light, prob = sample_light(rec, axis, child, roots, root_type, x0, x1, x2, n0, n1, n2, u[i, j, 0])
            out[i, j] = 0.0 if light < 0 else _point_estimate(x0, x1, x2, n0, n1, n2, light, prob, u[i, j, 1],
                                                              u[i, j, 2], p0, e1, e2, area, le)


@njit(cache=True)
def _table_estimates(cdf, points, normals, u, p0, e1, e2, area, le, out):
    """out[i, j] as :func:`_tree_estimates`, a triangle drawn from the table ``cdf`` instead."""
    total = cdf[-1]
    for i in range(points.shape[0]):
        for j in range(u.shape[1]):
            k = min(np.searchsorted(cdf, u[i, j, 0] * total, side="right"), cdf.shape[0] - 1)
            prob = (cdf[k] - (cdf[k - 1] if k > 0 else 0.0)) / total
            out[i, j] = _point_estimate(points[i, 0], points[i, 1], points[i, 2], normals[i, 0], normals[i, 1],
                                        normals[i, 2], k, prob, u[i, j, 1], u[i, j, 2], p0, e1, e2, area, le)


@njit(cache=True)
def _point_estimate(x0, x1, x2, n0, n1, n2, k, prob, a, b, p0, e1, e2, area, le):
    if prob <= 0.0:
        return 0.0
    if a + b > 1.0:
        a, b = 1.0 - a, 1.0 - b
    l0 = p0[k, 0] + a * e1[k, 0] + b * e2[k, 0] - x0
    l1 = p0[k, 1] + a * e1[k, 1] + b * e2[k, 1] - x1
    l2 = p0[k, 2] + a * e1[k, 2] + b * e2[k, 2] - x2
    d2 = l0 * l0 + l1 * l1 + l2 * l2
    d = np.sqrt(d2)
    m0 = e1[k, 1] * e2[k, 2] - e1[k, 2] * e2[k, 1]
    m1 = e1[k, 2] * e2[k, 0] - e1[k, 0] * e2[k, 2]
    m2 = e1[k, 0] * e2[k, 1] - e1[k, 1] * e2[k, 0]
    mn = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    cos_l = -(m0 * l0 + m1 * l1 + m2 * l2) / (mn * d)
    if cos_l <= 0.0:
        return 0.0
    cos_r = abs(n0 * l0 + n1 * l1 + n2 * l2) / d
    return le[k] * cos_l * cos_r / d2 * area[k] / prob


def shading_points(scene, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n points uniform by area over the non-emitting triangles, with their face normals."""
    rng = np.random.default_rng(seed)
    faces = np.flatnonzero(scene.emission.max(axis=1) <= 0)
    w = scene.face_areas[faces]
    f = faces[np.minimum(np.searchsorted(np.cumsum(w), rng.random(n) * w.sum(), side="right"), len(faces) - 1)]
    a, b = rng.random(n), rng.random(n)
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    t = scene.triangles[f]
    p = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
    n_ = scene.face_normals[f]
    return np.ascontiguousarray(p + 1e-4 * scene.diagonal * n_), np.ascontiguousarray(n_)


def rel_var(est: np.ndarray) -> float:
    """Median over points of variance / mean^2 of their estimates (points with a zero mean left out)."""
    mean = est.mean(axis=1)
    keep = mean > 0
    return float(np.median(est[keep].var(axis=1, ddof=1) / mean[keep] ** 2)) if keep.any() else float("nan")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default="configs/city-100k.yaml")
    ap.add_argument("--builders", default=",".join(BUILDERS))
    ap.add_argument("--points", type=int, default=256)
    ap.add_argument("--draws", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--csv", default=str(ROOT / "benchmarks" / "results" / "light_sampler.csv"))
    a = ap.parse_args(argv)
    load = load_average()
    scene = scene_from_config(load_config(a.config))
    tl = triangle_lights(scene)
    n = len(tl.lights)
    corners = scene.triangles[tl.tri]
    p0 = np.ascontiguousarray(corners[:, 0])
    e1 = np.ascontiguousarray(corners[:, 1] - corners[:, 0])
    e2 = np.ascontiguousarray(corners[:, 2] - corners[:, 0])
    area = np.ascontiguousarray(scene.face_areas[tl.tri])
    le = np.ascontiguousarray(scene.emission[tl.tri] @ LUMINANCE)
    points, normals = shading_points(scene, a.points, 1)
    u = np.random.default_rng(2).random((a.points, a.draws, 3))
    print(f"{a.config}: {n:,} emitting triangles, {scene.n_faces:,} triangles, load {load:.2f}, "
          f"{os.cpu_count()} cores", flush=True)
    rows = []
    for name in a.builders.split(","):
        t_tree, _, tree = timed(lambda: build_tree(tl.lights, name), a.repeats, warmup=True)
        boxes = {"oriented": (tl.lo, tl.hi)}
        t_s, _, s = timed(lambda: build_light_sampler({"oriented": tl.lights}, {"oriented": tree}, boxes), a.repeats,
                          warmup=True)
        out = np.zeros((a.points, a.draws))
        args = (s.rec, s.axis, s.child, s.roots, s.root_type, points, normals, u, p0, e1, e2, area, le, out)
        _tree_estimates(*args)
        t0 = time.perf_counter()
        _tree_estimates(*args)
        draw_ns = (time.perf_counter() - t0) / (a.points * a.draws) * 1e9
        rows.append({"builder": name, "tree_s": t_tree, "sampler_s": t_s, "bytes_per_light": s.nbytes / n,
                     "draw_ns": draw_ns, "rel_var": rel_var(out)})
        print(f"  {name:20s} tree {t_tree:6.2f} s  sampler {t_s:5.2f} s  {s.nbytes / n:5.1f} B/light  "
              f"{draw_ns:6.0f} ns/draw  rel var {rows[-1]['rel_var']:.4g}", flush=True)
    for name, weight in (("power", area * le), ("uniform", np.ones(n))):
        out = np.zeros((a.points, a.draws))
        _table_estimates(np.cumsum(weight), points, normals, u, p0, e1, e2, area, le, out)
        rows.append({"builder": name, "tree_s": 0.0, "sampler_s": 0.0, "bytes_per_light": 0.0, "draw_ns": 0.0,
                     "rel_var": rel_var(out)})
        print(f"  {name:20s} rel var {rows[-1]['rel_var']:.4g}", flush=True)
    best = min(r["rel_var"] for r in rows)
    for r in rows:
        r.update(config=a.config, n_lights=n, ratio=r["rel_var"] / best, load_avg=load)
    print("ratio to the best: " + ", ".join(f"{r['builder']} {r['ratio']:.2f}" for r in rows))
    save_csv(a.csv, rows, list(FIELDS))
    print(f"wrote {a.csv}")


if __name__ == "__main__":
    main()
