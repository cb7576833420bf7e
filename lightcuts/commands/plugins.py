"""``lightcuts plugins [KIND] [--markdown] [--write FILE]``: every registry's entries with their
parameters and traits (lightcuts.plugin_docs), and the README's generated tables rewritten.

Listing imports the registries and their entries' modules (numba kernels are defined there, not
compiled: no kernel runs).
"""

from __future__ import annotations

import sys
from pathlib import Path

from lightcuts.errors import LightcutsError

#: The kinds in the order they are listed: name -> (registry module, registry name, config key(s),
#: default entry's name in lightcuts.config.schema, else in the registry module, or None).
_KINDS = {
    "scenes": ("lightcuts.scene.registry", "SCENES", "scene.builtin, scene.procedural", None),
    "ray-casters": ("lightcuts.accel.registry", "RAY_CASTERS", "render.ray_caster", "DEFAULT_RAY_CASTER"),
    "builders": ("lightcuts.trees.registry", "BUILDERS", "tree.builder", "DEFAULT_BUILDER"),
    "metrics": ("lightcuts.trees.registry", "METRICS", "tree.metric", "DEFAULT_METRIC"),
    "integrators": ("lightcuts.integrators.registry", "INTEGRATORS", "render.integrator", "DEFAULT_INTEGRATOR"),
    "references": ("lightcuts.integrators.references", "REFERENCES", "--renderer (lightcuts reference)",
                   "DEFAULT_REFERENCE"),
}


def kinds() -> dict:
    """Name -> :class:`lightcuts.plugin_docs.Kind` for every registry, in listing order."""
    import importlib

    from lightcuts.config import schema
    from lightcuts.plugin_docs import Kind

    out = {}
    for name, (module, attr, key, default) in _KINDS.items():
        mod = importlib.import_module(module)
        registry = getattr(mod, attr)
        out[name] = Kind(name, registry, f"{module}.{attr}", key,
                         getattr(schema, default, None) or getattr(mod, default) if default else None)
    return out


def generators() -> dict:
    """Block NAME -> function returning its Markdown for lightcuts' own docs (built-in entries, not
    those of installed entry points): every kind, and ``index`` (one row per kind)."""
    from lightcuts.plugin_docs import index_markdown, kind_markdown

    all_kinds = kinds()
    out = {"index": lambda: index_markdown(list(all_kinds.values()), built_in=True)}
    out.update({name: (lambda k=k: kind_markdown(k, built_in=True)) for name, k in all_kinds.items()})
    return out


def rewritten(path: str, generate: dict) -> tuple[str, str]:
    """The Markdown file ``path``'s text and that text with every generated block rewritten by
    ``generate`` (:func:`generators`). LightcutsError ``<path>: ...`` for a file that cannot be
    read, has no block or a bad one."""
    from lightcuts.plugin_docs import block_names, update_blocks

    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LightcutsError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if not block_names(text):
        raise LightcutsError(f"{path}: no <!-- plugins:NAME --> ... <!-- /plugins:NAME --> block to rewrite")
    return text, update_blocks(text, generate, path)


def add_parser(sub) -> None:
    p = sub.add_parser("plugins", help="every registry's entries with their parameters and traits")
    p.add_argument("kind", nargs="?", metavar="KIND",
                   help=f"one kind only: {', '.join(_KINDS)}")
    p.add_argument("--markdown", action="store_true", help="Markdown tables, as the README's")
    p.add_argument("--write", metavar="FILE", action="append", default=[],
                   help="rewrite the generated <!-- plugins:NAME --> blocks of FILE (e.g. README.md; repeatable)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.kind is not None and args.kind not in _KINDS:
        raise LightcutsError(f"plugins: unknown kind {args.kind!r}; valid: {', '.join(_KINDS)}")
    if args.write:
        if args.kind is not None:
            raise LightcutsError(f"plugins: --write rewrites every block of the file; give no KIND ({args.kind})")
        generate = generators()
        texts = {path: rewritten(path, generate) for path in args.write}  # every file checked before any is written
        for path, (old, new) in texts.items():
            if new != old:
                Path(path).write_text(new, encoding="utf-8")
            print(f"{path}: {'rewritten' if new != old else 'up to date'}")
        return 0
    from lightcuts.plugin_docs import kind_markdown, kind_text

    selected = [k for name, k in kinds().items() if args.kind in (None, name)]
    render = kind_markdown if args.markdown else kind_text
    sys.stdout.write("\n".join(render(k) for k in selected))
    return 0
