"""What the commands share: the ``--set`` option, per-type output names."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_set(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set render.eps=0.01 (repeatable)")


def per_type_path(out: Path, typ: str, n_types: int) -> Path:
    """``out`` itself for a single light type, else ``<stem>-<type>.npz`` beside it."""
    return out if n_types == 1 else out.with_name(f"{out.stem}-{typ}{out.suffix or '.npz'}")
