"""Command line: ``lightcuts COMMAND ...``, one module per command in lightcuts.commands (their list:
``lightcuts.commands.COMMANDS``, which ``lightcuts --help`` shows).

User errors (LightcutsError) print one line ``error: ...`` and exit with status 2. Ctrl-C (SIGINT)
and SIGTERM print ``error: interrupted`` / ``error: terminated`` alone, remove the run's temporary
files, end a Dask LocalCluster's processes and exit with 130 / 143 within about a second: the
command runs on a worker thread while the main thread waits in short joins, so the signal handler
runs at once (the long numba kernels release the GIL), and a timer bounds what it does.
Heavy modules (numba kernels, colour, matplotlib) are imported inside the commands so that
``lightcuts --help`` stays fast.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading

from lightcuts.commands import COMMANDS
from lightcuts.errors import LightcutsError


def build_parser() -> argparse.ArgumentParser:
    from lightcuts import __version__

    ap = argparse.ArgumentParser(
        prog="lightcuts", description="Lightcuts rendering of scenes with many lights: "
        f"lightcuts {{{','.join(COMMANDS)}}} ...; lightcuts COMMAND --help for one command.")
    ap.add_argument("--version", action="version", version=f"lightcuts {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"lightcuts.commands.{name}").add_parser(sub)
    return ap


#: Exit status and message by signal.
_SIGNALS = {signal.SIGINT: (130, "interrupted"), signal.SIGTERM: (143, "terminated")}


def _run(args) -> int:
    from lightcuts.pipeline.warmup import announce_compiles

    announce_compiles()
    try:
        return args.func(args)
    except LightcutsError as exc:
        message = " ".join(str(exc).splitlines())  # one line, whatever a message quotes
        print(f"error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


#: Longest time from a signal's handler starting to the process's end, seconds.
END_WITHIN = 1.5
_ENDING = threading.Lock()


def _on_signal(signum, frame) -> None:
    """Print one line and end the process (worker threads included) within :data:`END_WITHIN`
    seconds: the process's own stderr silenced first (the threads still running, Dask's loggers and
    asyncio's would report the end as failures), the run's temporaries removed, a Dask cluster's
    processes ended and its tasks cancelled; a timer ends the process if that takes longer. A second
    signal meanwhile changes nothing."""
    for s in _SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    code, what = _SIGNALS[signum]
    stderr = os.dup(2)
    line = (f"\nerror: {what}\n" if os.isatty(stderr) else f"error: {what}\n").encode()
    timer = threading.Timer(END_WITHIN, _end, (stderr, line, code))
    timer.daemon = True
    timer.start()
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
        files = sys.modules.get("lightcuts.io")  # no temporaries before it is loaded
        if files is not None:
            with contextlib.suppress(Exception):
                files.remove_temporaries()
        sessions = sys.modules.get("lightcuts.distributed.session")  # loaded only by a run on a Dask cluster
        if sessions is not None:
            sessions.interrupt()
    finally:
        _end(stderr, line, code)


def _end(fd: int, line: bytes, code: int) -> None:
    """Write ``line`` to ``fd`` and end the process with ``code``, once (the handler or its timer)."""
    _ENDING.acquire()
    try:
        os.write(fd, line)
    finally:
        os._exit(code)


def main(argv: list[str] | None = None) -> int:
    if threading.current_thread() is not threading.main_thread():
        return _run(build_parser().parse_args(argv))  # signals reach only the main thread: nothing to wait for
    result = []
    before = {s: signal.signal(s, _on_signal) for s in _SIGNALS}  # from the start: parsing imports a while
    try:
        args = build_parser().parse_args(argv)

        def work():
            try:
                result.append((True, _run(args)))
            except BaseException as exc:  # re-raised on the calling thread
                result.append((False, exc))

        worker = threading.Thread(target=work, name="lightcuts-command", daemon=True)
        worker.start()
        while worker.is_alive():
            worker.join(0.05)
    finally:
        for s, h in before.items():
            signal.signal(s, h)
    ok, value = result[0]
    if not ok:
        raise value
    return value


if __name__ == "__main__":
    sys.exit(main())
