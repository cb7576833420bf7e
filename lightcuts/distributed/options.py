"""The cluster flags of ``render``, ``compare`` and ``scaling``, checked before any work.

``--workers N`` starts a LocalCluster of N worker processes on this machine for the run (at most
what the machine can start: :func:`max_local_workers`);
``--scheduler ADDRESS`` connects to a running cluster (``tcp://host:8786``; ``tls://host:8786`` with
``--tls-ca``, ``--tls-cert`` and ``--tls-key``, the files of ``distributed.security.Security``);
``--connect-timeout`` bounds the wait for the scheduler and its first worker. ``render`` adds
``--tile-size``. This module imports no Dask: a run without the flags never loads ``distributed``.
"""

from __future__ import annotations

import importlib.util
import math
import os
from dataclasses import dataclass

from lightcuts.errors import LightcutsError

#: Seconds to reach the scheduler (and for its first worker) before giving up.
DEFAULT_CONNECT_TIMEOUT = 10.0
#: Side of a square image tile, pixels: every tile is a task (about 2 ms of the scheduler's time) and
#: the last tiles leave workers idle; 128 was the fastest on one machine, 32 in the model of 64
#: machines and more (docs/performance.md, "Distributed renders").
DEFAULT_TILE_SIZE = 128
#: The largest tile side the flags take.
MAX_TILE_SIZE = 8192
#: The most worker processes ``--workers`` starts on any machine.
MAX_WORKERS = 1024
#: The most worker processes per core of this machine: a worker takes about a CPU-second to start
#: (Python, Dask, lightcuts and its render kernel), so 8 per core keep the start within about 8 s
#: (docs/performance.md, "Interrupts"); more workers than cores only share the cores.
WORKERS_PER_CORE = 8
#: Memory a worker process holds before any run's inputs, bytes (about 210 MB measured with the
#: render kernel loaded): ``--workers`` takes at most the available memory over this.
WORKER_MEMORY = 256 * 2**20
#: The address schemes a scheduler may have.
SCHEMES = ("tcp", "tls")


@dataclass(frozen=True)
class ClusterSpec:
    """What the flags ask for: ``workers`` (a LocalCluster of that many processes) or ``scheduler``
    (the address as given); ``tls``: (CA, certificate, key) file paths or None; ``connect_timeout``:
    seconds; ``tile_size``: pixels (render only)."""

    workers: int | None = None
    scheduler: str | None = None
    tls: tuple[str, str, str] | None = None
    connect_timeout: float = DEFAULT_CONNECT_TIMEOUT
    tile_size: int = DEFAULT_TILE_SIZE

    @property
    def given(self) -> str:
        """The cluster as the user named it: ``--workers N`` or the scheduler's address."""
        return f"--workers {self.workers}" if self.workers is not None else str(self.scheduler)


def add_cluster_options(p, tiles: bool = False) -> None:
    """Add the cluster flags to a command's parser (``tiles``: also ``--tile-size``)."""
    g = p.add_argument_group("Dask cluster (pip install 'lightcuts[distributed]')")
    g.add_argument("--workers", type=str, default=None, metavar="N",
                   help=f"start a Dask LocalCluster of N worker processes on this machine for the run (at most "
                        f"{WORKERS_PER_CORE} per core)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the Dask cluster of this scheduler (tcp://host:8786, or tls://... with the TLS files)")
    g.add_argument("--tls-ca", default=None, metavar="FILE", help="with a tls:// scheduler: the CA certificate")
    g.add_argument("--tls-cert", default=None, metavar="FILE", help="with a tls:// scheduler: this client's certificate")
    g.add_argument("--tls-key", default=None, metavar="FILE", help="with a tls:// scheduler: this client's private key")
    g.add_argument("--connect-timeout", type=str, default=None, metavar="SECONDS",
                   help=f"give up on the scheduler after this long (default {DEFAULT_CONNECT_TIMEOUT:g})")
    if tiles:
        g.add_argument("--tile-size", type=str, default=None, metavar="PIXELS",
                       help=f"side of the square image tiles sent to the workers (default {DEFAULT_TILE_SIZE})")


def _integer(text, flag: str, lo: int, hi: int) -> int:
    try:
        value = int(str(text).strip())
    except ValueError:
        value = None
    if value is None or not lo <= value <= hi:
        raise LightcutsError(f"{flag} {text!r}: expected an integer from {lo} to {hi}")
    return value


def cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def max_local_workers() -> tuple[int, str]:
    """(the most worker processes a LocalCluster of this machine starts, why): :data:`WORKERS_PER_CORE`
    per core, at most the available memory over :data:`WORKER_MEMORY`, at most :data:`MAX_WORKERS`."""
    n_cores = cores()
    limit = min(MAX_WORKERS, WORKERS_PER_CORE * n_cores)
    why = f"{WORKERS_PER_CORE} per core on {n_cores} core{'s' if n_cores > 1 else ''}"
    try:
        import psutil

        available = psutil.virtual_memory().available
    except (ImportError, OSError):
        return limit, why
    by_memory = max(1, int(available // WORKER_MEMORY))
    if by_memory < limit:
        limit = by_memory
        why = f"{WORKER_MEMORY // 2**20} MB each in the {available / 2**30:.1f} GB of memory available"
    return limit, why


def check_address(address: str) -> str:
    """The scheduler address as given if it reads ``[tcp|tls://]host:port``; LightcutsError naming
    ``--scheduler`` otherwise."""
    text = str(address).strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, _, port = rest.rpartition(":")
    if scheme not in SCHEMES or not host or not port.isdigit() or not 0 < int(port) < 65536 or "/" in rest:
        raise LightcutsError(f"--scheduler {address!r}: expected tcp://HOST:PORT or tls://HOST:PORT "
                             "(the address `dask scheduler` prints)")
    return text


def cluster_spec(args) -> ClusterSpec | None:
    """The ClusterSpec of a command's parsed flags, or None without ``--workers`` / ``--scheduler``
    (the run stays on this machine). LightcutsError naming the flag for a bad value, a contradiction,
    a missing TLS file or a missing ``distributed`` package, before any work."""
    workers = getattr(args, "workers", None)
    scheduler = getattr(args, "scheduler", None)
    tls_files = {"--tls-ca": getattr(args, "tls_ca", None), "--tls-cert": getattr(args, "tls_cert", None),
                 "--tls-key": getattr(args, "tls_key", None)}
    timeout_text = getattr(args, "connect_timeout", None)
    tile_text = getattr(args, "tile_size", None)
    if workers is None and scheduler is None:
        given = [f for f, v in {**tls_files, "--connect-timeout": timeout_text, "--tile-size": tile_text}.items()
                 if v is not None]
        if given:
            raise LightcutsError(f"{given[0]}: only with --workers or --scheduler (a run on a Dask cluster)")
        return None
    if workers is not None and scheduler is not None:
        raise LightcutsError("--workers: not with --scheduler (one starts a cluster on this machine, the other "
                             "connects to a running one)")
    n = _integer(workers, "--workers", 1, MAX_WORKERS) if workers is not None else None
    if n is not None:
        limit, why = max_local_workers()
        if n > limit:
            raise LightcutsError(f"--workers {n}: this machine starts at most {limit} worker processes ({why}); "
                                 "for more, start a cluster of several machines and use --scheduler")
    timeout = DEFAULT_CONNECT_TIMEOUT
    if timeout_text is not None:
        try:
            timeout = float(timeout_text)
        except ValueError:
            timeout = math.nan
        if not (math.isfinite(timeout) and 0 < timeout <= 3600):
            raise LightcutsError(f"--connect-timeout {timeout_text!r}: expected seconds, more than 0 and at most 3600")
    tile = _integer(tile_text, "--tile-size", 1, MAX_TILE_SIZE) if tile_text is not None else DEFAULT_TILE_SIZE
    tls = None
    if scheduler is not None:
        address = check_address(scheduler)
        given = [f for f, v in tls_files.items() if v is not None]
        if address.startswith("tls://"):
            if len(given) != 3:
                missing = [f for f in tls_files if f not in given]
                raise LightcutsError(f"--scheduler {address!r}: a tls:// scheduler needs {', '.join(missing)} "
                                     "(--tls-ca, --tls-cert and --tls-key together)")
            for flag, path in tls_files.items():
                if not os.path.isfile(path):
                    raise LightcutsError(f"{flag} {path!r}: no such file")
            tls = tuple(tls_files.values())
        elif given:
            raise LightcutsError(f"{given[0]}: the TLS files need a tls:// scheduler address, got {address!r}")
    else:
        address = None
        given = [f for f, v in tls_files.items() if v is not None]
        if given:
            raise LightcutsError(f"{given[0]}: only with --scheduler tls://... (--workers starts its own cluster)")
    if importlib.util.find_spec("distributed") is None:
        flag = "--workers" if n is not None else "--scheduler"
        raise LightcutsError(f"{flag}: Dask distributed is not installed; install it with: "
                             "pip install 'lightcuts[distributed]'")
    return ClusterSpec(workers=n, scheduler=address, tls=tls, connect_timeout=timeout, tile_size=tile)
