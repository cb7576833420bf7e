"""Atomic output: write to a temporary name in the target folder, then rename; a run's set of
files is written into a temporary folder that replaces the output folder as a whole.

A reader never sees a half-written file or a mix of two runs' files; an interrupted or failed run
leaves no partial output and no temporary behind.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import threading
from pathlib import Path
from typing import Iterator

import numpy as np

from lightcuts.errors import LightcutsError

#: The files a run may write into its output folder: a folder holding anything else is not
#: replaced (an ``--out`` naming a folder of the user's is refused before any work).
OUTPUT_FILES = frozenset({"image.exr", "image.png", "cutsize.png", "report.json", "report.html", "reference.exr",
                          "reference.png", "scaling.csv", "scaling.png", "render_scaling.csv", "render_scaling.png",
                          "gather_scaling.csv", "gather_scaling.png",
                          "compare", "accel", "reference", "mitsuba.exr", "mitsuba.png", "lightcuts.exr",
                          "lightcuts.png", "curve.csv", "curve.png", "split.csv", "path.exr", "path.png"})
#: Sub-folders of a render's folder that belong to other commands (``lightcuts compare`` writes
#: ``renders/<name>/compare/``, ``lightcuts reference`` ``renders/<name>/reference/``): a render's
#: output set carries them over instead of deleting them.
SUBRUN_FOLDERS = ("compare", "accel", "reference")

# Temporary files and folders of this process, removed by remove_temporaries (the signal handler
# of lightcuts.cli). The lock makes creating a temporary, or swapping an output set into place, and
# that removal exclude each other: an interrupt sees either the old set or the new one.
_LOCK = threading.RLock()
_TEMPORARIES: set[Path] = set()


def _temp_name(path: Path, tag: str) -> Path:
    return path.with_name(f".{path.name}.{tag}-{secrets.token_hex(4)}")


def remove_temporaries() -> None:
    """Remove every temporary file and folder this process has open; takes the lock and keeps it,
    for a caller that ends the process next (no temporary is made after this)."""
    _LOCK.acquire()
    for p in list(_TEMPORARIES):
        _remove(p)
    _TEMPORARIES.clear()


def _remove(p: Path) -> None:
    for _ in range(3):
        try:
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink(missing_ok=True)
            return
        except OSError:
            continue


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` when the block succeeds.

    ``suffix`` keeps the extension that some writers look at (``.png``, ``.exr``); defaults to the
    target's own suffix. The temporary is created empty with mode 0666 less the umask, like any
    new file, and removed if the block fails or the process is interrupted.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = suffix if suffix is not None else path.suffix
    with _LOCK:
        while True:
            tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}{suffix}")
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                break
            except FileExistsError:
                continue
        _TEMPORARIES.add(tmp)
    try:
        yield tmp
        with _LOCK:
            os.replace(tmp, path)
            _TEMPORARIES.discard(tmp)
    finally:
        with _LOCK:
            if tmp in _TEMPORARIES:
                _remove(tmp)
                _TEMPORARIES.discard(tmp)


def as_path(value, key: str) -> Path:
    """``value`` as a Path; LightcutsError naming ``key`` unless it is a str or os.PathLike naming a
    path (not empty, no NUL character, encodable as a file name: a lone surrogate is not)."""
    if not isinstance(value, (str, os.PathLike)):
        raise LightcutsError(f"{key} {value!r}: expected a path (str or os.PathLike), got {type(value).__name__}")
    try:
        text = os.fspath(value)
    except TypeError as exc:
        raise LightcutsError(f"{key} {value!r}: expected a path ({one_line(exc)})") from None
    if not isinstance(text, str) or not text or "\0" in text:
        raise LightcutsError(f"{key} {value!r}: expected a path (a non-empty text without NUL characters)")
    try:
        os.fsencode(text)
    except UnicodeError as exc:
        raise LightcutsError(f"{key} {value!r}: not a file name this system can encode ({exc.reason})") from None
    return Path(text)


@contextlib.contextmanager
def _path_errors(key: str, path: Path) -> Iterator[None]:
    """An OSError of a check (a name too long, a folder that cannot be listed) as one line naming
    ``key`` and ``path``."""
    try:
        yield
    except OSError as exc:
        raise LightcutsError(f"{key} {str(path)!r}: {exc.strerror or one_line(exc)}") from None


def run_dir(name: str, overrides=()) -> Path:
    """The default output folder of a run: ``renders/<name>``, or with ``--set`` overrides
    ``renders/<name>-set-<8 hex digits>`` (a hash of the overrides as given, in order), so a run
    with overrides never replaces the config's own run, and the same overrides reuse their folder."""
    if not overrides:
        return Path("renders") / name
    import hashlib

    digest = hashlib.sha256("\n".join(str(o).strip() for o in overrides).encode()).hexdigest()[:8]
    return Path("renders") / f"{name}-set-{digest}"


def check_output_dir(path: str | os.PathLike, key: str, allowed=OUTPUT_FILES) -> Path:
    """LightcutsError naming ``key`` unless ``path`` can become a run's output folder: it is a
    folder holding only ``allowed`` names (shell patterns; default OUTPUT_FILES), or it can be
    created, and a folder can be made beside it (:func:`output_set` makes the new set there), which
    :func:`probe_writable` proves before any work, so that a run does not fail at its end."""
    import fnmatch

    path = as_path(path, key)
    with _path_errors(key, path):
        if path.exists() or path.is_symlink():
            if not path.is_dir():
                raise LightcutsError(f"{key} {str(path)!r}: exists and is not a folder")
            other = sorted(p.name for p in path.iterdir()
                           if not any(fnmatch.fnmatchcase(p.name, a) for a in allowed))
            if other:
                raise LightcutsError(f"{key} {str(path)!r}: the folder holds files that are not a run's outputs "
                                     f"({', '.join(other[:3])}{', ...' if len(other) > 3 else ''}); "
                                     "give a new or empty folder")
        probe_writable(path.absolute().parent, key, path, folder_entry=True)
    return path


def check_output_file(path: str | os.PathLike, key: str) -> Path:
    """LightcutsError naming ``key`` unless a file can be written at ``path``: not a folder nor a
    device or other special file (the atomic write would replace it), and a file can be made in its
    folder, or the folder created (:func:`probe_writable`)."""
    path = as_path(path, key)
    with _path_errors(key, path):
        if path.is_dir():
            raise LightcutsError(f"{key} {str(path)!r}: is a folder")
        if path.exists() and not path.is_file():
            raise LightcutsError(f"{key} {str(path)!r}: exists and is not a regular file")
        probe_writable(path.absolute().parent, key, path)
    return path


def check_store_dir(path: str | os.PathLike, key: str) -> Path:
    """LightcutsError naming ``key`` unless ``path`` is, or can be made, a folder that files can be
    written into (a store filled as a run goes, :class:`lightcuts.report.compare_store.RowStore`)."""
    path = as_path(path, key)
    with _path_errors(key, path):
        if (path.exists() or path.is_symlink()) and not path.is_dir():
            raise LightcutsError(f"{key} {str(path)!r}: exists and is not a folder")
        probe_writable(path.absolute(), key, path)
    return path


def probe_writable(folder: Path, key: str, target: Path, folder_entry: bool = False) -> None:
    """Prove that ``folder`` is, or can be made, a folder that takes a new entry, by making one and
    removing it: a temporary file (``folder_entry``: a folder, as :func:`output_set` makes) in
    ``folder`` itself when it exists, else a temporary folder in its nearest existing ancestor, as
    ``mkdir -p`` would begin. Permissions alone do not tell: root passes every permission check, yet
    cannot write in /proc or on a read-only mount. LightcutsError naming ``key`` and ``target``
    otherwise; nothing is left behind either way."""
    p = folder
    while not (p.exists() or p.is_symlink()):
        p = p.parent
    if not p.is_dir():
        raise LightcutsError(f"{key} {str(target)!r}: {str(p)!r} is not a folder")
    make_folder = folder_entry or p != folder
    with _LOCK:
        probe = p / f".lightcuts-probe-{secrets.token_hex(4)}"
        try:
            if make_folder:
                os.mkdir(probe, 0o700)
            else:
                os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except OSError as exc:
            raise LightcutsError(f"{key} {str(target)!r}: cannot write in {str(p)!r} (a new entry there failed: "
                                 f"{exc.strerror or one_line(exc)})") from None
        _TEMPORARIES.add(probe)
        try:
            if make_folder:
                os.rmdir(probe)
            else:
                os.unlink(probe)
        except OSError as exc:
            _remove(probe)
            raise LightcutsError(f"{key} {str(target)!r}: cannot remove a new entry of {str(p)!r} "
                                 f"({exc.strerror or one_line(exc)})") from None
        finally:
            _TEMPORARIES.discard(probe)


@contextlib.contextmanager
def output_set(path: str | os.PathLike, keep=()) -> Iterator[Path]:
    """Yield a temporary folder beside the output folder ``path``; when the block succeeds, it
    replaces ``path`` as a whole (the old folder is renamed away, the new one renamed in, the old
    one removed), so ``path`` holds one run's complete files or the previous run's, untouched.
    Entries of the old folder named in ``keep`` that the new set lacks are moved into it first
    (e.g. another command's sub-folder). The temporary folder is removed if the block fails or the
    process is interrupted."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _LOCK:
        tmp = _temp_name(path, "new")
        os.mkdir(tmp, 0o777)
        _TEMPORARIES.add(tmp)
    try:
        yield tmp
        with _LOCK:
            old = None
            moved = []
            if path.exists():
                for name in keep:
                    if (path / name).exists() and not (tmp / name).exists():
                        os.rename(path / name, tmp / name)
                        moved.append(name)
                old = _temp_name(path, "old")
                os.rename(path, old)
            try:
                os.rename(tmp, path)
            except OSError:
                if old is not None:
                    os.rename(old, path)
                for name in moved:
                    os.rename(tmp / name, path / name)
                raise
            _TEMPORARIES.discard(tmp)
            if old is not None:
                _TEMPORARIES.add(old)
        if old is not None:
            with _LOCK:
                _remove(old)
                _TEMPORARIES.discard(old)
    finally:
        with _LOCK:
            if tmp in _TEMPORARIES:
                _remove(tmp)
                _TEMPORARIES.discard(tmp)


def read_npz(path: str | os.PathLike, what: str) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file ``path``, read now (nothing is unpickled); LightcutsError
    naming the file (and the key) if it is not a readable ``.npz`` of plain arrays. ``what`` names
    the kind of file in messages (``light``, ``tree``)."""
    path = Path(path)
    if not path.is_file():
        raise LightcutsError(f"{path}: no such {what} file")
    try:
        with open(path, "rb") as f:
            magic = f.read(6)
    except OSError as exc:
        raise LightcutsError(f"{path}: cannot read {what} file ({exc.strerror or exc})") from None
    if magic == b"\x93NUMPY":
        raise LightcutsError(f"{path}: not a .npz {what} file (a single .npy array)")
    if not magic.startswith(b"PK"):
        raise LightcutsError(f"{path}: not a .npz {what} file (not a zip archive)")
    try:
        z = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise LightcutsError(f"{path}: not a .npz {what} file ({one_line(exc)})") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise LightcutsError(f"{path}: not a .npz {what} file")
    out = {}
    with z:
        for k in z.files:
            try:
                out[k] = z[k]
            except Exception as exc:
                raise LightcutsError(f"{path}: {k}: cannot be read ({one_line(exc)})") from None
    for k, a in out.items():
        if a.dtype.kind not in "biufUS":
            raise LightcutsError(f"{path}: {k}: has dtype {a.dtype}; expected numbers or text")
    return out


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (at most 200 characters), for one-line errors."""
    text = str(exc).strip().splitlines()
    return text[0][:200] if text else type(exc).__name__


def save_npz(path: str | os.PathLike, **arrays) -> Path:
    """Write arrays to ``path`` (.npz, uncompressed) atomically."""
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
    return path


def save_json(path: str | os.PathLike, data) -> Path:
    """Write ``data`` as indented JSON atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
    return path


def save_csv(path: str | os.PathLike, rows: list[dict], fieldnames: list[str] | None = None) -> Path:
    """Write dict rows as CSV (header = ``fieldnames``, default the first row's keys) atomically."""
    import csv
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fieldnames or (list(rows[0]) if rows else []), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(buf.getvalue())
    return path
