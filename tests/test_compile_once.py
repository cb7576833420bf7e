"""Each lightcuts kernel compiles once per run: numba compiles a function again for every new tuple
of argument types (a literal ``0`` against an int64, a read-only array against a writeable one) and,
for an ``@overload``, for every set of its callers' compile flags; each such specialisation costs a
whole compile of the function and of what it inlines.

Checked on a cold run of the light tracing (``lightcuts lights``) and of the lightcuts render kernel
(its warm-up, one pixel: the specialisation every render uses) in one fresh process on an empty numba
cache, with numba's ``numba:compile`` events counted per function. ``NUMBA_OPT=0`` spares LLVM's
optimisation, which decides nothing about types.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: The child: every lightcuts function's compiles (their argument types), as JSON on the last line.
_PROBE = """
import json
from numba.core import event

compiles = {}

class Count(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        if f.__module__.split(".")[0] == "lightcuts":
            compiles.setdefault(f"{f.__module__}.{f.__qualname__}", []).append(str(ev.data["args"]))

    def on_end(self, ev):
        pass

event.register("numba:compile", Count())
from lightcuts.cli import main
from lightcuts.integrators.lightcut import warm_kernels

main(["lights", "run.yaml", "--out", "lights.npz"])
warm_kernels()
print(json.dumps(compiles))
"""


def test_light_tracing_and_the_render_kernel_compile_each_function_once(tmp_path):
    (tmp_path / "run.yaml").write_text("scene: {builtin: cornell}\ncamera: {resolution: [8, 8]}\n"
                                       "lights: {direct: {count: 16}, indirect: {count: 64}}\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "cache"), NUMBA_OPT="0")
    r = subprocess.run([sys.executable, "-c", _PROBE], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    compiles = json.loads(r.stdout.strip().splitlines()[-1])
    # the probe saw both phases: the tracer's kernel and the render kernel
    assert "lightcuts.lights.indirect._trace_fused" in compiles
    assert "lightcuts.integrators.lightcut._render_band" in compiles
    twice = {name: sigs for name, sigs in compiles.items() if len(sigs) > 1}
    assert twice == {}, "compiled more than once (argument types per compile):\n" + "\n".join(
        f"{name}:\n  " + "\n  ".join(sigs) for name, sigs in twice.items())


def test_every_kernel_calling_the_caster_shares_one_set_of_compile_flags():
    """numba builds an ``@overload``'s implementation once per set of its callers' compile flags, so
    every kernel that calls the caster's intersect, occluded, packet_occluded or new_scratch is
    compiled with ``nogil=True, error_model="numpy"`` (lightcuts.accel.kernel_api): checked on the
    source of every module, including the integrators no cold-run test above compiles."""
    import ast

    names = {"intersect", "occluded", "packet_occluded", "new_scratch"}
    wrong = []
    for path in sorted((ROOT / "lightcuts").rglob("*.py")):
        if path.relative_to(ROOT / "lightcuts").parts[0] == "accel":
            continue  # the casters' own implementations
        for f in ast.walk(ast.parse(path.read_text())):
            if not isinstance(f, ast.FunctionDef):
                continue
            calls = {n.func.id for n in ast.walk(f) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
            if calls & names and not any("njit" in ast.unparse(d) for d in f.decorator_list):
                continue  # Python code calling the caster's Python API
            flags = " ".join(ast.unparse(d) for d in f.decorator_list)
            if calls & names and not ("nogil=True" in flags and "error_model='numpy'" in flags):
                wrong.append(f"{path.relative_to(ROOT)}:{f.lineno} {f.name}: {flags}")
    assert wrong == [], "\n".join(wrong)
