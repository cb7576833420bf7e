"""Ray-casting throughput: shadow rays (occluded) and closest hits (intersect), in Mrays/s.

Routes compared on the same rays:
  embree      lightcuts' ``embree`` caster: numba prange kernels calling rtcOccluded1/rtcIntersect1 (all threads)
  embree-1t   the same with numba limited to one thread (per-core comparison)
  embreex     lightcuts' ``embreex`` caster: embreex's scene.run behind the same validation/conversion
  embreex-raw embreex's scene.run alone on prepared float32 arrays (the floor of that route)

Scenes: a UV sphere and random triangles in a box (~100K triangles each), and the Stanford bunny
(69K) when ../shared/models/stanford-bunny.obj exists (or --mesh PATH). Rays: closest hit from
random origins in the scene's box in isotropic directions (tfar = inf); shadow rays from random
points on the surface to random points in the box (d = target - origin; tnear = 1e-4, tfar = 1 - 1e-4).

Medians of --repeats runs after a warm-up round (numba compiled or loaded from cache first), the
routes interleaved round-robin so that load from other processes hits them alike. Besides wall-clock
Mrays/s, Mrays per CPU-second (process CPU time, all threads) shows per-core efficiency, which a
busy machine disturbs less. The machine is shared: compare routes within one run.

Also measures the first call of a kernel defined in another module that calls the per-ray device
functions, in two fresh processes sharing an empty numba cache: cold (compiles) and warm (loads).

    python benchmarks/bench_rays.py [--rays 500000] [--repeats 5] [--mesh PATH] [--no-cache-check]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402


def sphere_scene(target_faces: int = 100_000):
    import trimesh

    n = int(round(np.sqrt(target_faces / 4)))
    m = trimesh.creation.uv_sphere(radius=1.0, count=[n, n])
    return "sphere", np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int32)


def random_scene(n_faces: int = 100_000, seed: int = 0):
    rng = np.random.default_rng(seed)
    # Triangle size ~ n^(-1/3) so the box is filled about evenly at any count.
    size = 0.3 * n_faces ** (-1.0 / 3.0)
    corners = rng.random((n_faces, 1, 3)) + size * rng.standard_normal((n_faces, 3, 3))
    return "random-box", corners.reshape(-1, 3), np.arange(3 * n_faces, dtype=np.int32).reshape(-1, 3)


def mesh_scene(path: Path):
    import trimesh

    m = trimesh.load(path, force="mesh")
    return path.stem, np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int32)


def make_rays(vertices, faces, n, seed):
    """Closest-hit rays (org, dirs) and shadow rays (org, dirs, tnear, tfar), all float64."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    pad = 0.1 * (hi - lo)
    org = lo - pad + rng.random((n, 3)) * (hi - lo + 2 * pad)
    dirs = rng.standard_normal((n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)

    tri = vertices[faces[rng.integers(0, len(faces), n)]]
    u, v = rng.random((2, n))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    p = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    light = lo + rng.random((n, 3)) * (hi - lo)
    # d = light - p, so t = 1 is the light: skip the surface the ray starts on and stop short of the light.
    shadow = (p, light - p, np.full(n, 1e-4), np.full(n, 1.0 - 1e-4))
    return (org, dirs), shadow


def timed(fn):
    """(wall seconds, process CPU seconds over all threads) of one call."""
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def bench_scene(name, vertices, faces, n_rays, repeats, seed):
    import numba

    (org, dirs), (sorg, sdirs, snear, sfar) = make_rays(vertices, faces, n_rays, seed)
    t0 = time.perf_counter()
    embree = make_caster((vertices, faces), "embree")
    build_embree = time.perf_counter() - t0
    t0 = time.perf_counter()
    embreex = make_caster((vertices, faces), "embreex")
    build_embreex = time.perf_counter() - t0
    print(f"{name}: {len(faces)} triangles; build embree {build_embree * 1e3:.0f} ms, "
          f"embreex {build_embreex * 1e3:.0f} ms")

    # embreex-raw: its own inputs, prepared once outside the timing (tnear emulated by the origin shift).
    o32, d32 = org.astype(np.float32), dirs.astype(np.float32)
    so32 = (sorg + sdirs * snear[:, None]).astype(np.float32)
    sd32 = sdirs.astype(np.float32)
    sfar32 = (sfar - snear).astype(np.float32)
    raw = embreex._scene

    threads = numba.get_num_threads()
    # (query, route, threads the route uses, numba's thread count for the call, call)
    cases = []
    for query, routes in {
        "occluded": [("embree", lambda: embree.occluded(sorg, sdirs, snear, sfar)),
                     ("embreex", lambda: embreex.occluded(sorg, sdirs, snear, sfar)),
                     ("embreex-raw", lambda: raw.run(so32, sd32, dists=sfar32, query="OCCLUDED"))],
        "intersect": [("embree", lambda: embree.intersect(org, dirs, 0.0, np.inf)),
                      ("embreex", lambda: embreex.intersect(org, dirs, 0.0, np.inf)),
                      ("embreex-raw", lambda: raw.run(o32, d32, output=1))],
    }.items():
        for route, fn in routes:
            if route == "embree":
                cases.append((query, route, threads, threads, fn))
                if threads > 1:
                    cases.append((query, "embree-1t", 1, 1, fn))
            else:                                   # embreex runs on the calling thread only
                cases.append((query, route, 1, threads, fn))

    # Round-robin over the cases, so load from other processes on a shared machine hits all alike.
    wall = {i: [] for i in range(len(cases))}
    cpu = {i: [] for i in range(len(cases))}
    for rep in range(repeats + 1):                  # rep 0 is the warm-up (numba compile / cache load)
        for i, (_, _, _, numba_threads, fn) in enumerate(cases):
            numba.set_num_threads(numba_threads)
            try:
                w, c = timed(fn)
            finally:
                numba.set_num_threads(threads)
            if rep:
                wall[i].append(w)
                cpu[i].append(c)

    rows = []
    for i, (query, route, nthreads, _, _) in enumerate(cases):
        rates = sorted(n_rays / w / 1e6 for w in wall[i])
        med = statistics.median(rates)
        per_cpu = statistics.median(n_rays / c / 1e6 for c in cpu[i])
        rows.append(dict(scene=name, triangles=len(faces), query=query, route=route, threads=nthreads,
                         rays=n_rays, mrays_median=round(med, 3), mrays_min=round(rates[0], 3),
                         mrays_max=round(rates[-1], 3), mrays_per_cpu_s=round(per_cpu, 3)))
        print(f"  {query:9s} {route:12s} {nthreads} thr  {med:7.2f} Mrays/s  (min {rates[0]:.2f}, "
              f"max {rates[-1]:.2f})  {per_cpu:6.2f} Mrays/CPU-s")
    # The hit fraction says what kind of workload the figures are for.
    hit = embree.intersect(org, dirs, 0.0, np.inf)[1] >= 0
    occ = embree.occluded(sorg, sdirs, snear, sfar)
    print(f"  closest-hit rays hitting: {hit.mean():.0%}; shadow rays occluded: {occ.mean():.0%}")
    embree.close()
    return rows


_EXTERNAL = '''
import numpy as np
from numba import njit, prange
from lightcuts.accel.embree.embree_kernels import new_ray_buffer, ray_intersect, ray_occluded

@njit(parallel=True, cache=True)
def shade(intersect1, occluded1, scene, org, dirs, out):
    n = org.shape[0]
    for c in prange((n + 63) // 64):
        buf = new_ray_buffer()
        for i in range(c * 64, min(n, c * 64 + 64)):
            t, p = ray_intersect(intersect1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                 dirs[i, 0], dirs[i, 1], dirs[i, 2], 0.0, np.inf)
            out[i] = p >= 0 and not ray_occluded(occluded1, scene, buf, org[i, 0], org[i, 1], org[i, 2],
                                                 dirs[i, 0], dirs[i, 1], dirs[i, 2], 0.0, 0.5 * t)
'''

_RUNNER = '''
import json, time
import numpy as np
t0 = time.perf_counter()
import ext_kernel
from lightcuts.accel import make_caster
caster = make_caster((np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]])), "embree")
org = np.tile([0.2, 0.2, -1.0], (1000, 1)); dirs = np.tile([0.0, 0.0, 1.0], (1000, 1))
out = np.empty(1000, np.bool_)
t1 = time.perf_counter()
ext_kernel.shade(*caster.kernel_handles, org, dirs, out)
t2 = time.perf_counter()
s = ext_kernel.shade.stats
print(json.dumps(dict(setup=t1 - t0, first_call=t2 - t1, hits=sum(s.cache_hits.values()),
                      misses=sum(s.cache_misses.values()))))
'''


def cache_check():
    """First-call time of an external kernel in a cold then a warm fresh process."""
    import json

    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "ext_kernel.py").write_text(textwrap.dedent(_EXTERNAL))
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp, "cache")),
                   PYTHONPATH=os.pathsep.join([tmp, str(ROOT)]))
        out = []
        for label in ("cold cache", "warm cache"):
            r = subprocess.run([sys.executable, "-c", _RUNNER], env=env, cwd=tmp, capture_output=True, text=True,
                               check=True)
            d = json.loads(r.stdout.strip().splitlines()[-1])
            out.append((label, d))
            print(f"  {label}: first call {d['first_call']:.2f} s (imports + caster {d['setup']:.2f} s), "
                  f"cache hits {d['hits']}, misses {d['misses']}")
        return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=500_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--triangles", type=int, default=100_000)
    ap.add_argument("--mesh", type=Path, action="append", default=None,
                    help="extra OBJ/PLY meshes (default: ../shared/models/stanford-bunny.obj if present)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-cache-check", action="store_true")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "rays.csv")
    args = ap.parse_args(argv)

    meshes = args.mesh
    if meshes is None:
        bunny = ROOT.parent / "shared" / "models" / "stanford-bunny.obj"
        meshes = [bunny] if bunny.exists() else []
    scenes = [sphere_scene(args.triangles), random_scene(args.triangles, args.seed)]
    scenes += [mesh_scene(p) for p in meshes]

    rows = []
    for name, v, f in scenes:
        rows += bench_scene(name, v, f, args.rays, args.repeats, args.seed)

    print(f"\n{'scene':14s} {'tris':>7s} {'query':9s} {'route':12s} {'thr':>3s} {'Mrays/s':>8s} {'/CPU-s':>7s}")
    for r in rows:
        print(f"{r['scene']:14s} {r['triangles']:7d} {r['query']:9s} {r['route']:12s} {r['threads']:3d} "
              f"{r['mrays_median']:8.2f} {r['mrays_per_cpu_s']:7.2f}")
    save_csv(args.out, rows)
    print(f"wrote {args.out}")

    if not args.no_cache_check:
        print("\nkernel in another module calling ray_intersect/ray_occluded (fresh processes):")
        cache_check()


if __name__ == "__main__":
    main()
