"""Name -> object registries (builders, metrics, ray casters), extensible from outside.

Like Mitsuba's plugins: a decorated function per entry, resolved by name in exactly one place,
with an error that lists the valid names. Third-party packages add entries through an entry-point
group (e.g. ``lightcuts.builders``), loaded the first time a name is looked up.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Generic, TypeVar

from lightcuts.errors import LightcutsError

T = TypeVar("T")


class Registry(Generic[T]):
    """A dict of name -> entry with aliases, a ``register`` decorator and entry-point loading.

    Parameters
    ----------
    kind : str
        What the entries are, for messages ("builder", "metric", "ray caster").
    group : str, optional
        Entry-point group scanned once for outside registrations; each entry point names the
        object to register under the entry point's name.
    """

    def __init__(self, kind: str, group: str | None = None):
        self.kind = kind
        self.group = group
        self._entries: dict[str, T] = {}
        self._aliases: dict[str, str] = {}
        self._loaded_entry_points = group is None

    def register(self, name: str, obj: T | None = None, *, aliases: tuple[str, ...] = (),
                 replace: bool = False):
        """Register ``obj`` under ``name``; used bare as a decorator when ``obj`` is omitted."""

        def add(o: T) -> T:
            if not replace and (name in self._entries or name in self._aliases):
                raise LightcutsError(f"{self.kind} {name!r} is already registered")
            self._entries[name] = o
            for a in aliases:
                self._aliases[a] = name
            return o

        if obj is not None:
            return add(obj)
        return add

    def _load_entry_points(self) -> None:
        if self._loaded_entry_points:
            return
        self._loaded_entry_points = True
        for ep in entry_points(group=self.group):
            if ep.name in self._entries:
                continue
            try:
                obj = ep.load()
            except Exception as exc:  # a broken plugin must not hide the built-in entries
                raise LightcutsError(f"entry point {ep.name!r} in group {self.group!r} failed to load: {exc}")
            self._entries[ep.name] = obj

    def names(self) -> list[str]:
        """Sorted names of all entries (built-in and from entry points)."""
        self._load_entry_points()
        return sorted(self._entries)

    def get(self, name: str) -> T:
        """The entry registered as ``name`` (or an alias); LightcutsError listing valid names if none."""
        if name in self._aliases:
            name = self._aliases[name]
        if name not in self._entries:
            self._load_entry_points()
        if name not in self._entries:
            raise LightcutsError(
                f"unknown {self.kind} {name!r}; valid: {', '.join(self.names())}")
        return self._entries[name]

    def __contains__(self, name: str) -> bool:
        try:
            self.get(name)
        except LightcutsError:
            return False
        return True

