"""Seconds numba spends compiling each kernel in one cold run of a command, and how often it compiles each.

    python tools/compile_times.py [--top 15] [--json FILE] [--numba] -- render configs/cornell.yaml --no-progress --out /tmp/r

Runs the lightcuts CLI in this process on an empty ``NUMBA_CACHE_DIR`` (a fresh temporary folder,
unless the environment sets one) with the render kernel's warm-up child switched off, so that every compile
happens here and is seen. Prints, per function, its exclusive compile seconds (its own typing,
lowering and LLVM, not the functions it compiled on the way) and its inclusive seconds, largest
first, and the total: CPU seconds of the compiling thread, which a busy machine inflates less than
wall time.

Then the specialisations (one ``numba:compile`` event each: numba compiles a function again for
every new tuple of argument types): how many lightcuts functions and specialisations, how many of
numba's own overload implementations (``np.empty`` for each dtype and rank, ...; ``--numba`` lists
them too), the seconds the lightcuts functions' repeated compiles took (all but each one's longest),
and for every lightcuts function compiled more than once the argument positions whose types differ,
e.g. ``integrators.cut.stochastic_estimate x2: arg 32 Literal[int](0) | int64``, or, when the types
are the same, the compile flags of the callers that differ (numba builds an ``@overload``'s
implementation once per set of its caller's flags: ``release_gil``, ``error_model``, ...).
``--json FILE`` writes these figures (``functions``, ``specialisations``, ``numba_functions``,
``numba_specialisations``, ``compile_cpu_s``, ``repeat_cpu_s``, ``wall_s``, ``duplicates``: name ->
{"arg i" or "caller's flag": [types or values]}).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time


def differences(compiles: list[tuple[tuple, dict]]) -> dict[str, list[str]]:
    """What differs between the compiles of one function, each ``(argument types, caller's flags)``:
    ``{"arg i": distinct types}`` for the argument positions whose numba types differ (a position
    missing from a shorter tuple counts as ``-``), else ``{"flag name": distinct values}`` for the
    callers' compile flags that differ; values in order of first use."""
    def distinct(values):
        return list(dict.fromkeys(map(str, values)))

    sigs = [c[0] for c in compiles]
    out = {f"arg {i}": distinct(s[i] if i < len(s) else "-" for s in sigs)
           for i in range(max(map(len, sigs)))}
    out = {k: v for k, v in out.items() if len(v) > 1}
    if not out:
        names = dict.fromkeys(k for c in compiles for k in c[1])
        out = {f"caller's {k}": distinct(c[1].get(k, "-") for c in compiles) for k in names}
        out = {k: v for k, v in out.items() if len(v) > 1}
    return out


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--top", type=int, default=15)
    p.add_argument("--json", metavar="FILE", help="write the counts and the duplicates here")
    p.add_argument("--numba", action="store_true", help="list numba's own functions compiled more than once too")
    p.add_argument("args", nargs=argparse.REMAINDER)
    a = p.parse_args()
    args = a.args[1:] if a.args[:1] == ["--"] else a.args
    os.environ.setdefault("NUMBA_CACHE_DIR", tempfile.mkdtemp(prefix="lightcuts-numba-"))

    from numba.core import event
    from numba.core.targetconfig import ConfigStack

    stack: list[list] = []
    excl: dict[str, float] = {}
    each: dict[str, list[float]] = {}  # per function: the exclusive seconds of each of its compiles
    incl: dict[str, float] = {}
    compiles: dict[str, list[tuple[tuple, dict]]] = {}  # per function: (argument types, caller's flags)
    mine: set[str] = set()  # lightcuts' own functions; the others are numba's overload implementations

    class Timer(event.Listener):
        def on_start(self, ev):
            f = ev.data["dispatcher"].py_func
            key = f"{f.__module__.removeprefix('lightcuts.')}.{f.__qualname__}"
            caller = ConfigStack.top_or_none()  # the flags of the function being compiled around this one
            compiles.setdefault(key, []).append((tuple(ev.data["args"]), caller.values() if caller else {}))
            if f.__module__.split(".")[0] == "lightcuts":
                mine.add(key)
            stack.append([key, time.thread_time(), 0.0])

        def on_end(self, ev):
            key, t0, child = stack.pop()
            dt = time.thread_time() - t0
            excl[key] = excl.get(key, 0.0) + dt - child
            each.setdefault(key, []).append(dt - child)
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
    total = sum(excl.values())
    print(f"{len(rows)} functions compiled, {total:.1f} s compiling of {wall:.1f} s wall", file=sys.stderr)

    dups = {k: differences(v) for k, v in compiles.items() if len(v) > 1 and (k in mine or a.numba)}
    n_mine = sum(len(compiles[k]) for k in mine)
    n_theirs = sum(len(v) for k, v in compiles.items() if k not in mine)
    theirs = len(compiles) - len(mine)
    # what compiling each lightcuts function once would save, at least: all its compiles but the longest
    repeat = sum(sum(each[k]) - max(each[k]) for k in mine if len(each[k]) > 1)
    print(f"lightcuts: {len(mine)} functions, {n_mine} specialisations; "
          f"numba's own: {theirs} functions, {n_theirs} specialisations; "
          f"{repeat:.2f} s compiling lightcuts functions again", file=sys.stderr)
    for k in sorted(dups):
        diff = "; ".join(f"{i} {' | '.join(t)}" for i, t in dups[k].items()) or "same types and flags"
        print(f"  {k} x{len(compiles[k])}: {diff}", file=sys.stderr)
    if a.json:
        from lightcuts.io import save_json  # written whole, then renamed

        save_json(a.json, {"functions": len(mine), "specialisations": n_mine,
                           "numba_functions": theirs, "numba_specialisations": n_theirs,
                           "compile_cpu_s": round(total, 2), "repeat_cpu_s": round(repeat, 2),
                           "wall_s": round(wall, 2), "duplicates": {k: d for k, d in dups.items() if k in mine}})


if __name__ == "__main__":
    main()
