"""A resolved light-tree recipe: the builder's entry, the metric and ``c`` it reads, checked together.

:func:`tree_spec` is the one place where builder and metric names become objects and where their
combination is checked (a parameter the builder does not read, a user metric for a builder that
needs a built-in one, too many lights for a builder with a size limit). Commands call it in their
plan step, before any work, and hand the :class:`TreeSpec` down; :func:`lightcuts.trees.build_tree`
takes it as is.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

from lightcuts.config.schema import DEFAULT_BUILDER
from lightcuts.errors import LightcutsError
from lightcuts.registry import Entry, Resolved
from lightcuts.trees.metric_type import Metric
from lightcuts.trees.registry import BUILDERS, METRICS

#: Config keys named in messages, by parameter (commands pass their own, e.g. ``--metric``).
CONFIG_KEYS = {"builder": "tree.builder", "metric": "tree.metric", "c": "tree.c"}


@dataclass(frozen=True)
class TreeSpec:
    """builder : the builder's registry entry; metric : the Metric it reads, or None;
    c : the cone-term scale it reads (None = the default, scene diagonal / 16), or None;
    reads_c : whether ``c`` matters for this builder and metric."""

    builder: Entry
    metric: Metric | None
    c: float | None
    reads_c: bool

    @property
    def name(self) -> str:
        return self.builder.name

    @property
    def resolved(self) -> Resolved:
        """The builder as a registry :class:`Resolved`: its declared parameters, metric by name,
        c as given (None: the scene diagonal / 16, recorded per light type in the tree's meta)."""
        values = {"metric": self.metric.name if self.metric is not None else None, "c": self.c}
        return Resolved(self.builder, MappingProxyType({p: values.get(p) for p in sorted(self.builder.params)}))

    def record(self) -> dict:
        """For report.json: ``{"type": builder, "metric": ..., "c": ...}`` (what the builder reads)."""
        return self.resolved.record()

    def check_size(self, n_lights: int, key: str = "tree.builder") -> None:
        """LightcutsError if the builder refuses ``n_lights`` lights (its ``max_lights`` trait)."""
        limit = self.builder.trait("max_lights")
        if limit is not None and n_lights > limit:
            others = [e.name for e in BUILDERS.entries() if e.trait("max_lights") is None]
            raise LightcutsError(f"{key}: builder {self.name!r} is a reference for at most {limit:,} lights, "
                                 f"got {n_lights:,}; use one of {', '.join(others)}")


def flat_tree(builder=None, metric=None, c=None, keys: dict[str, str] | None = None):
    """``(builder name or Entry, metric, c, keys)`` from a builder given as a name or as a mapping
    ``{type: NAME, metric: ..., c: ...}`` beside the flat ``metric`` and ``c``; ``keys`` then names
    ``<builder key>.<param>`` for what the mapping gave. LightcutsError if the mapping has no type,
    a parameter no builder reads, or a parameter that is also given flat."""
    keys = {**CONFIG_KEYS, **(keys or {})}
    if not isinstance(builder, Mapping):
        return builder, metric, c, keys
    if not isinstance(builder.get("type"), str):
        BUILDERS.resolve(builder, keys["builder"])  # the registry's one-line error for a bad type
    flat = {"metric": metric, "c": c}
    for p in builder:
        if p == "type":
            continue
        if p not in flat:
            BUILDERS.resolve(builder, keys["builder"])  # names <key>.<p>: the builder has no such parameter
            raise LightcutsError(f"{keys['builder']}.{p}: not a builder parameter; valid: metric, c")
        if flat[p] is not None:
            raise LightcutsError(f"{keys[p]}: given twice, also as {keys['builder']}.{p}; give one")
        flat[p] = builder[p]
        keys[p] = f"{keys['builder']}.{p}"
    return builder["type"], flat["metric"], flat["c"], keys


def config_tree(tc) -> tuple:
    """:func:`flat_tree` of a config's ``tree`` section (:class:`~lightcuts.config.schema.TreeConfig`)."""
    return flat_tree(tc.builder, tc.metric, tc.c)


def tree_spec(builder: str | Mapping | Entry | None = None, metric: str | Metric | None = None,
              c: float | None = None, keys: dict[str, str] | None = None, drop_unread: bool = False) -> TreeSpec:
    """Resolve and check a builder with its metric and ``c``; LightcutsError naming the key at fault.

    builder : name, ``{type: NAME, metric: ..., c: ...}`` mapping (:func:`flat_tree`) or entry (default
        the schema's ``DEFAULT_BUILDER``)
    metric : name or Metric, or None for the builder's default (``BUILDERS``' ``metric`` parameter) if
        it reads one; given to a builder that reads no metric, an error
    c : positive float up to ``lightcuts.limits.MAX_COORD`` (``BUILDERS``' ``c`` parameter), or None for
        the default; given where nothing reads it, an error
    keys : how to name builder / metric / c in messages (default the config keys)
    drop_unread : leave out a metric or c that the builder does not read instead of refusing it
        (for commands that run several builders on one config, each with only what it reads)
    """
    builder, metric, c, keys = flat_tree(builder, metric, c, keys)

    def lookup(registry, key, name):
        try:
            return registry.entry(name)
        except LightcutsError as exc:
            raise LightcutsError(f"{keys[key]}: {exc}") from None

    entry = builder if isinstance(builder, Entry) else lookup(BUILDERS, "builder", builder or DEFAULT_BUILDER)
    m = None
    if "metric" in entry.reads:
        if not isinstance(metric, Metric):
            param = entry.params.get("metric", BUILDERS.common["metric"])
            name = param.default if metric is None else param.check(metric, keys["metric"])
            m = lookup(METRICS, "metric", name).obj
        else:
            m = metric
        if entry.trait("builtin_metrics_only") and not m.builtin:
            builtin = [e.name for e in METRICS.entries() if e.obj.builtin]
            general = [e.name for e in BUILDERS.entries() if "metric" in e.reads and not e.trait("builtin_metrics_only")]
            raise LightcutsError(f"{keys['metric']}: builder {entry.name!r} needs a built-in metric "
                                 f"({', '.join(builtin)}) for its kd-tree's lower bound; {m.name!r} is a user "
                                 f"metric (builders for any metric: {', '.join(general)})")
    elif metric is not None and not drop_unread:
        raise LightcutsError(f"{keys['metric']}: builder {entry.name!r} reads no metric; remove it "
                             f"(builders that read one: {', '.join(_readers('metric'))})")
    reads_c = "c" in entry.reads and (m is None or "c" in m.reads)
    if c is not None and drop_unread and not reads_c:
        c = None
    if c is not None:
        if not reads_c:
            why = (f"metric {m.name!r} has no cone term" if "c" in entry.reads
                   else f"builder {entry.name!r} reads no c")
            raise LightcutsError(f"{keys['c']}: {why}; remove it")
        c = entry.params.get("c", BUILDERS.common["c"]).check(c, keys["c"])
    return TreeSpec(entry, m, c, reads_c)


def _readers(param: str) -> list[str]:
    return [e.name for e in BUILDERS.entries() if param in e.reads]
