"""Light-tree build time on Cornell-box VPLs, 50K..800K lights, for every registered builder but greedy.

Lights: particle-traced indirect VPLs in the Cornell box (``lightcuts.lights.indirect``, seed 1;
about N, the exact count is in the table). Per size and builder:

  first     wall clock of the first ``build_tree`` call per builder and size: numba compile (or
            cache load) on the first size, plus one build
  total     ``build_tree`` wall clock: the checks of the lights, the builder's topology, the
            topology check and the shared bottom-up fill (boxes, cones, intensities, representatives)
  topology  the builder function alone
  cpu       process CPU time of ``build_tree`` (all threads)

Medians of --repeats runs after one warm-up build per builder and size (numba compiled or loaded
from its cache first). The machine has 2 cores shared with other work, so wall times are noisy:
compare builders within one run, and read the CPU column too. The load average at the start is
printed and saved.

    python benchmarks/bench_trees.py [--sizes 50000,...,800000] [--builders a,b] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numba

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
from lightcuts.lights.indirect import indirect_lights  # noqa: E402
from lightcuts.scene.cornell import cornell_box  # noqa: E402
from lightcuts.trees import BUILDERS, build_tree, default_c, get_metric  # noqa: E402

FIELDS = ("n_lights", "builder", "first_wall_s", "total_wall_s", "total_cpu_s", "topology_wall_s", "depth", "repeats",
          "load_avg")


def run(lights, name: str, repeats: int) -> dict:
    """Medians of ``repeats`` build_tree and bare-builder runs (after a warm-up of each)."""
    builder = BUILDERS.get(name)
    metric = get_metric("walter2008")
    c = default_c(lights)
    args = (lights.position, lights.normal, lights.luminance, lights.type, metric, c, 0)
    t0 = time.perf_counter()
    build_tree(lights, builder=name)
    first = time.perf_counter() - t0
    builder(*args)
    wall, cpu, topo = [], [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        tree = build_tree(lights, builder=name)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        t0 = time.perf_counter()
        builder(*args)
        topo.append(time.perf_counter() - t0)
    return dict(first_wall_s=first, total_wall_s=statistics.median(wall), total_cpu_s=statistics.median(cpu),
                topology_wall_s=statistics.median(topo), depth=tree.depth())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="50000,100000,200000,400000,800000")
    ap.add_argument("--builders", default=None, help="comma-separated (default: all registered but greedy)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "trees.csv"))
    a = ap.parse_args()
    names = a.builders.split(",") if a.builders else [b for b in BUILDERS.names() if b != "greedy"]
    load = os.getloadavg()[0]
    print(f"load average {load:.2f}, numba threads {numba.get_num_threads()}, repeats {a.repeats}")
    scene = cornell_box()
    caster = make_caster(scene, "embree")
    rows = []
    head = f"{'N':>8} {'builder':<22} {'first s':>9} {'total s':>9} {'cpu s':>9} {'topology s':>11} {'depth':>6}"
    print(head + "\n" + "-" * len(head))
    for n in (int(s) for s in a.sizes.split(",")):
        lights = indirect_lights(scene, caster, n, 1)
        for name in names:
            r = dict(n_lights=len(lights), builder=name, repeats=a.repeats, load_avg=round(load, 2),
                     **run(lights, name, a.repeats))
            rows.append(r)
            print(f"{r['n_lights']:>8} {name:<22} {r['first_wall_s']:>9.3f} {r['total_wall_s']:>9.4f} "
                  f"{r['total_cpu_s']:>9.4f} {r['topology_wall_s']:>11.4f} {r['depth']:>6}", flush=True)
    out = save_csv(a.out, rows, FIELDS)
    print(f"-> {out}")


if __name__ == "__main__":
    main()
