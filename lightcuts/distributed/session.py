"""A run's connection to a Dask cluster: a LocalCluster started for the run, or a Client of a running
scheduler, checked (reachable within the connect timeout, a worker present, the same versions of
lightcuts, numba, numpy and embreex on every worker) before any work, and closed whatever happens.

The sessions open in this process are listed, so that the CLI's signal handler can end them at once
(:func:`interrupt`) before it ends the process: an interrupted run leaves no task running on a
cluster and no process of its LocalCluster behind (:mod:`~lightcuts.distributed.processes`).
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
    local : whether the cluster is a LocalCluster started for the run (its processes this process's)
    timeout : seconds a run waits without any worker before it gives up (the connect timeout)

    :func:`local_cluster` starts its cluster on a thread, so that the client makes the scene, lights
    and trees meanwhile: ``client`` and ``cluster`` wait for it on first use.
    """

    def __init__(self, client=None, cluster=None, given: str = "", owned: bool = True, timeout: float = 10.0,
                 local: bool = False):
        self._client = client
        self._cluster = cluster
        self.timeout = float(timeout)
        self.given = given
        self.owned = owned
        self.local = local
        self.futures: list = []
        self.tokens: list[str] = []  # the runs whose state the workers keep (lightcuts.distributed.worker)
        self.warming: list = []  # warm_task futures, one per worker
        self.worker_pids: list[int] = []
        self._closed = False
        self._starting = None  # the thread starting a LocalCluster
        self._error = None
        with _OPEN_LOCK:
            _OPEN.append(self)

    def _start(self, start) -> None:
        """Run ``start()`` -> (client, cluster, worker pids) on a thread."""
        def run():
            try:
                self._client, self._cluster, self.worker_pids = start()
            except Exception as exc:  # raised on first use, one line
                self._error = LightcutsError(f"{self.given}: cannot start a Dask LocalCluster: {_one_line(exc)}")
            except BaseException as exc:
                self._error = exc

        self._starting = threading.Thread(target=run, name="lightcuts-cluster-start", daemon=True)
        self._starting.start()

    def _ready(self) -> None:
        starting = self._starting
        if starting is not None and starting is not threading.current_thread():
            starting.join()
            self._starting = None
        if self._error is not None:
            raise self._error

    @property
    def client(self):
        self._ready()
        return self._client

    @property
    def cluster(self):
        self._ready()
        return self._cluster

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

    def warm(self, kernels: str | None) -> None:
        """Import on every worker the modules its tasks unpickle into (:func:`import_modules`), then
        start loading the render kernel (module ``kernels``, None: none) on each (one task pinned to
        each), while the client makes the scene, lights and trees."""
        from lightcuts.distributed.worker import import_modules, warm_task

        self.client.run(import_modules, kernels)
        if kernels is None:
            return
        for i, addr in enumerate(self.workers()):
            self.warming += self.track([self.client.submit(warm_task, kernels, key=f"lightcuts-warm-{i}-{id(self)}",
                                                           workers=[addr], allow_other_workers=False)])

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
        if pending and self._client is not None:
            with contextlib.suppress(Exception):
                self._client.cancel(pending, force=True)

    def close(self, timeout: float = CLOSE_TIMEOUT) -> None:
        """Cancel the run's tasks, close the client (if owned) and the LocalCluster, and make sure
        none of its worker processes survives."""
        if self._closed:
            return
        self._closed = True
        with _OPEN_LOCK:
            if self in _OPEN:
                _OPEN.remove(self)
        if self._starting is not None:
            self._starting.join(timeout)
        self.cancel()
        if self.tokens and self._client is not None and self._cluster is None:  # a LocalCluster's workers end anyway
            from lightcuts.distributed.worker import drop_runs

            with contextlib.suppress(Exception):
                self._client.run(drop_runs, *self.tokens, on_error="ignore")
        if not self.owned:
            return
        if self._client is not None:
            with contextlib.suppress(Exception):
                self._client.close(timeout=timeout)
        _kill(self.worker_pids)  # a LocalCluster's workers hold nothing worth a graceful close (tenths of a second)
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close(timeout=timeout)


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


def interrupt(wait: float = 0.5) -> None:
    """What the CLI's signal handler calls before it ends the process, done within about
    ``2.5 * wait`` seconds: every process started for a LocalCluster killed (its scheduler and client
    live in this process and end with it; :func:`lightcuts.distributed.processes.end_all`), then, for
    at most ``wait`` seconds, the run's tasks on a running cluster cancelled and its workers told to
    forget the run (the scheduler would forget the tasks anyway once this process's connection closes)."""
    from lightcuts.distributed import processes

    processes.end_all(wait)
    with _OPEN_LOCK:
        remote = [s for s in _OPEN if not s.local and s._client is not None]

    def forget():
        for s in remote:
            s.cancel()
            if s.tokens:
                from lightcuts.distributed.worker import drop_runs

                with contextlib.suppress(Exception):
                    s._client.run(drop_runs, *s.tokens, on_error="ignore")

    if remote:
        thread = threading.Thread(target=forget, name="lightcuts-forget", daemon=True)
        thread.start()
        thread.join(wait)


def _quiet():
    """Dask's warnings and log lines about its own machinery (ports, versions, closing comms) off:
    the CLI's output stays its own one-line style. Importing ``distributed`` sets its loggers' levels
    from Dask's config, so it is imported first."""
    import distributed  # noqa: F401

    warnings.filterwarnings("ignore", module="distributed")
    for name in ("distributed", "distributed.client", "distributed.worker", "distributed.nanny",
                 "distributed.scheduler", "distributed.core", "distributed.comm"):
        logging.getLogger(name).setLevel(logging.ERROR)


def local_cluster(workers: int, threads: int | None = None, kernels: str | None = None) -> Session:
    """A Session of a LocalCluster of ``workers`` processes bound to 127.0.0.1 (its diagnostics server
    on a free port of 127.0.0.1), each with ``threads`` threads (default this machine's cores over the
    workers, at least 1), started on a thread; once up, its workers load the render kernel of the
    module ``kernels`` (:meth:`Session.warm`)."""
    import dask

    from lightcuts.distributed import processes

    _quiet()
    processes.install()  # the workers deaf to Ctrl-C, recorded, ended by interrupt()
    dask.config.set({"distributed.worker.multiprocessing-method": "spawn"})  # what processes.install wraps
    threads = threads or max(1, (os.cpu_count() or 1) // workers)
    session = Session(None, None, f"--workers {workers}", local=True)

    def start():
        from distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=workers, threads_per_worker=threads, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
        try:
            client = Client(cluster, set_as_default=False)
            pids = list(client.run(os.getpid).values())
        except BaseException:
            cluster.close()
            raise
        session._client, session._cluster, session.worker_pids = client, cluster, pids
        session.warm(kernels)
        return client, cluster, pids

    session._start(start)
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


def open_session(spec, kernels: str | None = None) -> Session:
    """The Session a :class:`~lightcuts.distributed.options.ClusterSpec` asks for, its workers loading
    the render kernel of the module ``kernels`` (None: none)."""
    if spec.workers is not None:
        return local_cluster(spec.workers, kernels=kernels)
    session = connect(spec.scheduler, spec.tls, spec.connect_timeout)
    session.warm(kernels)
    return session


@contextlib.contextmanager
def session_for(spec, kernels: str | None = None):
    """``with session_for(spec) as session:`` a Session (:func:`open_session`) closed at the end of the
    block, whatever ends it."""
    session = open_session(spec, kernels)
    try:
        yield session
    finally:
        session.close()


@contextlib.contextmanager
def cluster_session(cluster, kernels: str | None = None, key: str = "cluster"):
    """``with cluster_session(cluster) as session:`` the Session of the Python API's ``cluster``
    argument: a ``distributed.Client`` the caller owns (left open; the run's tasks and the workers'
    state of the run are dropped at the end) or a scheduler address (``tcp://host:port``, connected
    and closed here, as ``--scheduler``). Either needs a worker and this machine's versions on every
    worker. LightcutsError naming ``key`` for anything else, before any work."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        raise LightcutsError(f"{key}: Dask distributed is not installed; install it with: "
                             "pip install 'lightcuts[distributed]'")
    try:
        session = _given_session(cluster, key)
    except LightcutsError as exc:  # connect's and check_versions' lines name the CLI's flag
        raise LightcutsError(str(exc).replace("--scheduler", key, 1)) from None
    try:
        session.warm(kernels)
        yield session
    finally:
        session.close()


def _given_session(cluster, key: str) -> Session:
    """The Session of :func:`cluster_session`'s ``cluster`` (a Client or a scheduler address)."""
    from distributed import Client

    from lightcuts.distributed.options import DEFAULT_CONNECT_TIMEOUT, check_address

    if isinstance(cluster, str):
        return connect(check_address(cluster), None, DEFAULT_CONNECT_TIMEOUT)
    if not isinstance(cluster, Client):
        raise LightcutsError(f"{key} {cluster!r}: expected a distributed.Client or a scheduler address "
                             f"(tcp://HOST:PORT), got {type(cluster).__name__}")
    _quiet()
    if cluster.status != "running":
        raise LightcutsError(f"{key}: the Client is {cluster.status}, not running")
    address = cluster.scheduler.address
    session = Session(cluster, None, address, owned=False)
    try:
        if not session.workers():
            raise LightcutsError(f"{key}: the Client's cluster at {address} has no worker")
        check_versions(cluster, address)
    except BaseException:
        session.close()
        raise
    return session
