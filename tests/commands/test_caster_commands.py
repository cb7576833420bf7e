"""Every command with a non-Embree caster, named by name and as ``{type: ..., param: value}``: the
commands open, use and close any caster (``with`` blocks included), record its resolved parameters,
and refuse a parameter the caster does not declare before any work."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import lightcuts

from conftest import cli_recording_work

ROOT = Path(lightcuts.__file__).parents[1]
TINY = ("name: tiny\nscene: {builtin: cornell}\nlights: {direct: {count: 16}, indirect: {count: 40}}\n"
        "camera: {resolution: [12, 10]}\n")
#: The casters of these tests, as ``--set render.ray_caster=`` values, and their report.json records.
CASTERS = {
    "hug": {"type": "hug", "alpha": 0.01, "levels": 3},
    "{type: recursive-grid, maxp: 150}": {"type": "recursive-grid", "max_depth": 5, "maxp": 150},
}


def _cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "lightcuts", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture
def tiny(tmp_path):
    (tmp_path / "tiny.yaml").write_text(TINY)
    return tmp_path


@pytest.mark.slow
@pytest.mark.parametrize("spec", CASTERS)
def test_render(tiny, spec):
    r = _cli("render", "tiny.yaml", "--no-progress", "--out", "out", "--set", f"render.ray_caster={spec}", cwd=tiny)
    assert r.returncode == 0, r.stderr
    report = json.loads((tiny / "out" / "report.json").read_text())
    assert report["plugins"]["ray_caster"] == CASTERS[spec]


@pytest.mark.slow
@pytest.mark.parametrize("spec", CASTERS)
def test_reference(tiny, spec):
    pytest.importorskip("mitsuba")
    r = _cli("reference", "tiny.yaml", "--spp", "4", "--integrator", "direct", "--no-progress", "--out", "ref",
             "--set", f"render.ray_caster={spec}", cwd=tiny)
    assert r.returncode == 0, r.stderr
    assert (tiny / "ref" / "report.json").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("spec", CASTERS)
def test_compare(tiny, spec):
    r = _cli("compare", "tiny.yaml", "--builders", "divisive-6d,divisive-3d", "--pixels", "20", "--no-progress",
             "--out", "cmp", "--set", f"render.ray_caster={spec}", cwd=tiny)
    assert r.returncode == 0, r.stderr
    assert (tiny / "cmp" / "report.json").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("spec", CASTERS)
def test_accel(tiny, spec):
    r = _cli("accel", "tiny.yaml", "--casters", "embree,hug,recursive-grid-150", "--repeats", "1", "--no-progress",
             "--out", "acc", "--set", f"render.ray_caster={spec}", cwd=tiny)
    assert r.returncode == 0, r.stderr
    rows = json.loads((tiny / "acc" / "report.json").read_text())["rows"]
    assert [row["caster"] for row in rows] == ["embree", "hug", "recursive-grid-150"]
    assert rows[2]["maxp"] == 150 and all(row["eye_mismatch"] <= 2 for row in rows)


@pytest.mark.slow
def test_a_name_its_alias_and_its_mapping_give_the_same_bytes(tiny):
    images = []
    for i, spec in enumerate(("recursive-grid", "recursive-grid-50", "{type: recursive-grid, maxp: 50}")):
        r = _cli("render", "tiny.yaml", "--no-progress", "--out", f"r{i}", "--set", f"render.ray_caster={spec}",
                 cwd=tiny)
        assert r.returncode == 0, r.stderr
        images.append([(tiny / f"r{i}" / k).read_bytes() for k in ("image.exr", "image.png", "cutsize.png")])
    assert images[0] == images[1] == images[2]


@pytest.mark.slow
@pytest.mark.parametrize("spec, message", [
    ("{type: hug, maxp: 3}", "render.ray_caster.maxp: ray caster 'hug' has no parameter 'maxp' (it reads: alpha, levels)"),
    ("{type: grid, alpha: 0.1}", "render.ray_caster.alpha: ray caster 'grid' has no parameter 'alpha'"),
    ("{type: octree, maxp: 0}", "render.ray_caster.maxp: 0 is below the minimum 1"),
    ("{type: hug, alpha: 0}", "render.ray_caster.alpha: 0.0 is below the minimum"),
])
@pytest.mark.parametrize("command", ["render", "lights", "accel"])
def test_an_undeclared_parameter_is_one_line_before_any_work(tiny, spec, message, command):
    rc, calls, err = cli_recording_work([command, "tiny.yaml", "--set", f"render.ray_caster={spec}"], tiny)
    assert rc == 2 and calls == [] and len(err.strip().splitlines()) == 1, err
    assert err.startswith("error: ") and message in err, err
    assert sorted(p.name for p in tiny.iterdir()) == ["tiny.yaml"]
