"""The plugin reference, generated from the registries (as Mitsuba 3 generates its plugin docs from
each plugin's parameter table): every entry of a :class:`~lightcuts.registry.Registry` with its
description, aliases, traits and declared :class:`~lightcuts.registry.Param` s (type, default,
range or choices, doc), as plain text (``lightcuts plugins``) or as Markdown tables.

The README and docs hold the Markdown between markers ``<!-- plugins:NAME -->`` and
``<!-- /plugins:NAME -->`` (blank lines around the text, so that Markdown ends a table before the
closing marker); :func:`update_blocks` rewrites what lies between them, so a test can compare a
file with its regenerated text. This module knows registries only through their public
API (``kind``, ``group``, ``entries()``, ``aliases()``, ``alias_values()``); which registries exist
and which config key names each is the caller's :class:`Kind` list (lightcuts.commands.plugins).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from lightcuts.errors import LightcutsError
from lightcuts.registry import Entry, Param, Registry

#: What a value without a plain form (a ``None`` default) shows: the plugin computes it.
COMPUTED = "computed"


@dataclass(frozen=True)
class Kind:
    """One plugin kind as the reference lists it.

    name : the ``lightcuts plugins KIND`` argument and the marker's NAME (``builders``)
    registry : its :class:`Registry`
    where : the registry's import name, for the reader (``lightcuts.trees.BUILDERS``)
    key : the config key naming an entry (``tree.builder``), or keys separated by ``, ``
    default : the entry a config gets when it names none (None: no default)
    """

    name: str
    registry: Registry
    where: str
    key: str
    default: str | None = None

    def entries(self, built_in: bool = False) -> list[Entry]:
        """The registry's entries by name; built_in: without those loaded from entry points (what the
        installed outside packages add, which lightcuts' own docs do not list)."""
        return [e for e in self.registry.entries() if not (built_in and e.entry_point)]


def format_value(v: Any) -> str:
    """A plain value as the tables show it: ints with thousands separators, floats exactly (their
    repr), booleans ``yes``/``no``, tuples in brackets; None is :data:`COMPUTED`."""
    if v is None:
        return COMPUTED
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(format_value(x) for x in v) + "]"
    return str(v)


def _plain(v: Any) -> bool:
    if v is None or isinstance(v, (bool, int, float, str)):
        return True
    return type(v) in (tuple, list) and all(_plain(x) for x in v)


def param_range(p: Param) -> str:
    """The values ``p`` accepts beyond its type: ``1 to 64``, ``> 0, <= 1e+30``, ``a | b``; ``any``."""
    parts = []
    if p.above is not None:
        parts.append(f"> {format_value(p.above)}")
    if p.lo is not None and p.hi is not None:
        parts.append(f"{format_value(p.lo)} to {format_value(p.hi)}")
    elif p.lo is not None:
        parts.append(f">= {format_value(p.lo)}")
    elif p.hi is not None:
        parts.append(f"<= {format_value(p.hi)}")
    if p.choices is not None:
        parts.append(" | ".join(format_value(c) for c in p.choices))
    return ", ".join(parts) or "any"


def shown_traits(entry: Entry) -> dict[str, str]:
    """The entry's traits that have a plain form, name -> text: plain values (numbers, strings,
    booleans, tuples of them) as :func:`format_value` writes them, functions and classes by name;
    anything else (e.g. a caster's device functions) is left out."""
    out = {}
    for k, v in sorted(entry.traits.items()):
        if _plain(v):
            out[k] = format_value(v)
        elif callable(v) and hasattr(v, "__name__"):
            out[k] = v.__name__
    return out


def passed_in(entry: Entry) -> list[str]:
    """What ``entry`` reads of the kind's untyped common parameters: the run passes them in (a
    metric's ``c``), the entry's mapping cannot set them."""
    return sorted(set(entry.reads) - set(entry.params))


def aliases_of(kind: Kind, entry: Entry) -> list[tuple[str, str]]:
    """``entry``'s aliases in the order they were registered, each with the parameter values it
    fixes: ``("octree-50", "maxp=50")``."""
    return [(alias, ", ".join(f"{p}={format_value(v)}" for p, v in kind.registry.alias_values(alias).items()))
            for alias, name in kind.registry.aliases().items() if name == entry.name]


def _header(kind: Kind, code=str) -> str:
    default = f" (default {code(kind.default)})" if kind.default else ""
    group = f"; entry points {code(kind.registry.group)}" if kind.registry.group else ""
    keys = " or ".join(code(k) for k in kind.key.split(", "))
    return f"config key {keys}{default}; registry {code(kind.where)}{group}"


# ------------------------------------------------------------------------------------------ text

def kind_text(kind: Kind) -> str:
    """Every entry of ``kind`` as indented text: name and description, then aliases, parameters
    (name, type, default, range, doc), values the run passes in, and traits."""
    lines = [f"{kind.name}: {_header(kind)}"]
    for e in kind.entries():
        lines.append(f"  {e.name}" + (f": {e.description}" if e.description else ""))
        if e.entry_point:
            lines.append(f"    entry point: {e.entry_point}")
        aliases = aliases_of(kind, e)
        if aliases:
            lines.append("    aliases: " + ", ".join(a + (f" ({v})" if v else "") for a, v in aliases))
        width = max((len(p) for p in e.params), default=0)
        for p, decl in sorted(e.params.items()):
            lines.append(f"    {p:<{width}}  {decl.type.__name__}, default {format_value(decl.default)}, "
                         f"{param_range(decl)}: {decl.doc}")
        passed = passed_in(e)
        if passed:
            lines.append(f"    reads from the run: {', '.join(passed)}")
        if not e.params and not passed:
            lines.append("    no parameters")
        traits = shown_traits(e)
        if traits:
            lines.append("    traits: " + ", ".join(f"{k}={v}" for k, v in traits.items()))
    return "\n".join(lines) + "\n"


# -------------------------------------------------------------------------------------- markdown

def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table's lines; ``|`` in a cell is escaped (also inside code spans, as GFM asks)."""
    def line(cells):
        return "| " + " | ".join(c.replace("|", "\\|").replace("\n", " ") for c in cells) + " |"

    return [line(header), line(["---"] * len(header)), *(line(r) for r in rows)]


def _code(text: str) -> str:
    return f"`{text}`"


def kind_markdown(kind: Kind, built_in: bool = False) -> str:
    """``kind`` as Markdown: a line naming its config key, registry and entry-point group, a table of
    entries (name, aliases, description, traits; and what the run passes in, where an entry reads
    such a value) and a table of every declared parameter (entry, parameter, type, default, range,
    meaning). built_in: without the entries of entry points (:meth:`Kind.entries`)."""
    entries = kind.entries(built_in)
    optional = {"reads from the run": lambda e: ", ".join(_code(p) for p in passed_in(e)),
                "traits": lambda e: ", ".join(f"{_code(k)}: {v}" for k, v in shown_traits(e).items())}
    optional = {c: cell for c, cell in optional.items() if any(cell(e) for e in entries)}
    rows = []
    for e in entries:
        aliases = ", ".join(_code(a) + (f" ({fixed})" if fixed else "") for a, fixed in aliases_of(kind, e))
        name = _code(e.name) + (f" (aliases {aliases})" if aliases else "")
        rows.append([name, e.description, *(cell(e) for cell in optional.values())])
    out = [f"{kind.name.capitalize()}: {_header(kind, _code)}.", "", *_table(["name", "what", *optional], rows)]
    params = [[_code(e.name) if i == 0 else "", _code(p), decl.type.__name__, format_value(decl.default),
               param_range(decl), decl.doc]
              for e in entries for i, (p, decl) in enumerate(sorted(e.params.items()))]
    if params:
        out += ["", *_table(["name", "parameter", "type", "default", "range", "meaning"], params)]
    return "\n".join(out) + "\n"


def index_markdown(kinds: list[Kind], built_in: bool = False) -> str:
    """One table row per kind: its name, registry, config key, default and entry-point group, and
    its entries' names (built_in: :meth:`Kind.entries`)."""
    rows = [[k.name, _code(k.where), " or ".join(_code(key) for key in k.key.split(", ")), _code(k.default) if k.default else "",
             _code(k.registry.group) if k.registry.group else "", ", ".join(_code(e.name) for e in k.entries(built_in))]
            for k in kinds]
    return "\n".join(_table(["kind", "registry", "config key", "default", "entry points", "entries"], rows)) + "\n"


# ---------------------------------------------------------------------------------------- blocks

#: A generated block: a line ``<!-- plugins:NAME -->``, the text, a line ``<!-- /plugins:NAME -->``
#: (markers only count on lines of their own, so that prose can quote them).
BLOCK = re.compile(r"^(<!-- plugins:(?P<name>[\w-]+) -->\n)(?P<body>.*?)^(<!-- /plugins:(?P=name) -->)$",
                   re.S | re.M)
OPENING = re.compile(r"^<!-- plugins:([\w-]+) -->$", re.M)


def block_names(text: str) -> list[str]:
    """The NAMEs of the generated blocks in ``text``, in order."""
    return [m["name"] for m in BLOCK.finditer(text)]


def update_blocks(text: str, generate: Mapping[str, Callable[[], str]], source: str = "text") -> str:
    """``text`` with the body of every block replaced by ``generate[NAME]()``; LightcutsError
    ``<source>: ...`` for a block NAME that ``generate`` lacks or an opening marker without its
    closing one."""
    opened = OPENING.findall(text)
    found = block_names(text)
    if len(opened) != len(found):
        name = next((n for n in opened if opened.count(n) > found.count(n)), opened[-1])
        raise LightcutsError(f"{source}: <!-- plugins:{name} --> has no closing <!-- /plugins:{name} --> line")
    for name in found:
        if name not in generate:
            raise LightcutsError(f"{source}: unknown plugin block {name!r}; valid: {', '.join(generate)}")
    return BLOCK.sub(lambda m: m[1] + "\n" + generate[m["name"]]() + "\n" + m[4], text)
