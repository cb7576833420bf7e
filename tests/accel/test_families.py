"""The caster families in lightcuts/accel (embree/, bvh/, grids/) never import each other: each
depends only on the accel core (and the layers below), so a family can be removed or replaced alone."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import lightcuts

ACCEL = Path(lightcuts.__file__).parent / "accel"
FAMILIES = sorted(p.name for p in ACCEL.iterdir() if p.is_dir() and (p / "__init__.py").is_file())


def imports_of(text: str, package: str) -> set[str]:
    """Every module the source ``text`` of a module in ``package`` imports (absolute names; relative
    imports resolved), at any depth in it (imports inside functions count)."""
    out = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return out


def imported_modules(path: Path) -> set[str]:
    package = ".".join(("lightcuts", *path.relative_to(ACCEL.parent).parts[:-1]))
    return imports_of(path.read_text(), package)


def test_the_families_are_there():
    assert FAMILIES == ["bvh", "embree", "grids"]


@pytest.mark.parametrize("family", FAMILIES)
def test_a_family_imports_no_other_family(family):
    others = [f"lightcuts.accel.{f}" for f in FAMILIES if f != family]
    for path in sorted((ACCEL / family).rglob("*.py")):
        bad = sorted(m for m in imported_modules(path) for o in others if m == o or m.startswith(o + "."))
        assert not bad, f"{path.relative_to(ACCEL)} imports {bad}"


def test_the_core_imports_no_family():
    families = [f"lightcuts.accel.{f}" for f in FAMILIES]
    for path in sorted(ACCEL.glob("*.py")):
        bad = sorted(m for m in imported_modules(path) for o in families if m == o or m.startswith(o + "."))
        assert not bad, f"{path.relative_to(ACCEL)} imports {bad}"


def test_the_scan_sees_imports():
    """The scan finds absolute, relative and nested imports (so the tests above can fail)."""
    mods = imports_of("import lightcuts.accel.bvh.bvh\nfrom ..embree import embree\n"
                      "def f():\n    from lightcuts.accel.bvh import bvh_kernels\n", "lightcuts.accel.grids")
    assert {"lightcuts.accel.bvh.bvh", "lightcuts.accel.embree.embree", "lightcuts.accel.bvh.bvh_kernels"} <= mods
