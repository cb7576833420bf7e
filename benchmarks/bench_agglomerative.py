"""The fast agglomerative builders (Walter et al. 2008) on Cornell-box VPLs: time, scaling, memory,
agreement, compile time.

Lights: particle-traced indirect VPLs in the Cornell box (``lightcuts.lights.indirect`` with
``lightcuts.scene.cornell.cornell_box()``, seed 1; about N, the exact count is in the table),
oriented, metric walter2008 with box-of-normals cones, c = scene diagonal / 16.

Quantities (rows of benchmarks/results/agglomerative.csv: quantity, builder, n_lights, value, unit):

  build_wall_s, build_cpu_s   builder topology only (``agglomerative_stats``), median of --repeats
                              runs after a warm-up on the same lights; CPU = process time
  searches_per_merge          kd-tree findBestMatch searches / (N - 1)
  exponent                    least-squares slope of log(wall time) against log(N)
  heap_over_local             agglomerative-heap wall time / agglomerative wall time, per N
  agreement_local_heap        share of internal clusters (sets of lights) that both builders
                              make, on --agree-n VPLs (the default metric is not monotone, so
                              the two may differ)
  agreement_local_greedy      the same for agglomerative against greedy on --greedy-n VPLs
  peak_rss_mb, build_rss_mb   peak resident memory of a fresh process that loads --memory-n
                              lights and builds once (numba loaded from its cache), and its growth
                              over the resident size just before the build
  tracemalloc_peak_mb         tracemalloc's peak during that build: numpy arrays, including those
                              numba kernels allocate (numba's runtime allocates through Python's
                              raw allocator, which tracemalloc traces)
  compile_cold_s, compile_cached_s  first call of a builder in a fresh process with an empty
                              numba cache directory, then again with that directory filled

The machine has 2 cores shared with other work: wall times are noisy (the load average is saved).

    python benchmarks/bench_agglomerative.py [--sizes 50000,100000,200000,400000,800000]
        [--repeats 3] [--agree-n 200000] [--greedy-n 4000] [--memory-n 1000000]

A count of 0 skips that part (the agreement with the heap builder, with greedy, the peak memory).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
from lightcuts.lights.indirect import indirect_lights  # noqa: E402
from lightcuts.scene.cornell import cornell_box  # noqa: E402
from lightcuts.trees import build_tree, default_c, get_metric  # noqa: E402
from lightcuts.trees.agglomerative import agglomerative_stats  # noqa: E402

FIELDS = ("quantity", "builder", "n_lights", "value", "unit")
BUILDERS = ("agglomerative", "agglomerative-heap")

# Child process of the memory and compile measurements: load lights, build once, report.
_CHILD = r"""
import json, resource, sys, time, tracemalloc
import numpy as np
sys.path.insert(0, sys.argv[1])
from lightcuts.trees import get_metric
from lightcuts.trees.agglomerative import agglomerative_stats
z = np.load(sys.argv[2])
args = (z["position"], z["normal"], z["luminance"], "oriented", get_metric("walter2008"), float(z["c"]), 0)
small = tuple(a[:64] if isinstance(a, np.ndarray) else a for a in args)
t0 = time.perf_counter()
agglomerative_stats(*small)
first_call = time.perf_counter() - t0
out = {"first_call_s": first_call}
if sys.argv[3] == "memory":
    page = resource.getpagesize()
    rss_before = int(open("/proc/self/statm").read().split()[1]) * page
    tracemalloc.start()
    agglomerative_stats(*args)
    out["tracemalloc_peak"] = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    out["rss_before"] = rss_before
    out["peak_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(out))
"""


def vpls(scene, caster, n: int):
    return indirect_lights(scene, caster, n, seed=1)


def build_args(lights):
    return (lights.position, lights.normal, lights.luminance, lights.type, get_metric("walter2008"),
            default_c(lights), 0)


def time_builds(lights, repeats: int) -> dict:
    """Per builder: medians of wall and CPU time and the work counters."""
    args = build_args(lights)
    out = {}
    for name in BUILDERS:
        heap = name == "agglomerative-heap"
        agglomerative_stats(*args, heap=heap)
        wall, cpu = [], []
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            *_, stats = agglomerative_stats(*args, heap=heap)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        out[name] = dict(wall=statistics.median(wall), cpu=statistics.median(cpu), stats=stats)
    return out


def cluster_signatures(left: np.ndarray, right: np.ndarray, n: int) -> set:
    """Internal clusters as (size, sum and xor of random 64-bit keys of their lights): equal sets of
    lights give equal signatures; different ones collide with probability ~2^-128 per pair."""
    keys = np.random.default_rng(12345).integers(0, 2**63, size=n, dtype=np.int64).tolist()
    mask = 2**64 - 1
    size = [1] * n + [0] * (n - 1)
    ksum = keys + [0] * (n - 1)
    kxor = keys + [0] * (n - 1)
    # The builders number a merge's node after its children's, so id order is bottom-up.
    for node, a, b in zip(range(n, 2 * n - 1), left[n:].tolist(), right[n:].tolist()):
        size[node] = size[a] + size[b]
        ksum[node] = (ksum[a] + ksum[b]) & mask
        kxor[node] = kxor[a] ^ kxor[b]
    return set(zip(size[n:], ksum[n:], kxor[n:]))


def agreement(lights, other: str) -> float:
    """Share of agglomerative's internal clusters that builder ``other`` also makes."""
    n = len(lights)
    mine = build_tree(lights, builder="agglomerative")
    theirs = build_tree(lights, builder=other)
    a = cluster_signatures(mine.left, mine.right, n)
    b = cluster_signatures(theirs.left, theirs.right, n)
    return len(a & b) / len(a)


def child(script_args: list[str], cache_dir: str | None) -> dict:
    """Run _CHILD in a fresh interpreter; ``cache_dir`` overrides numba's cache (None: the default)."""
    import json

    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    res = subprocess.run([sys.executable, "-c", _CHILD, str(ROOT), *script_args], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="50000,100000,200000,400000,800000")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--agree-n", type=int, default=200000)
    ap.add_argument("--greedy-n", type=int, default=4000)
    ap.add_argument("--memory-n", type=int, default=1000000)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "agglomerative.csv"))
    opts = ap.parse_args()
    sizes = [int(s) for s in opts.sizes.split(",")]
    load = os.getloadavg()[0]
    print(f"load average at start: {load:.2f} (2 cores; wall times are noisy)")
    rows = []

    def add(quantity, builder, n, value, unit):
        rows.append(dict(quantity=quantity, builder=builder, n_lights=n, value=value, unit=unit))

    scene = cornell_box()
    caster = make_caster(scene)

    # Build time and scaling.
    print(f"\n{'N':>8} {'builder':>20} {'wall s':>8} {'cpu s':>8} {'searches/merge':>15}")
    walls = {name: [] for name in BUILDERS}
    counts = []
    for n_wanted in sizes:
        lights = vpls(scene, caster, n_wanted)
        n = len(lights)
        counts.append(n)
        res = time_builds(lights, opts.repeats)
        for name in BUILDERS:
            r = res[name]
            walls[name].append(r["wall"])
            per_merge = r["stats"]["searches"] / max(n - 1, 1)
            print(f"{n:>8} {name:>20} {r['wall']:>8.3f} {r['cpu']:>8.3f} {per_merge:>15.2f}")
            add("build_wall_s", name, n, r["wall"], "s")
            add("build_cpu_s", name, n, r["cpu"], "s")
            add("searches_per_merge", name, n, per_merge, "")
        ratio = res["agglomerative-heap"]["wall"] / res["agglomerative"]["wall"]
        add("heap_over_local", "agglomerative-heap", n, ratio, "")
    print()
    for name in BUILDERS:
        slope = float(np.polyfit(np.log(counts), np.log(walls[name]), 1)[0]) if len(counts) > 1 else float("nan")
        add("exponent", name, f"{counts[0]}-{counts[-1]}", slope, "")
        print(f"{name:>20}: fitted exponent {slope:.3f} over N = {counts[0]}..{counts[-1]}")
    ratios = [h / a for h, a in zip(walls["agglomerative-heap"], walls["agglomerative"])]
    print(f"{'heap / local':>20}: " + ", ".join(f"{r:.2f}" for r in ratios))

    # Agreement with the default (non-monotone) metric.
    if opts.agree_n > 0:
        lights = vpls(scene, caster, opts.agree_n)
        share = agreement(lights, "agglomerative-heap")
        add("agreement_local_heap", "agglomerative", len(lights), share, "share")
        print(f"\nagglomerative vs agglomerative-heap, {len(lights)} VPLs: {100 * share:.2f}% of clusters agree")
    if opts.greedy_n > 0:
        small = vpls(scene, caster, opts.greedy_n)
        share_g = agreement(small, "greedy")
        add("agreement_local_greedy", "agglomerative", len(small), share_g, "share")
        print(f"agglomerative vs greedy, {len(small)} VPLs: {100 * share_g:.2f}% of clusters agree")

    with tempfile.TemporaryDirectory() as tmp:
        # The compile measurement below reads the first lights of this file.
        big = vpls(scene, caster, max(opts.memory_n, 64))
        path = os.path.join(tmp, "lights.npz")
        np.savez(path, position=big.position, normal=big.normal, luminance=big.luminance, c=default_c(big))
        if opts.memory_n > 0:
            # Peak memory of one build in a fresh process.
            mem = child([path, "memory"], None)
            mb = 1024.0 ** 2
            add("peak_rss_mb", "agglomerative", len(big), mem["peak_rss"] / mb, "MB")
            add("build_rss_mb", "agglomerative", len(big), (mem["peak_rss"] - mem["rss_before"]) / mb, "MB")
            add("tracemalloc_peak_mb", "agglomerative", len(big), mem["tracemalloc_peak"] / mb, "MB")
            print(f"\n{len(big)} lights: peak RSS {mem['peak_rss'] / mb:.0f} MB, growth during the build "
                  f"{(mem['peak_rss'] - mem['rss_before']) / mb:.0f} MB, numpy (tracemalloc) peak "
                  f"{mem['tracemalloc_peak'] / mb:.0f} MB")
        # Compile time: an empty numba cache, then the filled one.
        cache = os.path.join(tmp, "numba_cache")
        cold = child([path, "compile"], cache)["first_call_s"]
        cached = child([path, "compile"], cache)["first_call_s"]
        add("compile_cold_s", "agglomerative", 64, cold, "s")
        add("compile_cached_s", "agglomerative", 64, cached, "s")
        print(f"first call (64 lights): {cold:.1f} s with an empty numba cache, {cached:.2f} s from the cache")
    add("load_avg", "", "", load, "")

    out = save_csv(opts.out, rows, FIELDS)
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
