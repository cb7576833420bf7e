"""The processes this process starts for a LocalCluster, started deaf to Ctrl-C and ended together.

Dask's nannies start each worker process with multiprocessing's ``spawn`` (fork and exec of a fresh
interpreter), and multiprocessing starts its resource tracker the same way: both go through
``multiprocessing.util.spawnv_passfds``, which :func:`install` wraps (once per process) so that

- the child starts with SIGINT and SIGTERM blocked (a blocked signal stays blocked across fork and
  exec; CPython starts its resource tracker so). Ctrl-C in a terminal reaches the whole process
  group: a worker that took it would die on its own (mid-start printing a traceback, at work closing
  its connections under the run, which then reports its cluster lost) before the command's handler
  ends the run. Only the command takes the signal, and it ends its workers (:func:`end_all`);
- the child is recorded (a ``psutil.Process``, so that a pid the system reused is never signalled);
- once :func:`end_all` has begun, no process starts (OSError), so a start racing the end leaves none.

The nannies' queues hold named semaphores (files in ``/dev/shm``), which a normal exit unlinks and
an exit by ``os._exit`` does not: :func:`install` also wraps their creation, which :func:`end_all`
refuses from its start (a nanny whose worker was killed would make new ones to start another), and
:func:`end_all` unlinks those made before.

A worker whose parent dies without :func:`end_all` (SIGKILL) still ends: Dask's worker processes
exit when the pipe their parent holds closes.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time

#: The signals a started process is deaf to.
DEAF = {signal.SIGINT, signal.SIGTERM}

_LOCK = threading.Lock()
_STARTED: list = []  # psutil.Process of every process started through the wrapper
_state = {"spawn": None, "semlock": None, "ended": False, "busy": 0}


def install() -> None:
    """Wrap multiprocessing's process start and semaphore creation (idempotent)."""
    import multiprocessing.synchronize as synchronize
    import multiprocessing.util as util

    with _LOCK:
        if _state["spawn"] is None:
            _state["spawn"], util.spawnv_passfds = util.spawnv_passfds, _spawnv_passfds
            _state["semlock"], synchronize.SemLock.__init__ = synchronize.SemLock.__init__, _semlock_init


@contextlib.contextmanager
def _admitted(what: str):
    """The block, unless :func:`end_all` has begun (OSError); end_all waits for the blocks under way."""
    with _LOCK:
        if _state["ended"]:
            raise OSError(f"the command is ending: no new {what}")
        _state["busy"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _state["busy"] -= 1


def _spawnv_passfds(path, args, passfds):
    """multiprocessing's ``spawnv_passfds``: the child deaf to :data:`DEAF` and recorded."""
    import psutil

    with _admitted("process"):
        old = signal.pthread_sigmask(signal.SIG_BLOCK, DEAF)
        try:
            pid = _state["spawn"](path, args, passfds)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        with contextlib.suppress(psutil.Error):
            _STARTED.append(psutil.Process(pid))
        return pid


def _semlock_init(self, *args, **kwargs):
    """multiprocessing's ``SemLock.__init__``, refused once :func:`end_all` has begun."""
    with _admitted("semaphore"):
        _state["semlock"](self, *args, **kwargs)


def started() -> list[int]:
    """The pids of the recorded processes still running (zombies excluded)."""
    return [p.pid for p in _running(list(_STARTED))]


def _running(procs, reap: bool = False) -> list:
    """Those of ``procs`` still running; with ``reap``, those that ended are reaped (they are this
    process's children: none is left behind as a zombie)."""
    import psutil

    out = []
    for p in procs:
        with contextlib.suppress(psutil.Error):
            if not p.is_running():
                continue
            if p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
            elif reap:
                with contextlib.suppress(OSError):
                    os.waitpid(p.pid, os.WNOHANG)
    return out


def end_all(wait: float = 1.0) -> None:
    """End every recorded process (SIGKILL: a LocalCluster's workers hold nothing of the run worth
    saving) and refuse new processes and semaphores, for a process about to exit (the CLI's signal
    handler); returns when none is running or after about ``wait`` seconds. The process's named
    semaphores are unlinked, as its normal exit would, and its resource tracker (which would warn
    about them) is killed with the workers."""
    import psutil

    deadline = time.monotonic() + wait
    with _LOCK:
        _state["ended"] = True
    while _state["busy"] and time.monotonic() < deadline - wait / 2:  # starts under way: recorded first
        time.sleep(0.001)
    procs = list(_STARTED)
    _forget_tracker(wait / 4)
    for p in procs:
        with contextlib.suppress(psutil.Error):
            p.kill()
    _unlink_semaphores()
    while _running(procs, reap=True) and time.monotonic() < deadline:
        time.sleep(0.005)
    _running(procs, reap=True)


def _forget_tracker(wait: float) -> None:
    """Make this process treat multiprocessing's resource tracker (a recorded process, which
    :func:`end_all` kills) as never started: nothing later writes to it or warns that it died."""
    with contextlib.suppress(Exception):
        from multiprocessing import resource_tracker

        rt = resource_tracker._resource_tracker
        if rt._lock.acquire(timeout=wait):
            try:
                fd, rt._fd, rt._pid = rt._fd, None, None
            finally:
                rt._lock.release()
            if fd is not None:
                os.close(fd)


def _unlink_semaphores() -> None:
    """Unlink the names of this process's named multiprocessing semaphores, as their finalizers do
    at a normal exit (which would also tell the resource tracker, ended here)."""
    with contextlib.suppress(Exception):
        import multiprocessing.synchronize as synchronize
        import multiprocessing.util as util
        from _multiprocessing import sem_unlink

        for key in list(util._finalizer_registry):
            finalizer = util._finalizer_registry.get(key)
            if finalizer is not None and getattr(finalizer, "_callback", None) is synchronize.SemLock._cleanup:
                with contextlib.suppress(Exception):
                    name = finalizer._args[0]
                    finalizer.cancel()
                    sem_unlink(name)
