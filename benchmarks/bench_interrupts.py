"""Interrupting ``lightcuts render --workers N`` at random moments: how long the command takes to end,
what it prints, and which of its processes outlive it.

A trial starts ``lightcuts render configs/cornell.yaml --workers N`` (96 x 96 pixels, 32 eye rays,
8 px tiles: about 20 s with 2 workers on 2 cores, so the moments fall on every stage: Python and Dask
starting, the worker processes starting, the scene, lights and trees, shipping them, the tiles and
their results) as a group leader (as a shell starts a job), waits a seeded random time between 0 and
``--max-seconds``, then sends SIGINT to the whole process group (Ctrl-C in a terminal) or SIGTERM
to the command alone (``kill PID``). It measures the seconds from the signal to the command's exit,
compares its stderr with the one line ``error: interrupted`` / ``error: terminated`` (exit status
130 / 143), and counts the processes left at the moment of its exit that are not zombies: those of
its process group and every descendant seen while it ran (looked for every 20 ms). A signal in the
first tens of milliseconds, before Python runs the command's code, meets Python's own default (for
SIGTERM, an exit by the signal with nothing printed): the table counts those apart.

Prints a table per worker count (interrupts, runs that finished first, leftover processes, wrong
stderr, slowest and median exit) and writes ``benchmarks/results/interrupts.csv`` (one row a trial).

    python benchmarks/bench_interrupts.py [--workers 2 16] [--interrupts 30] [--max-seconds 10] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

ARGS = ["render", str(ROOT / "configs" / "cornell.yaml"), "--no-progress", "--set", "camera.resolution=[96,96]",
        "--set", "render.spp=32", "--tile-size", "8"]
#: Signal -> (the line the command must print alone, its exit status).
EXPECTED = {signal.SIGINT: ("error: interrupted", 130), signal.SIGTERM: ("error: terminated", 143)}


def _alive(pids) -> list[int]:
    """Those of ``pids`` that are running processes (not zombies)."""
    import psutil

    out = []
    for pid in pids:
        try:
            if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                out.append(pid)
        except psutil.Error:
            pass
    return out


def _group(pgid: int) -> set[int]:
    """The processes of process group ``pgid``."""
    import psutil

    out = set()
    for pid in psutil.pids():
        try:
            if os.getpgid(pid) == pgid:
                out.add(pid)
        except OSError:
            pass
    return out


def trial(workers: int, at: float, signum: int = signal.SIGINT, folder: str | None = None,
          timeout: float = 120.0, settle: float = 1.0) -> dict:
    """Start the command with ``--workers workers``, send ``signum`` after ``at`` seconds (SIGINT to its
    process group, SIGTERM to the command) and return ``{"workers", "signal", "at", "finished"
    (it ended before the signal), "exit_seconds" (signal to exit), "returncode", "stderr", "ok_stderr"
    (the one expected line and exit status), "left" (pids alive when it exited), "left_after_1s" (of
    those, alive ``settle`` seconds later; then killed)}``."""
    import psutil

    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        err_path = Path(tmp) / "stderr"
        with open(err_path, "w") as err:
            p = subprocess.Popen([sys.executable, "-m", "lightcuts", *ARGS, "--out", str(Path(tmp) / "out"),
                                  "--workers", str(workers)], cwd=tmp, env=env, stdout=subprocess.DEVNULL,
                                 stderr=err, start_new_session=True)
        seen: set[int] = set()
        stop = threading.Event()

        def watch():
            while not stop.is_set():
                try:
                    seen.update(c.pid for c in psutil.Process(p.pid).children(recursive=True))
                except psutil.Error:
                    pass
                stop.wait(0.02)

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        finished = False
        try:
            p.wait(at)
            finished = True
        except subprocess.TimeoutExpired:
            pass
        t0 = time.perf_counter()
        if not finished:
            if signum == signal.SIGINT:
                os.killpg(p.pid, signal.SIGINT)
            else:
                os.kill(p.pid, signum)
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        seconds = time.perf_counter() - t0
        stop.set()
        watcher.join()
        left = _alive((_group(p.pid) | seen) - {p.pid})
        time.sleep(settle)
        later = _alive(left)
        for pid in later:  # leave the machine as it was
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        stderr = err_path.read_text(errors="replace")
    line, code = EXPECTED[signum]
    return {"workers": workers, "signal": signal.Signals(signum).name, "at": at, "finished": finished,
            "exit_seconds": 0.0 if finished else seconds, "returncode": p.returncode, "stderr": stderr,
            "ok_stderr": finished or (stderr == line + "\n" and p.returncode == code), "left": left,
            "left_after_1s": later}


def main() -> None:
    import numpy as np

    from lightcuts.io import save_csv

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, nargs="+", default=[2, 16], help="LocalCluster sizes")
    ap.add_argument("--interrupts", type=int, default=30, help="trials per worker count")
    ap.add_argument("--max-seconds", type=float, default=10.0, help="latest moment of a signal")
    ap.add_argument("--sigterm-every", type=int, default=3, help="every k-th trial sends SIGTERM (0: none)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()

    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    print(f"load average {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for n in a.workers:
        for i in range(a.interrupts):
            at = float(rng.uniform(0.0, a.max_seconds))
            signum = signal.SIGTERM if a.sigterm_every and i % a.sigterm_every == a.sigterm_every - 1 else signal.SIGINT
            r = trial(n, at, signum)
            rows.append({**r, "stderr": r["stderr"].replace("\n", "\\n")[:300], "left": len(r["left"]),
                         "left_after_1s": len(r["left_after_1s"])})
            print(f"  --workers {n:<3} {r['signal']:<7} at {at:5.2f} s: exit {r['exit_seconds']:.2f} s, "
                  f"status {r['returncode']}, left {len(r['left'])} ({len(r['left_after_1s'])} after 1 s)"
                  + ("" if r["ok_stderr"] else f", stderr {r['stderr'][:200]!r}")
                  + (", finished first" if r["finished"] else ""), flush=True)
    save_csv(out / "interrupts.csv", rows, ("workers", "signal", "at", "finished", "exit_seconds", "returncode",
                                            "ok_stderr", "left", "left_after_1s", "stderr"))
    print("\n| workers | interrupts | finished first | leftover processes | wrong stderr (before Python ran the "
          "command) | slowest exit | median exit |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in a.workers:
        rs = [r for r in rows if r["workers"] == n]
        hit = [r for r in rs if not r["finished"]]
        exits = [r["exit_seconds"] for r in hit] or [0.0]
        early = sum(r["returncode"] < 0 and r["stderr"] == "" for r in hit)  # the signal's default action
        print(f"| {n} | {len(hit)} | {len(rs) - len(hit)} | {sum(r['left'] for r in rs)} | "
              f"{sum(not r['ok_stderr'] for r in rs)} ({early}) | {max(exits):.2f} s | {statistics.median(exits):.2f} s |")


if __name__ == "__main__":
    main()
