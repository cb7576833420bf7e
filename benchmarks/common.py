"""What the benchmark scripts share: timing, the machine's load, the Cornell-box lights.

Each script puts the repository on ``sys.path`` and imports this module beside it.
"""

from __future__ import annotations

import os
import statistics
import time


def timed(fn, repeats: int, warmup: bool = False):
    """(median wall s, median process CPU s, last result) over ``repeats`` calls of ``fn``, after one
    untimed call when ``warmup`` (numba compiles or loads its cache on the first)."""
    if warmup:
        fn()
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), out


def load_average() -> float:
    """The 1-minute load average: a benchmark taken above ~0.5 on 2 cores shares them with other work."""
    return os.getloadavg()[0]


def cornell_vpls(n_indirect: int, n_direct: int = 0, seed: int = 1):
    """(scene, caster, LightSet): the built-in Cornell box, its ``embree`` caster and ``n_direct``
    direct plus about ``n_indirect`` particle-traced indirect lights (oriented), as ``cornell.yaml``
    makes them for its seed."""
    from lightcuts.accel import make_caster
    from lightcuts.lights.direct import direct_lights
    from lightcuts.lights.indirect import indirect_lights
    from lightcuts.lights.lightset import LightSet
    from lightcuts.scene.cornell import cornell_box

    scene = cornell_box()
    caster = make_caster(scene, "embree")
    sets = []
    if n_direct:
        sets.append(direct_lights(scene, n_direct, seed))
    if n_indirect:
        sets.append(indirect_lights(scene, caster, n_indirect, seed))
    return scene, caster, LightSet.concatenate(sets)
