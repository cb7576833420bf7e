"""The Python API (lightcuts.load_config / render / compare): the same bytes as the CLI, nothing
written unless asked, and ``import lightcuts`` still loads no stage."""

import csv
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.report.images import read_exr

ROOT = Path(__file__).parents[2]
CORNELL = ROOT / "configs/cornell.yaml"
#: The shipped Cornell config at a small size, as --set arguments and as load_config overrides.
SMALL = {"camera.resolution": [64, 64], "lights.indirect.count": 2000, "lights.direct.count": 256}
SMALL_SET = [a for k, v in SMALL.items() for a in ("--set", f"{k}={json.dumps(v)}")]


def run_cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "lightcuts", *map(str, args)], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def cli_render(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "render"
    run_cli("render", CORNELL, "--out", out, "--no-progress", *SMALL_SET, cwd=ROOT)
    return out


@pytest.fixture(scope="module")
def api_render():
    return lightcuts.render(lightcuts.load_config(CORNELL, **SMALL), progress=False)


def test_render_gives_the_cli_pixels(cli_render, api_render):
    cli = read_exr(cli_render / "image.exr")
    assert api_render.image.dtype == np.float32 and api_render.image.shape == (64, 64, 3)
    assert np.array_equal(api_render.image, cli) and api_render.image.any()
    report = json.loads((cli_render / "report.json").read_text())
    assert api_render.cut_size.shape == (64, 64)
    assert float(api_render.cut_size.mean()) == report["cut_size_mean"]
    assert report.keys() == api_render.report.keys()
    for key in ("lights", "builder", "metric", "c", "eps", "resolution", "shadow_rays", "eye_rays", "scene"):
        assert api_render.report[key] == report[key], key


def test_save_writes_the_cli_files(cli_render, api_render, tmp_path):
    out = api_render.save(tmp_path / "mine")
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in cli_render.iterdir())
    for name in ("image.exr", "image.png", "cutsize.png"):
        assert (out / name).read_bytes() == (cli_render / name).read_bytes(), name


def test_repr_png_is_the_tone_mapped_image(cli_render, api_render):
    shown = np.asarray(Image.open(io.BytesIO(api_render._repr_png_())).convert("RGB"))
    assert np.array_equal(shown, np.asarray(Image.open(cli_render / "image.png").convert("RGB")))


def test_nothing_is_written_unless_asked(tmp_path):
    code = ("import lightcuts; cfg = lightcuts.load_config(%r, **%r); r = lightcuts.render(cfg, progress=False); "
            "c = lightcuts.compare(cfg, builders='divisive-3d', pixels=16, progress=False)"
            % (str(CORNELL), {**SMALL, "camera.resolution": [16, 16]}))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert list(tmp_path.iterdir()) == []


def test_overrides_dotted_and_double_underscore():
    a = lightcuts.load_config(CORNELL, **{"render.eps": 0.01, "camera.resolution": [32, 16]})
    b = lightcuts.load_config(CORNELL, render__eps=0.01, camera__resolution=[32, 16])
    assert a == b and a.render.eps == 0.01 and a.camera.resolution == [32, 16]
    assert lightcuts.load_config(CORNELL, **{"render.max_cut": 10 ** 3}).render.max_cut == 1000
    assert lightcuts.load_config(CORNELL).render.eps == 0.02
    with pytest.raises(LightcutsError, match=r"cornell.yaml: render.epz: unknown key"):
        lightcuts.load_config(CORNELL, render__epz=0.01)
    with pytest.raises(LightcutsError, match=r"render.eps.x: eps is not a section"):
        lightcuts.load_config(CORNELL, **{"render.eps.x": 1})


def test_overrides_index_list_entries(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "run.yaml").write_text("scene: {meshes: [{file: m.obj}, {file: m.obj, scale: 2}]}\n")
    cfg = lightcuts.load_config(tmp_path / "run.yaml", **{"scene.meshes.1.scale": 3, "scene.meshes.0.rotate": [0, 90, 0]})
    assert cfg.scene.meshes[1].scale == 3 and cfg.scene.meshes[0].rotate == [0, 90, 0]
    assert cfg.scene.meshes[0].scale == 1
    for key in ("scene.meshes.2.file", "scene.meshes.x.file"):
        with pytest.raises(LightcutsError, match=r"scene.meshes has 2 entries, '(2|x)' is not one of their indices"):
            lightcuts.load_config(tmp_path / "run.yaml", **{key: "m.obj"})
    with pytest.raises(LightcutsError, match=r"scene.meshes.0.file.x: file is not a section"):
        lightcuts.load_config(tmp_path / "run.yaml", **{"scene.meshes.0.file.x": 1})


def test_compare_rows_are_the_csv_rows(tmp_path):
    cfg = lightcuts.load_config(CORNELL, **{**SMALL, "camera.resolution": [24, 24]})
    c = lightcuts.compare(cfg, builders=["divisive-6d", "divisive-3d"], pixels=32, progress=False)
    assert [r["label"] for r in c.rows] == ["divisive-6d", "divisive-3d"]
    assert c.cut_sizes["divisive-3d"].shape == (24, 24) and c.images["divisive-6d"].shape == (24, 24, 3)
    out = c.save(tmp_path / "cmp")
    with open(out / "table.csv", newline="") as f:
        csv_rows = list(csv.DictReader(f))
    assert [list(r) for r in csv_rows] == [list(r) for r in c.rows]
    assert csv_rows == [{k: "" if v is None else str(v) for k, v in r.items()} for r in c.rows]
    assert c.rows[0]["cut_vs_divisive_6d"] == 1.0 and c.rows[1]["pixels_compared"] > 0
    assert (out / "table.md").read_text() == c.markdown()
    with pytest.raises(LightcutsError, match="builders: unknown builder 'nope'"):
        lightcuts.compare(cfg, builders="divisive-3d,nope")


def test_import_lightcuts_loads_no_stage():
    code = ("import sys, lightcuts; a = sorted(m for m in sys.modules if m.startswith('lightcuts')); "
            "lightcuts.load_config; b = sorted(m for m in sys.modules if m.startswith('lightcuts')); "
            "print(a); print(b); print(callable(lightcuts.render))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    before, after, is_callable = r.stdout.split("\n")[:3]
    assert eval(before) == ["lightcuts", "lightcuts.errors"]
    assert not [m for m in eval(after) if m.split(".")[1:2] not in ([], ["api"], ["pipeline"], ["config"], ["errors"], ["limits"])], after
    assert is_callable == "True"


def test_render_is_a_plain_function_and_the_stage_has_its_own_name():
    import types

    import lightcuts.api
    import lightcuts.integrators.lightcut

    assert lightcuts.render is lightcuts.api.render and isinstance(lightcuts.render, types.FunctionType)
    assert lightcuts.integrators.lightcut.render_image is not None
    assert type(sys.modules["lightcuts"]) is types.ModuleType  # no module class swapped in
