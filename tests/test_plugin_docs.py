"""The plugin reference (lightcuts.plugin_docs, ``lightcuts plugins``): every registered entry with
its parameters, the README's generated blocks equal to what the registries give, a doc for every
declared parameter, and no kernel compiled by a listing."""

from __future__ import annotations

import difflib
import os
import re
import shutil
import subprocess
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

import lightcuts.registry
from lightcuts.cli import main
from lightcuts.commands.plugins import kinds
from lightcuts.pipeline.warmup import NOTICE
from lightcuts.errors import LightcutsError
from lightcuts.plugin_docs import (COMPUTED, Kind, format_value, kind_markdown, kind_text, param_range, shown_traits,
                                   update_blocks)
from lightcuts.registry import Param, Registry

ROOT = Path(__file__).parents[1]
#: The files holding generated blocks.
DOCS = ("README.md", "docs/architecture.md")


def _run_cli(*args, cwd, env=None):
    env = dict(os.environ if env is None else env, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lightcuts", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def _register_scratch_entries() -> dict[str, str]:
    """In every registry, a new entry (the object of its first entry again) with a parameter of its
    own: kind -> the new entry's name."""
    out = {}
    for name, kind in kinds().items():
        first = kind.registry.entries()[0]
        new = f"scratch-{name}"
        kind.registry.register(new, first.obj, params={"scratch_width": Param(int, 3, lo=1, hi=9,
                                                                              doc=f"a width for {name}")},
                               description=f"scratch {name}", **first.traits)
        out[name] = new
    return out


def _sections(text: str) -> dict[str, dict[str, list[str]]]:
    """``lightcuts plugins`` output as kind -> entry -> the entry's indented lines."""
    out: dict[str, dict[str, list[str]]] = {}
    for line in text.splitlines():
        if not line.strip():
            continue
        if not line.startswith(" "):
            kind = out.setdefault(line.split(":")[0], {})
        elif not line.startswith("    "):
            entry = kind.setdefault(line.strip().split(":")[0], [])
        else:
            entry.append(line.strip())
    return out


def test_listing_shows_every_entry_of_every_kind_with_its_parameters(scratch_registries, capsys):
    """Checked against the registries, with an entry registered at run time in each: every entry
    under its kind (and no other), every declared parameter with type, default, range and doc."""
    scratch = _register_scratch_entries()
    assert main(["plugins"]) == 0
    listed = _sections(capsys.readouterr().out)
    assert list(listed) == list(kinds())
    for name, kind in kinds().items():
        assert sorted(listed[name]) == kind.registry.names()
        assert scratch[name] in listed[name]
        for e in kind.registry.entries():
            for p, decl in e.params.items():
                line = f"{p} {decl.type.__name__}, default {format_value(decl.default)}, {param_range(decl)}: {decl.doc}"
                assert line in [re.sub(r"^(\S+)\s+", r"\1 ", s) for s in listed[name][e.name]], (name, e.name, p)
    assert "scratch_width int, default 3, 1 to 9: a width for builders" in [
        re.sub(r"^(\S+)\s+", r"\1 ", s) for s in listed["builders"]["scratch-builders"]]


def test_one_kind_as_markdown(scratch_registries, capsys):
    """``plugins KIND --markdown``: that kind only, a row per entry, a row per declared parameter."""
    scratch = _register_scratch_entries()
    assert main(["plugins", "ray-casters", "--markdown"]) == 0
    out = capsys.readouterr().out
    head, entries, params = out.strip().split("\n\n")
    assert head.startswith("Ray-casters: config key `render.ray_caster` (default `embree`)")
    from lightcuts.accel import RAY_CASTERS

    assert [re.match(r"\| `([^`]+)`", row)[1] for row in entries.splitlines()[2:]] == RAY_CASTERS.names()
    assert f"| `{scratch['ray-casters']}` | `scratch_width` | int | 3 | 1 to 9 | a width for ray-casters |" in params
    assert "| `hug` | `alpha` | float | 0.01 | 1e-09 to 1000.0 | " in params


def test_unknown_kind_is_one_error_line(capsys):
    assert main(["plugins", "nosuchkind"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == ("error: plugins: unknown kind 'nosuchkind'; valid: scenes, ray-casters, builders, metrics, "
                   "integrators, references\n")


def test_help_lists_the_command():
    from lightcuts.cli import build_parser

    assert "plugins" in build_parser().format_help()


# ----------------------------------------------------------------------------------- the docs

def test_every_declared_parameter_has_a_doc():
    """Every Param of every entry, and of every registry's common parameters, says what it is."""
    missing = [(name, e.name, p) for name, k in kinds().items() for e in k.registry.entries()
               for p, decl in e.params.items() if not decl.doc.strip()]
    missing += [(name, "(common)", p) for name, k in kinds().items() for p, decl in k.registry.common.items()
                if decl is not None and not decl.doc.strip()]
    assert missing == []


def test_the_docs_generated_blocks_match_the_registries(tmp_path):
    """README.md's and docs/architecture.md's blocks are what ``plugins --write`` makes of them in a
    fresh process (only the built-in entries registered); a diff shows the drift."""
    copies = []
    for rel in DOCS:
        copies.append(tmp_path / rel.replace("/", "-"))
        shutil.copy(ROOT / rel, copies[-1])
    r = _run_cli("plugins", *[a for c in copies for a in ("--write", str(c))], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    for rel, copy in zip(DOCS, copies):
        old, new = (ROOT / rel).read_text(), copy.read_text()
        diff = "".join(difflib.unified_diff(old.splitlines(True), new.splitlines(True), rel, "generated"))
        assert old == new, f"{rel}: its plugin tables drifted; run lightcuts plugins --write {rel}\n{diff}"


def test_an_edited_cell_is_drift_and_write_restores_it(tmp_path):
    """One README cell changed: ``--write`` finds a difference and puts back the generated text."""
    readme = (ROOT / "README.md").read_text()
    cell = "| 1 to 16 | copies of the kitchen in the building |"
    assert readme.count(cell) == 1
    (tmp_path / "README.md").write_text(readme.replace(cell, "| 1 to 17 | copies of the kitchen in the building |"))
    r = _run_cli("plugins", "--write", "README.md", cwd=tmp_path)
    assert r.returncode == 0 and r.stdout == "README.md: rewritten\n", r.stderr
    assert (tmp_path / "README.md").read_text() == readme


def test_write_refuses_a_file_without_blocks_before_writing_any(tmp_path):
    (tmp_path / "a.md").write_text("<!-- plugins:index -->\nold\n<!-- /plugins:index -->\n")
    (tmp_path / "b.md").write_text("no blocks\n")
    r = _run_cli("plugins", "--write", "a.md", "--write", "b.md", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.splitlines() == [
        "error: b.md: no <!-- plugins:NAME --> ... <!-- /plugins:NAME --> block to rewrite"]
    assert (tmp_path / "a.md").read_text().splitlines()[1] == "old"


def test_listing_compiles_no_kernel(tmp_path):
    """On an empty numba cache a listing writes no cache file and prints no compile notice: it
    imports the entries' modules but runs no kernel."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    r = _run_cli("plugins", cwd=tmp_path, env=env)
    assert r.returncode == 0 and NOTICE not in r.stderr and r.stderr == "", r.stderr
    assert [p for p in (tmp_path / "cache").rglob("*") if p.is_file()] == []
    assert "  multidimensional: " in r.stdout


# ------------------------------------------------------------------------------------- the parts

def test_blocks_need_markers_on_lines_of_their_own():
    gen = {"a": lambda: "A\n"}
    quoted = "x `<!-- plugins:a -->` quoted, and at the end of a line: <!-- plugins:a -->\n"
    text = quoted + "<!-- plugins:a -->\nold\n<!-- /plugins:a -->\ny\n"
    assert update_blocks(text, gen) == quoted + "<!-- plugins:a -->\n\nA\n\n<!-- /plugins:a -->\ny\n"
    with pytest.raises(LightcutsError, match=r"^f.md: <!-- plugins:a --> has no closing"):
        update_blocks("<!-- plugins:a -->\nold\n", gen, "f.md")
    with pytest.raises(LightcutsError, match=r"^f.md: unknown plugin block 'b'; valid: a$"):
        update_blocks("<!-- plugins:b -->\n<!-- /plugins:b -->\n", gen, "f.md")


def test_ranges_defaults_and_traits_as_shown():
    assert param_range(Param(float, None, above=0, hi=1e30)) == "> 0, <= 1e+30"
    assert param_range(Param(int, 1, lo=1)) == ">= 1"
    assert param_range(Param(str, "a", choices=("a", "b"))) == "a | b"
    assert param_range(Param(str, "a")) == "any"
    assert [format_value(v) for v in (None, True, 200_000, 0.01, (512, 384), "x")] == [
        COMPUTED, "yes", "200,000", "0.01", "[512, 384]", "x"]
    reg = Registry("widget")

    def reference():
        pass

    reg.register("w", object(), device=(object(), "k"), reference=reference, lens=False, size=(2, 3))
    assert shown_traits(reg.entry("w")) == {"lens": "no", "reference": "reference", "size": "[2, 3]"}


def _widget(position, c):
    """A widget that spans
    two lines.

    Details no listing shows.
    """


def test_entry_point_entries_are_listed_but_not_in_the_docs(monkeypatch):
    """An installed package's entry (group lightcuts.widgets here) is in ``plugins`` listings, with
    its entry point, and left out of the generated docs; a description is the docstring's first
    paragraph."""
    monkeypatch.setattr(lightcuts.registry, "entry_points", lambda group: [
        EntryPoint("outside", f"{__name__}:_widget", group)] if group == "lightcuts.widgets" else [])
    reg = Registry("widget", group="lightcuts.widgets", params={"c": Param(float, 1.0, doc="a scale")},
                   default_reads=("c",))
    reg.register("inside", object(), reads=(), aliases={"inside-2": {}})
    kind = Kind("widgets", reg, "tests.WIDGETS", "widget.type", "inside")
    text = kind_text(kind)
    assert f"  outside: A widget that spans two lines.\n    entry point: {__name__}:_widget\n" in text
    assert "    c  float, default 1.0, any: a scale\n" in text
    assert "| `outside` |" in kind_markdown(kind) and "outside" not in kind_markdown(kind, built_in=True)
    assert "| `inside` (aliases `inside-2`) |" in kind_markdown(kind, built_in=True)
