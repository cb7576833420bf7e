"""The command line as a user meets it: one-line errors, exit status 2, nothing written."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import cli_recording_work

ROOT = Path(__file__).parents[2]


def run_cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lightcuts", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


BAD = [
    ("scene: {builtin: cornell}\nrender: {epss: 0.1}\n", "render.epss: unknown key"),
    ("scene: {builtin: cornell}\nrender: {spp: many}\n", "render.spp:"),
    ("scene: {meshes: [{file: missing.obj}]}\n", "scene.meshes.0.file: no such file"),
    ("scene: {builtin: cornell}\ntree: {builder: nope}\n", "unknown builder 'nope'"),
    ("scene: {builtin: cornell}\ntree: {metric: nope}\n", "unknown metric 'nope'"),
]


@pytest.mark.parametrize("command", ["render", "lights", "tree"])
@pytest.mark.parametrize("text, expected", BAD[:3])
def test_bad_config_one_line_nothing_written(tmp_path, command, text, expected):
    (tmp_path / "run.yaml").write_text(text)
    r = run_cli(command, "run.yaml", cwd=tmp_path)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: run.yaml: "), r.stderr
    assert expected in lines[0]
    assert "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.yaml"]


@pytest.mark.parametrize("text, expected", BAD[3:])
def test_unknown_names_fail_before_rendering(tmp_path, text, expected):
    """The error comes from the plan step: no scene, lights or tree were made, nothing written."""
    (tmp_path / "run.yaml").write_text(text + "lights: {direct: {count: 16}}\ncamera: {resolution: [8, 8]}\n")
    rc, calls, err = cli_recording_work(["render", "run.yaml", "--no-progress"], tmp_path)
    assert rc == 2, err
    assert calls == []
    assert expected in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "renders").exists()


def test_set_override_error_names_the_key(tmp_path):
    (tmp_path / "run.yaml").write_text("scene: {builtin: cornell}\n")
    r = run_cli("render", "run.yaml", "--set", "render.eps=-3", cwd=tmp_path)
    assert r.returncode == 2 and "render.eps" in r.stderr and "Traceback" not in r.stderr


def test_help_lists_commands(tmp_path):
    r = run_cli("--help", cwd=tmp_path)
    assert r.returncode == 0
    for c in ("lights", "tree", "scaling", "render"):
        assert c in r.stdout


def test_compile_notice_on_a_cold_cache_only(tmp_path):
    """The first-compile notice appears once when numba compiles, and not when it loads its cache."""
    (tmp_path / "kern.py").write_text("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n\n"
                                      "@njit(cache=True)\ndef g(x):\n    return f(x) * 2\n")
    code = ("import sys; sys.path.insert(0, sys.argv[1])\n"
            "from lightcuts.pipeline.warmup import announce_compiles, NOTICE\nannounce_compiles()\n"
            "import kern; kern.g(1.0); kern.f(2)\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    runs = [subprocess.run([sys.executable, "-c", code, str(tmp_path)], env=env, capture_output=True, text=True,
                           timeout=300) for _ in range(2)]
    notice = ("compiling numba kernels once (light tracing, tree builder, renderer); later runs load them "
              "from the cache; report.json gives the seconds spent compiling")  # no figure: it is the machine's
    assert runs[0].returncode == 0 and runs[0].stderr.strip().splitlines() == [notice], runs[0].stderr
    assert runs[1].returncode == 0 and runs[1].stderr.strip() == "", runs[1].stderr


def test_help_lists_every_command_in_plain_text(capsys):
    from lightcuts.cli import main
    from lightcuts.commands import COMMANDS

    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    description = out.split("positional arguments")[0].split("\n\n", 1)[1]
    assert all(name in description for name in COMMANDS) and "``" not in out


def test_a_render_with_overrides_keeps_the_configs_own_run(tmp_path, monkeypatch):
    """``--set`` runs go to renders/<name>-set-<hash>/: the config's renders/<name>/ stays, the
    same overrides reuse their folder and other overrides get another."""
    from lightcuts.cli import main
    from lightcuts.io import run_dir

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run.yaml").write_text("name: r\nscene: {builtin: cornell}\ncamera: {resolution: [8, 8]}\n"
                                       "lights: {direct: {count: 16}}\n")
    assert main(["render", "run.yaml", "--no-progress"]) == 0
    own = (tmp_path / "renders" / "r" / "image.exr").read_bytes()
    small = ["--set", "camera.resolution=[4,4]"]
    assert main(["render", "run.yaml", "--no-progress", *small]) == 0
    assert (tmp_path / "renders" / "r" / "image.exr").read_bytes() == own
    folder = tmp_path / run_dir("r", ["camera.resolution=[4,4]"])
    assert folder.parent == tmp_path / "renders" and folder.name.startswith("r-set-")
    assert (folder / "image.exr").is_file()
    assert run_dir("r", ["camera.resolution=[4,4]"]) != run_dir("r", ["camera.resolution=[5,5]"])
    assert sorted(p.name for p in (tmp_path / "renders").iterdir()) == ["r", folder.name]


def test_compile_seconds_count_numba_compiles_only():
    """The clock behind report.json's ``compile_seconds``: a fresh kernel's compile adds its time, a
    call of a compiled kernel adds nothing."""
    import numba

    from lightcuts.pipeline.warmup import announce_compiles, compile_seconds

    announce_compiles()
    before = compile_seconds()

    @numba.njit
    def fresh(x):
        return x * 2.0 + 1.0

    assert fresh(1.0) == 3.0
    spent = compile_seconds() - before
    assert spent > 0.0
    assert fresh(2.0) == 5.0 and compile_seconds() - before == spent


def test_a_compile_inside_a_phase_is_reported_apart_from_its_work(tmp_path, monkeypatch):
    """report.json's preprocess_seconds, build_seconds and render_seconds leave out what numba spends
    compiling inside them. A cold cache is stood in for by numba's own ``numba:compile`` event (what
    numba fires around a compile, and what compile_seconds counts) around a sleep of SLOW seconds,
    injected into the lights, the trees and the first render call of a warm run; against the same
    run without it, each phase's work is unchanged and its compile figure grows by SLOW. (A real cold
    run in a subprocess with an empty NUMBA_CACHE_DIR compiles for minutes here.)"""
    import time

    from numba.core import event

    import lightcuts.integrators.registry as registry
    from lightcuts.cli import main
    from lightcuts.pipeline.plan import Plan

    slow = 1.0

    def compile_first(call):
        def wrapped(*args, **kwargs):
            with event.trigger_event("numba:compile"):
                time.sleep(slow)
            return call(*args, **kwargs)
        return wrapped

    def compiled_kernel(*args, **kwargs):  # the integrator's first render call compiles
        integrator = make_integrator(*args, **kwargs)
        plain = integrator.render

        def render(*a, **k):
            integrator.render = plain
            return compile_first(plain)(*a, **k)
        integrator.render = render
        return integrator

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run.yaml").write_text("name: cc\nscene: {builtin: cornell}\ncamera: {resolution: [8, 8]}\n"
                                       "lights: {direct: {count: 16}}\n")
    reports = []
    for cold in (False, False, True):  # the first loads (or compiles) the kernels into this process
        if cold:
            make_integrator = registry.make_integrator
            monkeypatch.setattr(Plan, "lights", compile_first(Plan.lights))
            monkeypatch.setattr(Plan, "trees", compile_first(Plan.trees))
            monkeypatch.setattr(registry, "make_integrator", compiled_kernel)
        assert main(["render", "run.yaml", "--no-progress"]) == 0
        reports.append(json.loads((tmp_path / "renders" / "cc" / "report.json").read_text()))
    warm, cold = reports[1:]
    for phase, work in (("preprocess", "preprocess_seconds"), ("build", "build_seconds"),
                        ("render", "render_seconds")):
        assert cold["compile_seconds"][phase] - warm["compile_seconds"][phase] >= slow, phase
        assert cold[work] - warm[work] < slow / 2, phase
    assert cold["jit_seconds"] == cold["compile_seconds"]["render"]


def test_render_names_each_phase_and_keeps_compiling_apart(tmp_path, monkeypatch, capsys):
    from lightcuts.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run.yaml").write_text("name: ph\nscene: {builtin: cornell}\ncamera: {resolution: [8, 8]}\n"
                                       "lights: {direct: {count: 16}}\n")
    assert main(["render", "run.yaml"]) == 0
    err = capsys.readouterr().err
    where = [err.index(f"ph: {name} ...") for name in ("scene", "lights", "trees", "render")]
    assert where == sorted(where)
    report = json.loads((tmp_path / "renders" / "ph" / "report.json").read_text())
    compiling = report["compile_seconds"]
    assert set(compiling) == {"preprocess", "build", "render"} and compiling["render"] == report["jit_seconds"]
    assert min(compiling.values()) >= 0 and report["preprocess_seconds"] >= 0 and report["build_seconds"] >= 0
    assert main(["render", "run.yaml", "--no-progress"]) == 0
    assert "ph: scene" not in capsys.readouterr().err
