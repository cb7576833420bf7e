"""The row store of ``lightcuts compare``: finished rows, the reference and the long Mitsuba render
kept as one ``.npz`` each, so that an interrupted compare keeps them and the next run only computes
what is missing or changed.

Each file holds the arrays of its result and a ``key``: a hash of everything the result depends on
(the config's shared part, the builder, metric and c, the pixel sample, the version). A file whose
key differs, or that cannot be read, counts as absent. Files are written atomically.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError


def store_key(**parts) -> str:
    """32 hex digits of the SHA-256 of ``parts`` as sorted JSON (non-JSON values by ``str``)."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:32]


def shared_config(cfg) -> dict:
    """Everything of the config that the scene, lights, reference and images depend on (all but the
    tree and the name), with the config's folder made absolute."""
    data = cfg.model_dump(mode="json")
    data.pop("tree", None)
    data.pop("name", None)
    data["base_dir"] = str(Path(cfg.base_dir).resolve())
    return data


class RowStore:
    """The ``.npz`` files of a folder (``None``: a store that keeps nothing, every lookup a miss).

    force : every lookup a miss (the results are computed again and stored over the old ones)
    """

    def __init__(self, folder: str | Path | None, force: bool = False):
        self.folder = None if folder is None else Path(folder)
        self.force = force

    def load(self, name: str, key: str) -> dict | None:
        """The arrays of ``<name>.npz`` if its key is ``key``, else None."""
        from lightcuts.io import read_npz

        if self.folder is None or self.force:
            return None
        path = self.folder / f"{name}.npz"
        if not path.is_file():
            return None
        try:
            z = read_npz(path, "compare row")
        except LightcutsError:
            return None
        return z if str(z.get("key")) == key else None

    def save(self, name: str, key: str, **arrays) -> None:
        """Write ``<name>.npz`` with ``key`` and ``arrays`` (nothing without a folder)."""
        from lightcuts.io import save_npz

        if self.folder is None:
            return
        self.folder.mkdir(parents=True, exist_ok=True)
        save_npz(self.folder / f"{name}.npz", key=np.array(key), **arrays)
