"""Ctrl-C and SIGTERM end a run on a LocalCluster at any moment within 2 s, with one line on stderr and
no process of the command left: the processes started for the cluster are deaf to the terminal's
signals, recorded, and killed by the command's handler."""

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).parents[2]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_interrupts", ROOT / "benchmarks" / "bench_interrupts.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_DEAF = """
import json, multiprocessing, os, signal, time
from lightcuts.distributed import processes

def blocked(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("SigBlk:"):
            mask = int(line.split()[1], 16)
            return [s for s in ("SIGINT", "SIGTERM") if mask >> (getattr(signal, s) - 1) & 1]

def mapped():  # the names in /dev/shm that a process has open (another one's, in use)
    names = set()
    for pid in os.listdir("/proc"):
        try:
            names |= {line.split("/dev/shm/")[1].split()[0] for line in open(f"/proc/{pid}/maps") if "/dev/shm/" in line}
        except (OSError, ValueError):
            pass
    return names

if __name__ == "__main__":
    processes.install()
    ctx = multiprocessing.get_context("spawn")
    p = ctx.Process(target=time.sleep, args=(60,))
    p.start()
    lock = ctx.Lock()  # a named semaphore, as Dask's queues hold
    semaphore = "/dev/shm/sem." + lock._semlock.name.lstrip("/")
    time.sleep(0.5)
    os.kill(p.pid, signal.SIGINT)
    os.kill(p.pid, signal.SIGTERM)
    time.sleep(0.5)
    out = {"blocked": blocked(p.pid), "recorded": p.pid in processes.started(), "alive": p.is_alive(),
           "mine": blocked(os.getpid()), "semaphore": os.path.exists(semaphore)}
    t0 = time.monotonic()
    processes.end_all()
    out["ended_seconds"] = time.monotonic() - t0
    out["ended"] = not os.path.exists(f"/proc/{p.pid}")  # killed and reaped: not even a zombie
    out["unlinked"] = not os.path.exists(semaphore)
    out["refused"] = []
    before = set(os.listdir("/dev/shm"))
    for make in (lambda: ctx.Process(target=time.sleep, args=(1,)).start(), ctx.Lock):
        try:
            make()
        except OSError:
            out["refused"].append(True)
    out["made"] = sorted(set(os.listdir("/dev/shm")) - before - mapped())
    print(json.dumps(out), flush=True)
    os._exit(0)  # as the CLI's handler ends
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the signal mask in /proc")
def test_a_started_process_is_deaf_to_the_signals_and_ended_at_once(tmp_path):
    """A process multiprocessing starts after processes.install(): SIGINT and SIGTERM blocked (so they
    leave it running), recorded; end_all kills and reaps it at once, unlinks the named semaphores made
    before and refuses any later process or semaphore, without a word from the resource tracker. This
    process's own signals stay as they were."""
    script = tmp_path / "deaf.py"
    script.write_text(_DEAF)
    r = subprocess.run([sys.executable, str(script)], env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                       text=True, timeout=120)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["blocked"] == ["SIGINT", "SIGTERM"] and out["recorded"] and out["alive"] and out["mine"] == [], out
    assert out["semaphore"] and out["unlinked"] and out["refused"] == [True, True] and out["made"] == [], out
    assert out["ended"] and out["ended_seconds"] < 1.0, out
    assert r.stderr == "", r.stderr


_NOISY = """
import logging, os, signal, sys, threading, time, types, warnings
from lightcuts import cli

def noise():
    while True:
        print("a thread's error", file=sys.stderr, flush=True)
        os.write(2, b"a C library's line\\n")
        logging.getLogger("distributed.scheduler").critical("Closed comm")
        warnings.warn("a warning")
        time.sleep(0.001)

def interrupt():  # a cluster's end that makes the other threads report failures, and takes too long
    threading.Thread(target=noise, daemon=True).start()
    time.sleep(float(sys.argv[1]))

sys.modules["lightcuts.distributed.session"] = types.SimpleNamespace(interrupt=interrupt)
logging.basicConfig()
signal.signal(signal.SIGINT, cli._on_signal)
print("ready", flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("hang", [0.3, 30.0])
def test_the_handler_prints_its_line_alone_and_ends_in_time(tmp_path, hang):
    """Whatever the other threads write to stderr (print, a C library, Dask's loggers, warnings) once
    the handler runs is not seen, and the process ends within cli.END_WITHIN even if ending the
    cluster hangs."""
    from lightcuts.cli import END_WITHIN

    script = tmp_path / "noisy.py"
    script.write_text(_NOISY)
    p = subprocess.Popen([sys.executable, str(script), str(hang)], env=dict(os.environ, PYTHONPATH=str(ROOT)),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert p.stdout.readline() == "ready\n"
    t0 = time.perf_counter()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    seconds = time.perf_counter() - t0
    assert p.returncode == 130 and err == "error: interrupted\n", err[:500]
    assert seconds < min(hang, END_WITHIN) + 0.5, seconds


#: (worker count, interrupts): 2 workers (the moments fall on Python and Dask starting, the workers
#: starting, the scene, lights and trees, the shipping, the tiles) and 16, the most a 2-core machine
#: starts (the moments fall mostly on the workers starting, the costliest stage to stop).
TRIALS = [(2, 5), (16, 5)]


@pytest.mark.slow
@pytest.mark.parametrize("workers, n", TRIALS)
def test_interrupts_at_random_moments_end_the_command_alone(tmp_path, workers, n):
    """Seeded moments between 0 and 10 s, SIGINT to the process group (Ctrl-C) or SIGTERM to the
    command: exit within 2 s with status 130 / 143, the one line on stderr, no process left
    (benchmarks/bench_interrupts.py runs more)."""
    from lightcuts.distributed.options import max_local_workers

    workers = min(workers, max_local_workers()[0])  # a smaller machine: the most it starts
    bench = _bench()
    moments = np.random.default_rng(workers).uniform(0.0, 10.0, n)
    for i, at in enumerate(moments):
        signum = signal.SIGTERM if i % 3 == 2 else signal.SIGINT
        r = bench.trial(workers, float(at), signum, folder=str(tmp_path), settle=0.0)
        where = f"--workers {workers}, {r['signal']} at {at:.2f} s"
        assert not r["finished"], f"{where}: the run ended before the signal; make it longer"
        assert r["ok_stderr"], (where, r["returncode"], r["stderr"])
        assert r["exit_seconds"] < 2.0 and r["left"] == [], (where, r["exit_seconds"], r["left"])
