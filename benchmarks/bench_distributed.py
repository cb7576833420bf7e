"""Dask distributed renders: costs measured on this machine, and a model of many machines.

Measured (``configs/kitchen.yaml``):

  overhead   ``lightcuts render configs/kitchen.yaml`` against the same with ``--workers 2`` (a
             LocalCluster of 2 worker processes x 1 thread on this 2-core machine: pure overhead) and
             ``--workers 1`` (1 process x 2 threads), wall times of the whole command, ``--pairs``
             interleaved rounds, medians
  tiles      single-thread seconds of tiles of 16, 32, 64 and 128 px of the 3840 x 2160 frame at 1 eye
             ray per pixel, rendered as a worker renders them (a crop window of the run's image, the
             render call's fixed cost included): ``--samples`` random 128 px tiles and every 64, 32 and
             16 px tile inside them (the same pixels at every size); the fixed cost alone (a one-pixel
             tile); a few 32 px tiles at 16 eye rays against ``fixed + 16 x (1-ray tile - fixed)``,
             whose ratio scales the model's tiles to 16 eye rays
  ship       at 200K and 1M triangles: the client's scene + lights + trees seconds (2 threads), the
             bytes of scene, lights and trees as Dask sends them, the seconds to scatter them to a
             LocalCluster of 2 workers (broadcast, loopback), a worker's setup (its scene and ray
             caster); at 1M also the cost of 64 px tiles over the 200K ones
  scheduler  seconds per task of ``--tasks`` tasks through a LocalCluster of 2 workers, empty and
             returning a 64 px tile's result (98 KB)

Model: a 3840 x 2160, 16-eye-ray kitchen frame on M machines of 2 cores (2 single-thread workers
each), a discrete-event list scheduling of the tiles (costs drawn from the measured ones, scaled to
16 eye rays and to the area of edge tiles) after the client's serial scene + lights + trees and the
shipping of the inputs (one copy from the client, then Dask's replication tree, branching factor 2:
ceil(log3 M) rounds of two copies per holder, at ``--bandwidth`` Gb/s, and the worker's setup), with
the scheduler handling one task per measured per-task time (a task starts no earlier than the
scheduler has dispatched all before it). Efficiency = T(1 machine) / (M x T(M)); the best tile size
per M, median of ``--trials`` draws.

Prints tables and writes ``benchmarks/results/distributed-{overhead,tiles,ship,scheduler,model}.csv``.

    python benchmarks/bench_distributed.py [--pairs 3] [--samples 12] [--tasks 2000] [--bandwidth 10]
"""

from __future__ import annotations

import argparse
import heapq
import logging
import math
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
sys.path.insert(0, str(ROOT / "benchmarks"))

KITCHEN = ROOT / "configs" / "kitchen.yaml"
FRAME = (3840, 2160)
SPP = 16
SIZES = (16, 32, 64, 128)
MACHINES = (1, 8, 64, 256)
CORES = 2


def command_overhead(pairs: int) -> list[dict]:
    """Wall seconds of ``lightcuts render kitchen.yaml`` and of the same with ``--workers 2``, interleaved."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(pairs):
            for case, extra in (("local", []), ("workers-2", ["--workers", "2"]), ("workers-1", ["--workers", "1"])):
                out = Path(tmp) / case
                t0 = time.perf_counter()
                subprocess.run([sys.executable, "-m", "lightcuts", "render", str(KITCHEN), "--out", str(out),
                                "--no-progress", *extra], check=True, env=env, capture_output=True)
                rows.append({"pair": i, "case": case, "seconds": time.perf_counter() - t0})
                print(f"  {case:<10} {rows[-1]['seconds']:.2f} s", flush=True)
            local = (Path(tmp) / "local" / "image.exr").read_bytes()
            if any((Path(tmp) / c / "image.exr").read_bytes() != local for c in ("workers-1", "workers-2")):
                raise SystemExit("the cluster's image differs from the local one")
    return rows


def prepare(triangles: int, resolution=FRAME):
    """(cfg, plan, scene, envmap, lights, trees, client seconds) of the kitchen at that size."""
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config

    cfg = load_config(KITCHEN, [f"scene.procedural.triangles={triangles}",
                                f"camera.resolution=[{resolution[0]},{resolution[1]}]"])
    plan = plan_run(cfg, render=True)
    t0 = time.perf_counter()
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        envmap = plan.environment()
        lights = plan.lights(scene, caster, envmap)
    trees = plan.trees(lights)
    return cfg, plan, scene, envmap, lights, trees, time.perf_counter() - t0


def tile_seconds(cfg, plan, scene, envmap, lights, trees, windows, spp: int = 1) -> tuple[list, float]:
    """(single-thread seconds of each window, the worker's setup seconds), each tile rendered as a
    worker renders it (lightcuts.distributed.runner.tile_task's call: the run's caster and light
    forest made once, then the crop window)."""
    from lightcuts.distributed.worker import Run
    from lightcuts.parallel import num_threads
    from lightcuts.integrators.registry import make_integrator

    c = cfg.model_copy(update={"render": cfg.render.model_copy(update={"spp": spp})})
    integ = make_integrator(c, plan.integrator)
    out = []
    with num_threads(1):
        t0 = time.perf_counter()
        caster = plan.make_caster(scene)
        run = Run(plan, scene, envmap, caster, 0.0)
        forest = run.forest(integ, lights, trees)
        setup = time.perf_counter() - t0
        inputs = dict(forest=forest, envmap=envmap, seed=c.seed)
        integ.render(scene, caster, lights, trees, crop=(0, 0, 1, 1), **inputs)  # the kernel loaded
        for w in windows:
            t0 = time.perf_counter()
            integ.render(scene, caster, lights, trees, crop=w, **inputs)
            out.append(time.perf_counter() - t0)
        caster.close()
    return out, setup


def random_windows(size: int, n: int, rng) -> list:
    """n distinct size x size tiles of the frame's tile grid (whole tiles only)."""
    nx, ny = FRAME[0] // size, FRAME[1] // size
    picks = rng.choice(nx * ny, size=min(n, nx * ny), replace=False)
    return [(int(i % nx) * size, int(i // nx) * size, int(i % nx) * size + size, int(i // nx) * size + size)
            for i in picks]


def ship_seconds(client, objects, repeats: int = 3) -> tuple[int, float]:
    """(bytes, median seconds) of scattering ``objects`` to every worker (broadcast)."""
    from lightcuts.distributed.runner import nbytes

    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        futures = client.scatter(list(objects), broadcast=True, hash=False)
        times.append(time.perf_counter() - t0)
        client.cancel(futures)
        del futures
        time.sleep(0.5)
    return sum(nbytes(o) for o in objects), statistics.median(times)


def scheduler_seconds(client, tasks: int) -> list[dict]:
    """Seconds per task of ``tasks`` tasks, empty and returning a 64 px tile's result."""
    def empty(i):
        return i

    def tile_result(i):
        return np.zeros((64, 64, 3), np.float32), np.zeros((64, 64), np.float32), np.zeros((64, 64), np.int64)

    rows = []
    for name, fn in (("empty", empty), ("tile-result-64px", tile_result)):
        per = []
        for r in range(3):
            t0 = time.perf_counter()
            futures = client.map(fn, range(tasks), key=[f"{name}-{r}-{i}" for i in range(tasks)])
            results = client.gather(futures)
            per.append((time.perf_counter() - t0) / tasks)
            del futures, results
        rows.append({"tasks": name, "seconds_per_task": statistics.median(per), "n": tasks})
    return rows


def simulate(machines: int, size: int, costs: np.ndarray, fixed: float, scale: float, prep: float, ship: float,
             sched: float, rng) -> float:
    """Wall seconds of the 4K frame on ``machines`` x CORES single-thread workers: tiles of ``size`` px,
    their 16-eye-ray seconds ``fixed + scale x 16 x (c - fixed)``, c drawn from ``costs`` (1-ray
    seconds of whole tiles, fixed cost included; ``scale`` the measured 16-ray correction), and
    scaled to the area of edge tiles; list scheduling in row-major order after prep + ship, the
    scheduler dispatching one task per ``sched`` seconds."""
    nx, ny = math.ceil(FRAME[0] / size), math.ceil(FRAME[1] / size)
    area = np.ones((ny, nx))
    area[:, -1] *= (FRAME[0] - (nx - 1) * size) / size
    area[-1, :] *= (FRAME[1] - (ny - 1) * size) / size
    work = (rng.choice(costs, size=nx * ny) - fixed) * SPP * scale
    seconds = fixed + work * area.ravel()
    start = prep + ship
    slots = [start] * (machines * CORES)
    for i, s in enumerate(seconds):
        free = heapq.heappop(slots)
        heapq.heappush(slots, max(free, start + (i + 1) * sched) + s)
    return max(slots)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3, help="interleaved local / --workers 2 command runs")
    ap.add_argument("--samples", type=int, default=12, help="random 128 px regions whose tiles are measured")
    ap.add_argument("--tasks", type=int, default=2000, help="tasks of the scheduler measurement")
    ap.add_argument("--bandwidth", type=float, default=10.0, help="network link of the model, Gb/s")
    ap.add_argument("--trials", type=int, default=9, help="simulations per point (median)")
    ap.add_argument("--skip-overhead", action="store_true", help="leave out the command runs")
    a = ap.parse_args()

    from distributed import Client, LocalCluster

    from lightcuts.io import save_csv

    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2026)
    print(f"load average {os.getloadavg()[0]:.2f}", flush=True)

    if not a.skip_overhead:
        print("overhead: lightcuts render configs/kitchen.yaml, local and --workers 2", flush=True)
        rows = command_overhead(a.pairs)
        save_csv(out / "distributed-overhead.csv", rows, ("pair", "case", "seconds"))
        med = {c: statistics.median(r["seconds"] for r in rows if r["case"] == c)
               for c in ("local", "workers-2", "workers-1")}
        print(f"  medians: local {med['local']:.2f} s, --workers 2 {med['workers-2']:.2f} s "
              f"({med['workers-2'] / med['local']:.3f}x), --workers 1 {med['workers-1']:.2f} s "
              f"({med['workers-1'] / med['local']:.3f}x)", flush=True)

    print("tiles: kitchen 200K triangles, 3840x2160, single thread", flush=True)
    cfg, plan, scene, envmap, lights, trees, prep200 = prepare(200_000)
    fixed, setup200 = tile_seconds(cfg, plan, scene, envmap, lights, trees, [(0, 0, 1, 1)] * 5)
    fixed = statistics.median(fixed)
    tile_rows, costs = [], {}
    regions = random_windows(max(SIZES), a.samples, rng)
    for size in SIZES:
        windows = [(x, y, x + size, y + size) for x0, y0, x1, y1 in regions
                   for y in range(y0, y1, size) for x in range(x0, x1, size)]
        secs, _ = tile_seconds(cfg, plan, scene, envmap, lights, trees, windows)
        costs[size] = np.array(secs)
        tile_rows += [{"size": size, "window": w, "spp": 1, "seconds": s} for w, s in zip(windows, secs)]
        q = np.percentile(secs, [10, 50, 90])
        print(f"  {size:>4} px: {len(secs)} tiles, p10 / median / p90 {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f} s, "
              f"max {max(secs):.3f} s, sum {sum(secs):.2f} s", flush=True)
    check = random_windows(32, 4, rng)
    one, _ = tile_seconds(cfg, plan, scene, envmap, lights, trees, check)
    many, _ = tile_seconds(cfg, plan, scene, envmap, lights, trees, check, spp=SPP)
    model = [fixed + SPP * (s - fixed) for s in one]
    tile_rows += [{"size": 32, "window": w, "spp": SPP, "seconds": s} for w, s in zip(check, many)]
    save_csv(out / "distributed-tiles.csv", tile_rows, ("size", "window", "spp", "seconds"))
    ratio = statistics.median(m / p for m, p in zip(many, model))
    print(f"  fixed cost per tile {fixed:.3f} s; 16 eye rays measured / 16 x one (32 px tiles) {ratio:.3f}, "
          "the model's scale",
          flush=True)

    windows64 = random_windows(64, 8, rng)  # the 1M scene's tiles against these
    small, _ = tile_seconds(cfg, plan, scene, envmap, lights, trees, windows64)

    lc = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
    client = Client(lc, set_as_default=False)
    try:
        print("ship: scene, lights and trees to a LocalCluster of 2 workers", flush=True)
        ship_rows = []
        nbytes, seconds = ship_seconds(client, (scene, envmap, lights, trees))
        ship_rows.append({"triangles": 200_000, "client_seconds": prep200, "bytes": nbytes, "scatter_seconds": seconds,
                          "worker_setup_seconds": setup200, "tile_cost_ratio": 1.0})
        del scene, lights, trees
        cfg1, plan1, scene1, envmap1, lights1, trees1, prep1m = prepare(1_000_000)
        big, setup1m = tile_seconds(cfg1, plan1, scene1, envmap1, lights1, trees1, windows64)
        nbytes1, seconds1 = ship_seconds(client, (scene1, envmap1, lights1, trees1))
        ship_rows.append({"triangles": 1_000_000, "client_seconds": prep1m, "bytes": nbytes1,
                          "scatter_seconds": seconds1, "worker_setup_seconds": setup1m,
                          "tile_cost_ratio": statistics.median(b / s for b, s in zip(big, small))})
        del scene1, lights1, trees1
        save_csv(out / "distributed-ship.csv", ship_rows, tuple(ship_rows[0]))
        for r in ship_rows:
            print(f"  {r['triangles']:>9,} triangles: client {r['client_seconds']:.2f} s, {r['bytes'] / 1e6:.1f} MB, "
                  f"scatter {r['scatter_seconds']:.2f} s, worker setup {r['worker_setup_seconds']:.2f} s, "
                  f"64 px tile cost x{r['tile_cost_ratio']:.2f}", flush=True)

        print(f"scheduler: {a.tasks} tasks through the LocalCluster", flush=True)
        sched_rows = scheduler_seconds(client, a.tasks)
        save_csv(out / "distributed-scheduler.csv", sched_rows, ("tasks", "seconds_per_task", "n"))
        for r in sched_rows:
            print(f"  {r['tasks']:<18} {1e3 * r['seconds_per_task']:.2f} ms per task", flush=True)
    finally:
        client.close()
        lc.close()

    sched = max(r["seconds_per_task"] for r in sched_rows)
    bw = a.bandwidth * 1e9 / 8
    model_rows = []
    print(f"model: 3840x2160, {SPP} eye rays, machines of {CORES} cores, {a.bandwidth:g} Gb/s, "
          f"{1e3 * sched:.2f} ms per task", flush=True)
    for r in ship_rows:
        for m in MACHINES:
            ship = (1 + 2 * math.ceil(math.log(m, 3))) * r["bytes"] / bw + r["worker_setup_seconds"] if m > 1 else 0.0
            best = None
            for size in SIZES:
                c = costs[size] * r["tile_cost_ratio"]
                f = fixed * r["tile_cost_ratio"]
                t = statistics.median(simulate(m, size, c, f, ratio, r["client_seconds"], ship,
                                               sched if m > 1 else 0.0, rng) for _ in range(a.trials))
                row = {"triangles": r["triangles"], "machines": m, "tile": size, "seconds": t, "ship_seconds": ship,
                       "client_seconds": r["client_seconds"], "best": False}
                model_rows.append(row)
                best = row if best is None or t < best["seconds"] else best
            best["best"] = True
        one = {row["tile"]: row["seconds"] for row in model_rows if row["triangles"] == r["triangles"]
               and row["machines"] == 1}
        t1 = min(one.values())
        for row in model_rows:
            if row["triangles"] == r["triangles"]:
                row["efficiency"] = t1 / (row["machines"] * row["seconds"])
        for row in model_rows:
            if row["triangles"] == r["triangles"] and row.get("best"):
                tiles = math.ceil(FRAME[0] / row["tile"]) * math.ceil(FRAME[1] / row["tile"])
                print(f"  {r['triangles']:>9,} triangles, {row['machines']:>3} machines: best tile {row['tile']:>3} px, "
                      f"{row['seconds']:8.1f} s, efficiency {row['efficiency']:.3f}; ideal {t1 / row['machines']:.1f} s, "
                      f"client {row['client_seconds']:.1f} s, ship {row['ship_seconds']:.2f} s, scheduler "
                      f"{tiles * sched if row['machines'] > 1 else 0:.1f} s for {tiles} tiles", flush=True)
    save_csv(out / "distributed-model.csv", model_rows, ("triangles", "machines", "tile", "seconds", "efficiency",
                                                         "ship_seconds", "client_seconds", "best"))


if __name__ == "__main__":
    main()
