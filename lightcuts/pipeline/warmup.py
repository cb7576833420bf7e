"""numba on the commands' side: a notice when kernels first compile, and the render kernel compiled on the side.

On an empty cache a render spends most of its time compiling kernels (``cache=True``: later runs
load them), one kernel at a time (numba compiles under one lock per process). The render kernel
(the ``_render_band`` of the integrator's ``kernels`` module) is the largest of them and is needed
last, so :func:`start_render_warmup` compiles it in a child process (one core, one pixel) while
this process traces lights and builds trees (the other), and :func:`finish_warmup` waits for the
child before the first render, which then loads the kernel from the cache. Correct however the
child ends: the cache is a cache (numba writes each entry atomically), so a child that failed, was
killed or found no writable cache only leaves this process to compile the kernel itself.
"""

from __future__ import annotations

import os
import subprocess
import sys

#: The child: on Linux it asks to be killed with its parent (a command stopped by a signal exits at
#: once), then compiles the render kernel.
_CHILD = """
try:
    import ctypes, signal
    ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
except Exception:
    pass
import importlib, sys
importlib.import_module(sys.argv[1]).warm_kernels()
"""

#: Longest wait for the child before the render compiles the kernel itself, seconds.
WARMUP_TIMEOUT = 600.0


_ANNOUNCING = False
#: No figure: how long compiling takes depends on the machine and its load (the run's report.json
#: gives the seconds measured, ``compile_seconds``).
NOTICE = ("compiling numba kernels once (light tracing, tree builder, renderer); later runs load them "
          "from the cache; report.json gives the seconds spent compiling")
#: Seconds numba spent compiling in this process (outermost ``numba:compile`` events), and the depth.
_COMPILING = {"seconds": 0.0, "depth": 0, "start": 0.0}


def compile_seconds() -> float:
    """Wall seconds numba has spent compiling kernels in this process so far (0 until
    :func:`announce_compiles` is called; cache loads are not compiles)."""
    return _COMPILING["seconds"]


def announce_compiles() -> None:
    """Print :data:`NOTICE` to stderr once, when numba first compiles a kernel in this process (not
    on cache hits: numba's ``numba:compile`` event fires on cache misses only), and from then on
    count the seconds compiling takes (:func:`compile_seconds`)."""
    global _ANNOUNCING
    if _ANNOUNCING:
        return
    _ANNOUNCING = True
    import time

    from numba.core import event

    class Once(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                print(NOTICE, file=sys.stderr, flush=True)
            if _COMPILING["depth"] == 0:
                _COMPILING["start"] = time.perf_counter()
            _COMPILING["depth"] += 1

        def on_end(self, ev):
            _COMPILING["depth"] = max(0, _COMPILING["depth"] - 1)
            if _COMPILING["depth"] == 0:
                _COMPILING["seconds"] += time.perf_counter() - _COMPILING["start"]

    event.register("numba:compile", Once())


def is_cached(dispatcher) -> bool:
    """Whether numba's cache holds a compiled version of the current source of ``dispatcher``
    (a ``cache=True`` kernel; True when that cannot be told, e.g. caching disabled)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # numba internals differ, no cache: do not claim the cache is cold
        return True


def start_render_warmup(kernels: str | None = "lightcuts.integrators.lightcut") -> subprocess.Popen | None:
    """If the render kernel is not in the cache, start a child process that compiles it (and writes
    it to the cache) by rendering one pixel of a small scene; None if it is cached, ``kernels`` is
    None or the child cannot start.

    kernels : the module of the render kernel ``_render_band`` and of ``warm_kernels()``, which
        compiles it (an integrator's ``kernels`` trait)
    """
    import importlib

    if kernels is None or is_cached(importlib.import_module(kernels)._render_band):
        return None
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in [env.get("PYTHONPATH")] if p])
    try:
        return subprocess.Popen([sys.executable, "-c", _CHILD, kernels], env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None


def finish_warmup(proc: subprocess.Popen | None, timeout: float = WARMUP_TIMEOUT) -> None:
    """Wait for the child of :func:`start_render_warmup` (None: nothing to do); after ``timeout``
    seconds it is killed, and the caller compiles what it needs itself."""
    if proc is None:
        return
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        pass
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
