"""The worker side of a cluster run: one lightcuts task at a time per process, on the worker's share
of the cores, with the ray caster built once per run.

A Dask worker runs tasks on its own threads. lightcuts' kernels run on lightcuts.parallel's threads
inside a task, and some (the Embree batch casts) are numba ``parallel=True`` kernels, which numba's
default threading layer does not allow several threads to launch at once. So every task takes this
process's lock (:data:`LOCK`) for its whole run, and inside sets the numba thread count to the
worker's thread count (its share of the machine's cores: ``dask worker --nthreads``), which the task's
kernels then use. A worker of N threads thus runs one lightcuts task with N threads at a time, the
others waiting.

Scenes, lights and trees arrive as the arguments of tasks (Dask keeps one copy per worker); the ray
caster (Embree's scene cannot be pickled) is built from the scene by the first task of a run on a
worker and kept under the run's token (:func:`run_state`) until the client drops it
(:func:`drop_runs`) or newer runs push it out. The render kernel is loaded (or compiled) once per
process (:func:`warm`).
"""

from __future__ import annotations

import os
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field

#: Held by every lightcuts task of this process for its whole run (module docstring).
LOCK = threading.Lock()
#: Runs whose casters a worker keeps at most (a client that died cannot drop its run).
KEEP_RUNS = 4

_RUNS: OrderedDict = OrderedDict()
_WARM: dict = {}
_DROP: set = set()  # runs dropped while a task held the lock: dropped when it ends


@dataclass
class Run:
    """One run's state on this worker: the plan of its config, its scene, environment
    map and the ray caster built over the scene; ``warmed``: the builders whose kernels a task has loaded;
    ``forests``: what the integrator renders from, made once (:meth:`forest`)."""

    plan: object
    scene: object
    envmap: object
    caster: object
    setup_seconds: float
    warmed: set = field(default_factory=set)
    forests: dict = field(default_factory=dict)

    def forest(self, integrator, lights: dict, trees: dict | None):
        """The light forest ``integrator`` renders from (its ``forest(lights, trees, scene)`` hook), made
        once for all tiles of the same lights and trees and the same kind of integrator (the worker
        keeps one copy of the shipped objects, so identity tells them apart; the entry holds them, so
        their ids cannot be reused)."""
        key = (type(integrator), trees is None)
        entry = self.forests.get(key)
        if entry is None or entry[0] is not lights or entry[1] is not trees:
            entry = self.forests[key] = (lights, trees, integrator.forest(lights, trees, self.scene))
        return entry[2]


def worker_address() -> str:
    """This worker's address, or ``local`` outside a Dask worker."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def core_share() -> int:
    """The numba threads a task uses: the Dask worker's thread count (outside a worker, this thread's
    numba count), at most numba's pool."""
    import numba

    try:
        from distributed import get_worker

        n = int(get_worker().state.nthreads)
    except (ImportError, ValueError, AttributeError):
        n = numba.get_num_threads()
    return max(1, min(n, numba.config.NUMBA_NUM_THREADS))


def exclusive(body, *args):
    """``body(*args)`` as this process's only lightcuts task, with :func:`core_share` numba threads:
    ``(value, info)``, info = {"worker", "pid", "threads", "seconds" (body's), "wait" (for the lock),
    "start", "end" (wall-clock, for checks that tasks did not overlap)}."""
    import numba

    from lightcuts.parallel import num_threads

    t_ask = time.perf_counter()
    with LOCK:
        start = time.time()
        t0 = time.perf_counter()
        try:
            with num_threads(core_share()):
                threads = numba.get_num_threads()  # what the task's kernels use
                value = body(*args)
        finally:
            while _DROP:
                _forget(_DROP.pop())
        seconds = time.perf_counter() - t0
        end = time.time()
    return value, {"worker": worker_address(), "pid": os.getpid(), "threads": threads, "seconds": seconds,
                   "wait": t0 - t_ask, "start": start, "end": end}


def warm(kernels: str | None) -> float:
    """Load (or compile) the render kernel of the module ``kernels`` (an integrator's ``kernels``
    trait) once per process; the seconds it took the first time, 0 after."""
    import importlib

    if kernels is None or kernels in _WARM:
        return 0.0
    t0 = time.perf_counter()
    importlib.import_module(kernels).warm_kernels()
    _WARM[kernels] = time.perf_counter() - t0
    return _WARM[kernels]


#: The modules whose objects a task's arguments hold (config, scene, textures, lights, trees, the
#: integrators and their forest).
DATA_MODULES = ("lightcuts.config.schema", "lightcuts.scene.scene", "lightcuts.scene.textures",
                "lightcuts.lights.lightset", "lightcuts.lights.environment", "lightcuts.trees.tree",
                "lightcuts.integrators.registry", "lightcuts.integrators.forest")


def import_modules(kernels: str | None) -> None:
    """Import :data:`DATA_MODULES` and the integrator modules (and ``kernels``) in this worker, run
    once before its first task (``Client.run``): a task's arguments unpickled in one thread while the
    warm task imports the kernels in another can otherwise meet a half-initialised module of the
    same package (Python's import deadlock avoidance hands one thread the partial module)."""
    import importlib

    from lightcuts.integrators.registry import INTEGRATORS

    for name in DATA_MODULES + ((kernels,) if kernels else ()):
        importlib.import_module(name)
    INTEGRATORS.names()  # imports every built-in integrator's module


def warm_task(kernels: str | None) -> dict:
    """A task that warms this worker (:func:`warm`) while the client makes the scene, lights and trees."""
    seconds, info = exclusive(warm, kernels)
    return {**info, "warm_seconds": seconds}


def run_state(token: str, cfg, scene, envmap) -> Run:
    """The Run of ``token`` on this worker, made on first use (the plan of ``cfg``, the caster over
    ``scene``, the kernels warmed); call with :data:`LOCK` held."""
    run = _RUNS.get(token)
    if run is not None:
        _RUNS.move_to_end(token)
        return run
    from lightcuts.pipeline.plan import plan_run

    t0 = time.perf_counter()
    plan = plan_run(cfg)  # the client checked the config; its caster need not render (scaling)
    caster = plan.make_caster(scene)
    warm(plan.integrator.trait("kernels"))
    run = Run(plan, scene, envmap, caster, time.perf_counter() - t0)
    _RUNS[token] = run
    while len(_RUNS) > KEEP_RUNS:
        _close(_RUNS.popitem(last=False)[1])
    return run


def _close(run: Run) -> None:
    close = getattr(run.caster, "close", None)
    if close is not None:
        close()


def _forget(token: str) -> None:
    run = _RUNS.pop(token, None)
    if run is not None:
        _close(run)


def drop_runs(*tokens: str) -> None:
    """Forget the runs ``tokens`` on this worker (their casters closed). The client calls it on every
    worker when its runs end (``client.run``, on the worker's event loop, so it never waits): while a
    task holds the lock, that task drops them when it ends."""
    if LOCK.acquire(blocking=False):
        try:
            for token in tokens:
                _forget(token)
        finally:
            LOCK.release()
    else:
        _DROP.update(tokens)


def runs() -> list[str]:
    """The tokens of the runs this worker keeps (for tests)."""
    return list(_RUNS)


def in_run(token: str, cfg, scene, envmap, body, *args):
    """``body(run, *args)`` as an :func:`exclusive` task of the run ``token``: ``(value, info)``,
    info with ``setup_seconds`` when this task built the run's caster."""
    def task():
        fresh = token not in _RUNS
        run = run_state(token, cfg, scene, envmap)
        return body(run, *args), (run.setup_seconds if fresh else 0.0)

    (value, setup), info = exclusive(task)
    return value, {**info, "setup_seconds": setup}
