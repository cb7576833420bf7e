"""Plugins: a registry per kind (builders, metrics, ray casters, scenes, ...), name -> :class:`Entry`.

An entry is the plugin's object (a builder function, a :class:`~lightcuts.trees.metrics.Metric`, a
caster class) plus what it declares, as a Mitsuba plugin declares its parameters: ``params``, each
parameter it reads as a :class:`Param` (type, range, default), and ``traits``, kind-specific facts
that the plan step checks before any work (a caster: ``kernel_callable``; a builder:
``builtin_metrics_only``). ``reads`` is the set of parameter names.

A config names a plugin as ``NAME`` or as ``{type: NAME, param: value, ...}`` (Mitsuba's dict
shape); :meth:`Registry.resolve` turns either into a :class:`Resolved` (the entry and every
parameter checked and filled with its default), or one error line naming the config key.

Built-in entries register themselves when their modules are imported; each registry names those
modules and imports them on its first lookup or listing, so ``names()`` is complete from the start.
Outside packages add entries through an entry-point group (e.g. ``lightcuts.builders``): the entry
point names the object, and :func:`declare` attached to it says what it reads (without it, the
object's own ``reads`` attribute if it has one, else the registry's ``default_reads``).
"""

from __future__ import annotations

import contextlib
import importlib
import math
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from types import MappingProxyType
from typing import Any, Iterator, Mapping

from lightcuts.errors import LightcutsError

_DECLARATION = "__lightcuts_plugin__"


def declare(obj=None, *, reads: tuple[str, ...] = (), params: Mapping | None = None, **traits):
    """Attach a plugin declaration (``reads``, ``params``, ``traits``) to ``obj``; a decorator when
    ``obj`` is omitted.

    For objects named by entry points, which are registered without a call to ``register``.
    """

    def attach(o):
        setattr(o, _DECLARATION, {"reads": tuple(reads), "params": dict(params or {}), "traits": dict(traits)})
        return o

    return attach if obj is None else attach(obj)


def declaration(obj) -> dict:
    """What :func:`declare` attached to ``obj`` (``{"reads", "params", "traits"}``; empty without it)."""
    return getattr(obj, _DECLARATION, None) or {}


@dataclass(frozen=True)
class Param:
    """One declared plugin parameter.

    type : ``int``, ``float``, ``bool`` or ``str`` (an int is accepted where a float is declared)
    default : the value when the config leaves it out; None: the plugin computes it (e.g. ``c``,
        scene diagonal / 16) and receives None
    lo, hi : inclusive bounds for numbers; above : an exclusive lower bound (e.g. 0 for a positive
        scale); choices : the allowed values for strings
    doc : one line for ``--help`` texts and the README
    """

    type: type
    default: Any = None
    lo: float | None = None
    hi: float | None = None
    choices: tuple | None = None
    doc: str = ""
    above: float | None = None

    def check(self, value, key: str):
        """``value`` converted to the declared type; LightcutsError ``<key>: <problem>`` if it is not one."""
        t = self.type
        ok = (isinstance(value, bool) if t is bool else
              isinstance(value, int) and not isinstance(value, bool) if t is int else
              isinstance(value, (int, float)) and not isinstance(value, bool) if t is float else
              isinstance(value, t))
        if not ok:
            raise LightcutsError(f"{key}: expected {t.__name__}, got {value!r}")
        if t is float:
            value = float(value)
            if not math.isfinite(value):
                raise LightcutsError(f"{key}: {value} is not a finite number")
        if self.above is not None and not value > self.above:
            raise LightcutsError(f"{key}: {value} must be above {self.above:g}")
        if self.lo is not None and value < self.lo:
            raise LightcutsError(f"{key}: {value} is below the minimum {self.lo:g}")
        if self.hi is not None and value > self.hi:
            raise LightcutsError(f"{key}: {value} is above the maximum {self.hi:g}")
        if self.choices is not None and value not in self.choices:
            raise LightcutsError(f"{key}: {value!r} is not one of {', '.join(map(str, self.choices))}")
        return value


@dataclass(frozen=True)
class Entry:
    """One registered plugin: its name, object, declared parameters and traits; ``description`` is
    one line for listings (given, else the object's ``description``, else its docstring's first
    paragraph); ``entry_point`` the entry point's value (``mypackage.trees:my_builder``) for an
    entry loaded from one, else empty."""

    name: str
    obj: Any
    reads: frozenset[str] = frozenset()
    traits: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""
    params: Mapping[str, Param] = field(default_factory=dict)
    entry_point: str = ""

    def trait(self, key: str, default=None):
        return self.traits.get(key, default)


@dataclass(frozen=True)
class Resolved:
    """A plugin as a config names it: its entry and every declared parameter (given or default)."""

    entry: Entry
    params: Mapping[str, Any]

    @property
    def name(self) -> str:
        return self.entry.name

    @property
    def obj(self) -> Any:
        return self.entry.obj

    def trait(self, key: str, default=None):
        return self.entry.trait(key, default)

    def record(self) -> dict:
        """For report.json: ``{"type": name, **params}``."""
        return {"type": self.entry.name, **self.params}


class Registry:
    """Name -> Entry, with aliases, built-in modules loaded on first use and entry-point loading.

    kind : what the entries are, for messages ("builder", "metric", "ray caster")
    group : entry-point group scanned once for outside registrations
    builtins : modules whose import registers the built-in entries
    params : the parameters common to the kind, name -> :class:`Param` (a tuple of names: untyped);
        an entry's ``reads`` picks from them, its own ``params`` declares others
    default_reads : what an entry reads when it declares nothing (entry points without :func:`declare`)
    coerce : ``coerce(name, obj) -> obj`` applied to every object registered, so that lookups always
        return one type (e.g. a bare njit function becomes a Metric)
    """

    def __init__(self, kind: str, group: str | None = None, builtins: tuple[str, ...] = (),
                 params: tuple[str, ...] = (), default_reads: tuple[str, ...] = (), coerce=None):
        self.kind = kind
        self.group = group
        self.common: dict[str, Param | None] = (dict(params) if isinstance(params, Mapping)
                                                 else {p: None for p in params})
        self.params = frozenset(self.common)
        self.default_reads = tuple(default_reads)
        self._coerce = coerce
        self._builtins = tuple(builtins)
        self._entries: dict[str, Entry] = {}
        self._aliases: dict[str, str] = {}
        self._alias_params: dict[str, Mapping[str, Any]] = {}
        self._loaded_builtins = not builtins
        self._loaded_entry_points = group is None

    def register(self, name: str, obj: Any = None, *, reads: tuple[str, ...] | None = None,
                 params: Mapping[str, Param] | None = None, aliases: Mapping[str, Mapping] | tuple[str, ...] = (),
                 replace: bool = False, description: str | None = None, **traits):
        """Register ``obj`` under ``name``; used bare as a decorator when ``obj`` is omitted.

        reads : the kind's common parameters the entry uses (default: its :func:`declare`, else
            ``default_reads``)
        params : parameters of its own, name -> :class:`Param`
        aliases : other names; a mapping gives each alias fixed parameter values (e.g.
            ``{"octree-150": {"maxp": 150}}``)
        traits : kind-specific declarations, e.g. ``kernel_callable=True`` for a caster
        """

        def add(o):
            self._add(name, o, reads, traits, aliases, replace, description, params)
            return o

        return add if obj is None else add(obj)

    def _add(self, name, obj, reads, traits, aliases, replace, description, params=None, entry_point="") -> Entry:
        declared = getattr(obj, _DECLARATION, None) or {}
        if self._coerce is not None:
            obj = self._coerce(name, obj)
        if reads is None:
            reads = declared.get("reads", getattr(obj, "reads", self.default_reads))
        traits = {**declared.get("traits", {}), **traits}
        unknown = set(reads) - set(self.params)
        if unknown:
            raise LightcutsError(f"{self.kind} {name!r} declares unknown parameters {sorted(unknown)}; "
                                 f"valid: {', '.join(sorted(self.params)) or 'none'}")
        own = dict(params or declared.get("params", {}))
        declared_params = {p: self.common[p] for p in reads if self.common[p] is not None}
        declared_params.update(own)
        reads = set(reads) | set(own)
        if not replace and (name in self._entries or name in self._aliases):
            raise LightcutsError(f"{self.kind} {name!r} is already registered")
        if description is None:
            doc = (getattr(obj, "__doc__", None) or "").strip().split("\n\n")[0]
            description = getattr(obj, "description", None) or " ".join(doc.split())
        entry = Entry(name, obj, frozenset(reads), MappingProxyType(dict(traits)), str(description),
                      MappingProxyType(declared_params), entry_point)
        aliases = dict(aliases) if isinstance(aliases, Mapping) else {a: {} for a in aliases}
        for a, fixed in aliases.items():
            for p, v in fixed.items():
                if p not in declared_params:
                    raise LightcutsError(f"{self.kind} alias {a!r} fixes {p!r}, which {name!r} does not declare")
                declared_params[p].check(v, f"{self.kind} alias {a!r}: {p}")
        self._entries[name] = entry
        for a, fixed in aliases.items():
            self._aliases[a] = name
            self._alias_params[a] = MappingProxyType(dict(fixed))
        return entry

    def unregister(self, name: str) -> None:
        """Remove ``name`` and its aliases (for plugins replaced at run time, and for tests)."""
        self._entries.pop(name, None)
        for a in [a for a, n in self._aliases.items() if n == name]:
            del self._aliases[a]
            self._alias_params.pop(a, None)

    @contextlib.contextmanager
    def scratch(self) -> Iterator["Registry"]:
        """A block in which registrations are undone on exit (tests register throw-away entries)."""
        self._load()
        entries, aliases, alias_params = dict(self._entries), dict(self._aliases), dict(self._alias_params)
        try:
            yield self
        finally:
            self._entries, self._aliases, self._alias_params = entries, aliases, alias_params

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
                self._add(ep.name, obj, None, {}, (), False, None, entry_point=ep.value)

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

    def aliases(self) -> dict[str, str]:
        """Alias -> entry name."""
        self._load()
        return dict(self._aliases)

    def alias_values(self, alias: str) -> Mapping[str, Any]:
        """The parameter values ``alias`` fixes (``{"maxp": 150}`` for ``octree-150``); empty for a plain alias."""
        self._load()
        return self._alias_params.get(alias, MappingProxyType({}))

    def resolve(self, spec, key: str) -> Resolved:
        """The plugin ``spec`` names, with its parameters checked and defaults filled in.

        spec : a name, a ``{"type": NAME, param: value, ...}`` mapping, or a :class:`Resolved`
        key : the config key, for messages (``render.ray_caster``)
        An alias's fixed values apply first; the mapping's values override them. LightcutsError with
        one line ``<key>[.<param>]: <problem>`` for an unknown name, an undeclared parameter or a
        value of the wrong type or out of range.
        """
        if isinstance(spec, Resolved):
            return spec
        if isinstance(spec, Mapping):
            if "type" not in spec:
                raise LightcutsError(f"{key}: a mapping needs 'type' (the {self.kind}'s name)")
            name, given = spec["type"], {k: v for k, v in spec.items() if k != "type"}
        else:
            name, given = spec, {}
        if not isinstance(name, str):
            raise LightcutsError(f"{key}: expected a {self.kind} name, got {name!r}")
        try:
            entry = self.entry(name)
        except LightcutsError as exc:
            raise LightcutsError(f"{key}: {exc}") from None
        values = dict(self._alias_params.get(name, {}))
        for p, v in given.items():
            if p not in entry.params:
                declared = ", ".join(sorted(entry.params)) or "nothing"
                raise LightcutsError(f"{key}.{p}: {self.kind} {entry.name!r} has no parameter {p!r} "
                                     f"(it reads: {declared})")
            values[p] = entry.params[p].check(v, f"{key}.{p}")
        out = {p: values.get(p, decl.default) for p, decl in sorted(entry.params.items())}
        return Resolved(entry, MappingProxyType(out))

    def get(self, name: str) -> Any:
        """The object registered as ``name`` (``entry(name).obj``)."""
        return self.entry(name).obj

    def __contains__(self, name: str) -> bool:
        self._load()
        return self._aliases.get(name, name) in self._entries
