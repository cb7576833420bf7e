"""Seconds numba spends compiling each kernel in one cold run of a command, from ``numba:compile`` events.

    python tools/compile_times.py [--top 15] -- render configs/cornell.yaml --no-progress --out /tmp/r

Runs the lightcuts CLI in this process on an empty ``NUMBA_CACHE_DIR`` (a fresh temporary folder,
unless the environment sets one) with the render kernel's warm-up child switched off, so that every compile
happens here and is seen. Prints, per function, its exclusive compile seconds (its own typing,
lowering and LLVM, not the functions it compiled on the way) and its inclusive seconds, largest
first, and the total: CPU seconds of the compiling thread, which a busy machine inflates less than
wall time.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--top", type=int, default=15)
    p.add_argument("args", nargs=argparse.REMAINDER)
    a = p.parse_args()
    args = a.args[1:] if a.args[:1] == ["--"] else a.args
    os.environ.setdefault("NUMBA_CACHE_DIR", tempfile.mkdtemp(prefix="lightcuts-numba-"))

    from numba.core import event

    stack: list[list] = []
    excl: dict[str, float] = {}
    incl: dict[str, float] = {}

    class Timer(event.Listener):
        def on_start(self, ev):
            stack.append([ev.data["dispatcher"].py_func.__qualname__, time.thread_time(), 0.0,
                          ev.data["dispatcher"].py_func.__module__])

        def on_end(self, ev):
            name, t0, child, mod = stack.pop()
            dt = time.thread_time() - t0
            key = f"{mod.removeprefix('lightcuts.')}.{name}"
            excl[key] = excl.get(key, 0.0) + dt - child
            incl[key] = incl.get(key, 0.0) + dt
            if stack:
                stack[-1][2] += dt

    event.register("numba:compile", Timer())
    import lightcuts.pipeline.warmup as warmup
    from lightcuts.cli import main as cli

    warmup.start_render_warmup = lambda *a: None  # every compile in this process, where it is seen

    t0 = time.perf_counter()
    try:
        cli(args)
    except SystemExit:
        pass
    wall = time.perf_counter() - t0
    rows = sorted(excl, key=excl.get, reverse=True)
    print(f"{'function':60s} {'excl s':>8s} {'incl s':>8s}", file=sys.stderr)
    for k in rows[:a.top]:
        print(f"{k:60s} {excl[k]:8.2f} {incl[k]:8.2f}", file=sys.stderr)
    print(f"{len(rows)} functions compiled, {sum(excl.values()):.1f} s compiling of {wall:.1f} s wall",
          file=sys.stderr)


if __name__ == "__main__":
    main()
