"""The package's layers: config imports no stage, stages import only the stages before them, and no
stage imports a command. Checked on the source (every import statement, also those inside functions)
and on what importing a module really loads."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import lightcuts

PACKAGE = Path(lightcuts.__file__).parent
#: The stages in their order; a stage may import the ones before it. ``cluster`` is the clustering
#: engine (kd-tree, Fig. 3/4) that the BVH builders of accel and the light-tree builders share.
STAGES = ("cluster", "scene", "accel", "lights", "trees", "integrators", "report", "mitsuba")
#: On top, in their order (each may import the stages and the ones before it): the run pipeline (plan,
#: stage driver, timing, warm-up, passes, the runs of render / compare / the studies), runs on a Dask
#: cluster (``distributed``, over the pipeline), the Python API (``api``, which may hand a run to a
#: cluster), the commands (argument parsing and printing) and the command line.
ABOVE = ("pipeline", "distributed", "api", "commands", "cli", "__main__")
LAYERS = STAGES + ABOVE


def imported_lightcuts_modules(path: Path) -> set[str]:
    """The ``lightcuts.X`` top-level parts imported anywhere in one source file."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        out |= {n.split(".")[1] for n in names if n.startswith("lightcuts.")}
    return out


def layer(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    return rel.parts[0]


SOURCES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_down_the_layers(path):
    """Every layer, the top ones included, imports only the layers before it (function-level imports
    count); the helpers below the stages (config, registry, io, ...) import no layer at all."""
    own = layer(path)
    imported = imported_lightcuts_modules(path) - {own}
    if own == "__init__":  # the package exports the API's names, imported on first use
        imported -= {"api"}
    if own in LAYERS:
        later = set(LAYERS[LAYERS.index(own) + 1:])
        assert not imported & later, f"{own} imports later layers {sorted(imported & later)}"
    else:
        assert not imported & set(LAYERS), f"{own} imports layers {sorted(imported & set(LAYERS))}"


def test_the_scan_sees_function_level_imports(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("def f():\n    from lightcuts.pipeline.plan import plan_run\n")
    assert imported_lightcuts_modules(p) == {"pipeline"}


def _loaded_after_import(module: str) -> list[str]:
    code = f"import sys, {module}; print('\\n'.join(sorted(m for m in sys.modules if m.startswith('lightcuts'))))"
    env = dict(os.environ, PYTHONPATH=str(PACKAGE.parent))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.split()


def test_config_loads_no_stage():
    loaded = _loaded_after_import("lightcuts.config")
    assert not [m for m in loaded if m.split(".")[1:2] and m.split(".")[1] in STAGES + ABOVE], loaded


@pytest.mark.parametrize("module", ["lightcuts", "lightcuts.api"])
def test_the_package_and_its_api_load_no_stage(module):
    """``import lightcuts`` and the API's names stay cheap: stages load when a function runs."""
    loaded = _loaded_after_import(module)
    assert not [m for m in loaded if m.split(".")[1:2] and m.split(".")[1] in STAGES + ("distributed", "commands", "cli")], loaded


@pytest.mark.parametrize("module", ["lightcuts.integrators.lightcut", "lightcuts.report.images",
                                    "lightcuts.trees.build", "lightcuts.lights.generate", "lightcuts.accel.embree.embree",
                                    "lightcuts.cluster.agglomerate"])
def test_stages_load_no_command(module):
    loaded = _loaded_after_import(module)
    assert module in loaded and not [m for m in loaded if m.startswith(("lightcuts.commands", "lightcuts.cli"))]


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


MODULES = {module_name(p): p for p in SOURCES}


def module_imports(path: Path) -> set[str]:
    """The lightcuts modules that ``path`` imports anywhere (at module level and inside functions),
    relative imports resolved; ``from a import b`` counts ``a.b`` when b is a module."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    # A module's own ancestor packages are loaded before it anyway (``from lightcuts import
    # __version__``): no edge.
    ancestors = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)}
    return {m for m in out if m in MODULES and m != name and m not in ancestors}


def import_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of the directed graph as a list of nodes (first = last), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def test_no_import_cycle_among_lightcuts_modules():
    # Function-level imports count too: a lazy import that closes a circle is still a circle of
    # modules that need each other.
    graph = {name: module_imports(path) for name, path in MODULES.items()}
    assert sum(len(v) for v in graph.values()) > 200  # the scan sees the package's imports
    assert import_cycle(graph) is None, " -> ".join(import_cycle(graph))


def test_the_cycle_check_finds_a_cycle():
    assert import_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert import_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None
