"""Plugins: a registry per kind (builders, metrics, ray casters), name -> :class:`Entry`.

An entry is the plugin's object (a builder function, a :class:`~lightcuts.trees.metrics.Metric`, a
caster class) plus what it declares, as a Mitsuba plugin declares its parameters: ``reads``, the run
parameters it uses (a builder: ``metric`` and/or ``c``), and ``traits``, kind-specific facts that the
plan step checks before any work (a caster: ``kernel_callable``; a builder: ``builtin_metrics_only``).

Built-in entries register themselves when their modules are imported; each registry names those
modules and imports them on its first lookup or listing, so ``names()`` is complete from the start.
Outside packages add entries through an entry-point group (e.g. ``lightcuts.builders``): the entry
point names the object, and :func:`declare` attached to it says what it reads (without it, the
object's own ``reads`` attribute if it has one, else the registry's ``default_reads``).
"""

from __future__ import annotations

import contextlib
import importlib
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from types import MappingProxyType
from typing import Any, Iterator, Mapping

from lightcuts.errors import LightcutsError

_DECLARATION = "__lightcuts_plugin__"


def declare(obj=None, *, reads: tuple[str, ...] = (), **traits):
    """Attach a plugin declaration (``reads``, ``traits``) to ``obj``; a decorator when ``obj`` is omitted.

    For objects named by entry points, which are registered without a call to ``register``.
    """

    def attach(o):
        setattr(o, _DECLARATION, {"reads": tuple(reads), "traits": dict(traits)})
        return o

    return attach if obj is None else attach(obj)


@dataclass(frozen=True)
class Entry:
    """One registered plugin: its name, object, the parameters it reads and its traits."""

    name: str
    obj: Any
    reads: frozenset[str] = frozenset()
    traits: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""

    def trait(self, key: str, default=None):
        return self.traits.get(key, default)


class Registry:
    """Name -> Entry, with aliases, built-in modules loaded on first use and entry-point loading.

    kind : what the entries are, for messages ("builder", "metric", "ray caster")
    group : entry-point group scanned once for outside registrations
    builtins : modules whose import registers the built-in entries
    params : every parameter an entry of this kind may declare in ``reads`` (checked at registration)
    default_reads : what an entry reads when it declares nothing (entry points without :func:`declare`)
    coerce : ``coerce(name, obj) -> obj`` applied to every object registered, so that lookups always
        return one type (e.g. a bare njit function becomes a Metric)
    """

    def __init__(self, kind: str, group: str | None = None, builtins: tuple[str, ...] = (),
                 params: tuple[str, ...] = (), default_reads: tuple[str, ...] = (), coerce=None):
        self.kind = kind
        self.group = group
        self.params = frozenset(params)
        self.default_reads = tuple(default_reads)
        self._coerce = coerce
        self._builtins = tuple(builtins)
        self._entries: dict[str, Entry] = {}
        self._aliases: dict[str, str] = {}
        self._loaded_builtins = not builtins
        self._loaded_entry_points = group is None

    def register(self, name: str, obj: Any = None, *, reads: tuple[str, ...] | None = None,
                 aliases: tuple[str, ...] = (), replace: bool = False, description: str | None = None,
                 **traits):
        """Register ``obj`` under ``name``; used bare as a decorator when ``obj`` is omitted.

        reads : the parameters the entry uses (default: its :func:`declare`, else ``default_reads``)
        traits : kind-specific declarations, e.g. ``kernel_callable=True`` for a caster
        """

        def add(o):
            self._add(name, o, reads, traits, aliases, replace, description)
            return o

        return add if obj is None else add(obj)

    def _add(self, name, obj, reads, traits, aliases, replace, description) -> Entry:
        declared = getattr(obj, _DECLARATION, None) or {}
        if self._coerce is not None:
            obj = self._coerce(name, obj)
        if reads is None:
            reads = declared.get("reads", getattr(obj, "reads", self.default_reads))
        traits = {**declared.get("traits", {}), **traits}
        unknown = set(reads) - self.params
        if unknown:
            raise LightcutsError(f"{self.kind} {name!r} declares unknown parameters {sorted(unknown)}; "
                                 f"valid: {', '.join(sorted(self.params)) or 'none'}")
        if not replace and (name in self._entries or name in self._aliases):
            raise LightcutsError(f"{self.kind} {name!r} is already registered")
        if description is None:
            description = (getattr(obj, "description", None) or (getattr(obj, "__doc__", None) or "")
                           .strip().split("\n")[0])
        entry = Entry(name, obj, frozenset(reads), MappingProxyType(dict(traits)), str(description))
        self._entries[name] = entry
        for a in aliases:
            self._aliases[a] = name
        return entry

    def unregister(self, name: str) -> None:
        """Remove ``name`` and its aliases (for plugins replaced at run time, and for tests)."""
        self._entries.pop(name, None)
        for a in [a for a, n in self._aliases.items() if n == name]:
            del self._aliases[a]

    @contextlib.contextmanager
    def scratch(self) -> Iterator["Registry"]:
        """A block in which registrations are undone on exit (tests register throw-away entries)."""
        self._load()
        entries, aliases = dict(self._entries), dict(self._aliases)
        try:
            yield self
        finally:
            self._entries, self._aliases = entries, aliases

    def _load(self) -> None:
        if not self._loaded_builtins:
            self._loaded_builtins = True
            for mod in self._builtins:
                importlib.import_module(mod)
        if not self._loaded_entry_points:
            self._loaded_entry_points = True
            for ep in entry_points(group=self.group):
                if ep.name in self._entries:
                    continue
                try:
                    obj = ep.load()
                except Exception as exc:  # a broken plugin must not hide the built-in entries
                    raise LightcutsError(f"entry point {ep.name!r} in group {self.group!r} failed to load: "
                                         f"{exc}") from None
                self._add(ep.name, obj, None, {}, (), False, None)

    def names(self) -> list[str]:
        """Sorted names of all entries (built-in and from entry points)."""
        self._load()
        return sorted(self._entries)

    def entries(self) -> list[Entry]:
        """All entries, sorted by name."""
        self._load()
        return [self._entries[n] for n in sorted(self._entries)]

    def entry(self, name: str) -> Entry:
        """The Entry registered as ``name`` (or an alias); LightcutsError listing the valid names if none."""
        self._load()
        name = self._aliases.get(name, name)
        if name not in self._entries:
            raise LightcutsError(f"unknown {self.kind} {name!r}; valid: {', '.join(self.names())}")
        return self._entries[name]

    def get(self, name: str) -> Any:
        """The object registered as ``name`` (``entry(name).obj``)."""
        return self.entry(name).obj

    def __contains__(self, name: str) -> bool:
        self._load()
        return self._aliases.get(name, name) in self._entries
