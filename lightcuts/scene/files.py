"""Files a scene reads (meshes, material libraries, textures, glTF buffers): checked to be readable
regular files before anything opens them, so a folder, a device or a pipe is named for what it is
(and a pipe never blocks the read)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from lightcuts.errors import LightcutsError


def regular_file(path, where: str) -> Path:
    """``path`` as a Path if it is a readable regular file (after symlinks); else LightcutsError
    ``<where>: <problem>``: no such file, a folder, not a regular file, permission denied."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise LightcutsError(f"{where}: no such file") from None
    except OSError as exc:
        raise LightcutsError(f"{where}: cannot read file ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise LightcutsError(f"{where}: is a folder, not a file")
    if not stat.S_ISREG(mode):
        raise LightcutsError(f"{where}: not a regular file (a device, a pipe or a socket)")
    if not os.access(path, os.R_OK):
        raise LightcutsError(f"{where}: cannot read file (permission denied)")
    return path
