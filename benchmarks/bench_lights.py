"""Light generation time: particle-traced VPLs in the Cornell box, direct lights, environment lights, CLI.

Rows:
  indirect/<caster>  100,000 indirect VPLs (about: see lightcuts.lights.indirect) in the Cornell box,
                     with the ``embree`` caster (per-ray calls inside one numba kernel) and the
                     ``embreex`` caster (wavefront over its batch API); also with numba on one thread
  direct             1,024 direct lights on the Cornell box's light
  environment        a 256 x 128 procedural sky generated and sampled into 4,096 directional lights
  cli                ``lightcuts lights configs/cornell.yaml`` in a fresh process (numba cache warm),
                     wall clock of the whole process, and the generation time the command reports

Medians of --repeats runs after a warm-up (numba compiled or loaded from its cache first). Wall
clock and process CPU time (all threads) are both given: the machine has 2 cores shared with
other work, so wall times are noisy and CPU time shows the work itself. The load average at the
start is printed and saved.

    python benchmarks/bench_lights.py [--count 100000] [--repeats 5] [--no-cli]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lightcuts.accel import RAY_CASTERS, make_caster  # noqa: E402
from lightcuts.io import save_csv  # noqa: E402
sys.path.insert(0, str(ROOT / "benchmarks"))
from common import load_average, timed  # noqa: E402
from lightcuts.lights.direct import direct_lights  # noqa: E402
from lightcuts.lights.environment import environment_lights, procedural_sky  # noqa: E402
from lightcuts.lights.indirect import indirect_lights  # noqa: E402
from lightcuts.scene.cornell import cornell_box  # noqa: E402


def cli_runs(repeats):
    """(median wall s of the process, median generation s it reports, lights) for the CLI command."""
    config = ROOT / "configs" / "cornell.yaml"
    cmd = [sys.executable, "-m", "lightcuts", "lights", str(config)]
    wall, reported, n = [], [], 0
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "lights.npz"
        for i in range(repeats + 1):  # the first run fills numba's cache if it is cold
            t0 = time.perf_counter()
            res = subprocess.run(cmd + ["--out", str(out)], capture_output=True, text=True, cwd=ROOT)
            dt = time.perf_counter() - t0
            if res.returncode != 0:
                raise SystemExit(f"lightcuts lights failed: {res.stderr.strip()}")
            m = re.search(r": (\d+) oriented lights in ([\d.]+) s", res.stdout)
            if i > 0:
                wall.append(dt)
                reported.append(float(m.group(2)))
                n = int(m.group(1))
    return statistics.median(wall), statistics.median(reported), n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=100_000, help="indirect VPLs asked for")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-cli", action="store_true", help="skip the fresh-process CLI timing")
    args = ap.parse_args()

    load = load_average()
    scene = cornell_box()
    rows = []
    threads = numba.get_num_threads()
    casters = [c for c in ("embree", "embreex") if c in RAY_CASTERS]
    for name in casters:
        caster = make_caster(scene, name)
        for n_threads in sorted({threads, 1}, reverse=True):
            numba.set_num_threads(n_threads)
            try:
                wall, cpu, ls = timed(lambda: indirect_lights(scene, caster, args.count, seed=1), args.repeats,
                                      warmup=True)
            finally:
                numba.set_num_threads(threads)
            rows.append(dict(benchmark=f"indirect/{name}", threads=n_threads, lights=len(ls),
                             paths=ls.meta["indirect_paths"], median_s=wall, cpu_s=cpu))
    wall, cpu, ls = timed(lambda: direct_lights(scene, 1024, seed=1), args.repeats, warmup=True)
    rows.append(dict(benchmark="direct", threads=threads, lights=len(ls), paths="", median_s=wall, cpu_s=cpu))
    wall, cpu, ls = timed(lambda: environment_lights(procedural_sky(), 4096, seed=1), args.repeats, warmup=True)
    rows.append(dict(benchmark="environment", threads=threads, lights=len(ls), paths="", median_s=wall, cpu_s=cpu))
    if not args.no_cli and (ROOT / "configs" / "cornell.yaml").is_file():
        wall, reported, n = cli_runs(max(3, args.repeats // 2 + 1))
        rows.append(dict(benchmark="cli process", threads=threads, lights=n, paths="", median_s=wall, cpu_s=""))
        rows.append(dict(benchmark="cli reported", threads=threads, lights=n, paths="", median_s=reported,
                         cpu_s=""))

    print(f"Cornell box ({scene.n_faces} triangles), medians of {args.repeats} runs after warm-up; "
          f"load average {load:.2f} on {os.cpu_count()} cores (shared machine: wall times are noisy)")
    print(f"{'benchmark':<20}{'threads':>8}{'lights':>9}{'paths':>8}{'wall s':>9}{'CPU s':>9}")
    for r in rows:
        cpu = f"{r['cpu_s']:.3f}" if r["cpu_s"] != "" else "-"
        print(f"{r['benchmark']:<20}{r['threads']:>8}{r['lights']:>9}{r['paths']!s:>8}{r['median_s']:>9.3f}{cpu:>9}")
    out = ROOT / "benchmarks" / "results" / "lights.csv"
    save_csv(out, [{**r, "load_average": round(load, 2)} for r in rows])
    print(f"-> {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
