"""Command line: ``lightcuts lights|tree|scaling|render CONFIG`` (one module each in lightcuts.commands).

User errors (LightcutsError) print one line ``error: ...`` and exit with status 2.
Heavy modules (numba kernels, colour, matplotlib) are imported inside the commands so that
``lightcuts --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from lightcuts.commands import COMMANDS
from lightcuts.errors import LightcutsError


def build_parser() -> argparse.ArgumentParser:
    from lightcuts import __version__

    ap = argparse.ArgumentParser(prog="lightcuts", description=__doc__.splitlines()[0])
    ap.add_argument("--version", action="version", version=f"lightcuts {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"lightcuts.commands.{name}").add_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except LightcutsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
