"""A run's connection to a Dask cluster: a LocalCluster started for the run, or a Client of a running
scheduler, checked (reachable within the connect timeout, a worker present, the same versions of
lightcuts, numba, numpy and embreex on every worker) before any work, and closed whatever happens.

The sessions open in this process are listed, so that the CLI's signal handler can cancel their
tasks and close them (:func:`close_all`) before it ends the process: an interrupted run leaves no
task running on a cluster and no worker process of its LocalCluster behind.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
import warnings

from lightcuts.errors import LightcutsError

#: Packages whose versions must be the same on the client and every worker (the kernels' code and
#: arithmetic), and Dask's own (the wire protocol).
SAME_VERSIONS = ("lightcuts", "numba", "numpy", "embreex", "dask", "distributed", "cloudpickle", "msgpack")
#: Longest wait when closing a cluster, seconds.
CLOSE_TIMEOUT = 5.0

_OPEN: list["Session"] = []
_OPEN_LOCK = threading.Lock()


class Session:
    """A Client (and the LocalCluster it owns, if any) for one run.

    client : distributed.Client; cluster : the LocalCluster started for the run, or None
    given : the cluster as the user named it (``--workers N`` or the scheduler address as typed)
    owned : whether the run closes the client (False for a Client the caller passed in)
    timeout : seconds a run waits without any worker before it gives up (the connect timeout)
    """

    def __init__(self, client, cluster=None, given: str = "", owned: bool = True, timeout: float = 10.0):
        self.client = client
        self.timeout = float(timeout)
        self.cluster = cluster
        self.given = given
        self.owned = owned
        self.futures: list = []
        self.worker_pids: list[int] = []
        self._closed = False
        with _OPEN_LOCK:
            _OPEN.append(self)

    @property
    def closed(self) -> bool:
        return self._closed

    def workers(self) -> dict:
        """Worker address -> number of threads, as the scheduler knows them now."""
        try:
            info = self.client.scheduler_info(n_workers=-1)  # newer Dask lists 5 workers unless asked
        except TypeError:
            info = self.client.scheduler_info()
        return {addr: int(w.get("nthreads", 1)) for addr, w in info.get("workers", {}).items()}

    def record(self) -> dict:
        """report.json's view of the cluster: the address as given, the scheduler, workers and threads."""
        workers = self.workers()
        return {"given": self.given, "scheduler": self.client.scheduler.address, "workers": len(workers),
                "threads": int(sum(workers.values())), "worker_addresses": sorted(workers)}

    def track(self, futures) -> list:
        """Remember futures, so that closing (or an interrupt) cancels them; returns them."""
        futures = list(futures)
        self.futures.extend(futures)
        return futures

    def cancel(self) -> None:
        """Cancel every tracked future still pending (on the cluster, not only here)."""
        pending = [f for f in self.futures if not f.done()]
        self.futures = []
        if pending:
            with contextlib.suppress(Exception):
                self.client.cancel(pending, force=True)

    def close(self, timeout: float = CLOSE_TIMEOUT) -> None:
        """Cancel the run's tasks, close the client (if owned) and the LocalCluster, and make sure
        none of its worker processes survives."""
        if self._closed:
            return
        self._closed = True
        with _OPEN_LOCK:
            if self in _OPEN:
                _OPEN.remove(self)
        self.cancel()
        if not self.owned:
            return
        with contextlib.suppress(Exception):
            self.client.close(timeout=timeout)
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close(timeout=timeout)
        _kill(self.worker_pids)


def _kill(pids) -> None:
    """Kill the processes still alive among ``pids`` (a LocalCluster's workers after its close)."""
    import psutil

    alive = []
    for pid in pids:
        with contextlib.suppress(psutil.Error):
            p = psutil.Process(pid)
            p.kill()
            alive.append(p)
    psutil.wait_procs(alive, timeout=2.0)


def close_all(timeout: float = 2.0) -> None:
    """Close every open session (the CLI's signal handler calls this before it ends the process)."""
    with _OPEN_LOCK:
        sessions = list(_OPEN)
    for s in sessions:
        s.close(timeout)


def _quiet():
    """Dask's warnings and log lines about its own machinery (ports, versions, closing comms) off:
    the CLI's output stays its own one-line style."""
    warnings.filterwarnings("ignore", module="distributed")
    for name in ("distributed", "distributed.client", "distributed.worker", "distributed.nanny",
                 "distributed.scheduler", "distributed.core", "distributed.comm"):
        logging.getLogger(name).setLevel(logging.ERROR)


def local_cluster(workers: int, threads: int | None = None) -> Session:
    """A LocalCluster of ``workers`` processes bound to 127.0.0.1, no dashboard, each with ``threads``
    threads (default this machine's cores over the workers, at least 1), and its Client."""
    import psutil
    from distributed import Client, LocalCluster

    _quiet()
    threads = threads or max(1, (os.cpu_count() or 1) // workers)
    before = {c.pid for c in psutil.Process().children(recursive=True)}
    cluster = LocalCluster(n_workers=workers, threads_per_worker=threads, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
    try:
        client = Client(cluster, set_as_default=False)
    except BaseException:
        cluster.close()
        raise
    session = Session(client, cluster, f"--workers {workers}")
    session.worker_pids = [c.pid for c in psutil.Process().children(recursive=True) if c.pid not in before]
    return session


def connect(address: str, tls=None, timeout: float = 10.0) -> Session:
    """A Client of the scheduler at ``address`` (TLS files ``tls`` = (CA, certificate, key)), with a
    worker present and the same versions everywhere; LightcutsError naming ``--scheduler`` within
    about ``timeout`` seconds when the scheduler cannot be reached, has no worker, or differs."""
    import asyncio

    from distributed import Client
    from distributed.comm import connect as comm_connect
    from distributed.security import Security

    _quiet()
    security = None
    if tls is not None:
        ca, cert, key = tls
        try:
            security = Security(tls_ca_file=ca, tls_client_cert=cert, tls_client_key=key, require_encryption=True)
            args = security.get_connection_args("client")
        except Exception as exc:  # unreadable or mismatched certificate files
            raise LightcutsError(f"--tls-ca/--tls-cert/--tls-key: cannot use the TLS files: {_one_line(exc)}") from None
    else:
        args = {}

    async def probe():
        comm = await comm_connect(address, timeout=timeout, **args)
        await comm.close()

    t0 = time.perf_counter()
    try:  # first a bare connection: a failed Client would linger and block the exit for seconds
        asyncio.run(asyncio.wait_for(probe(), timeout))
    except BaseException as exc:  # refused, timed out, not a scheduler, TLS handshake failed
        if isinstance(exc, KeyboardInterrupt):
            raise
        raise LightcutsError(f"--scheduler: cannot reach {address} within {timeout:g} s: {_one_line(exc)}") from None
    left = max(1.0, timeout - (time.perf_counter() - t0))
    try:
        client = Client(address, timeout=left, security=security, set_as_default=False)
    except Exception as exc:
        raise LightcutsError(f"--scheduler: cannot connect to {address}: {_one_line(exc)}") from None
    session = Session(client, None, address, timeout=timeout)
    try:
        try:
            client.wait_for_workers(1, timeout=max(1.0, timeout - (time.perf_counter() - t0)))
        except Exception:
            raise LightcutsError(f"--scheduler: no worker has joined {address} within {timeout:g} s; start one "
                                 f"with: dask worker {address}") from None
        check_versions(client, address)
    except BaseException:
        session.close()
        raise
    return session


def check_versions(client, address: str) -> None:
    """LightcutsError naming ``--scheduler`` unless every worker has this process's versions of
    :data:`SAME_VERSIONS` (Dask's own version report, ``client.get_versions``)."""
    versions = client.get_versions(packages=["lightcuts", "embreex"])
    mine = versions["client"]["packages"]
    for worker, info in sorted(versions["workers"].items()):
        theirs = (info or {}).get("packages", {}) if isinstance(info, dict) else {}
        for pkg in SAME_VERSIONS:
            if theirs.get(pkg) != mine.get(pkg):
                raise LightcutsError(f"--scheduler: worker {worker} of {address} has {pkg} {theirs.get(pkg) or 'missing'}, "
                                     f"this machine {mine.get(pkg)}; install the same version on every worker "
                                     f"(pip install {pkg}=={mine.get(pkg)})")


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) < 300 else text[:297] + "..."


def open_session(spec) -> Session:
    """The Session a :class:`~lightcuts.distributed.options.ClusterSpec` asks for."""
    if spec.workers is not None:
        return local_cluster(spec.workers)
    return connect(spec.scheduler, spec.tls, spec.connect_timeout)


@contextlib.contextmanager
def session_for(spec):
    """``with session_for(spec) as session:`` a Session closed at the end of the block, whatever ends it."""
    session = open_session(spec)
    try:
        yield session
    finally:
        session.close()
