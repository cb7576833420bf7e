"""``lightcuts scaling --gather``: a row per (gather points, integrator) whose cut per pixel is what each
integrator's render evaluates per pixel, the same cut at one gather point, one-line errors before any work."""

import csv
import json
from pathlib import Path

import pytest

from conftest import cli_recording_work
from lightcuts.cli import main

ROOT = Path(__file__).parents[2]
CORNELL = str(ROOT / "configs/cornell.yaml")
#: A tiny Cornell box: 16 x 16 pixels, about 2,000 lights.
SMALL = {"camera.resolution": [16, 16], "lights.indirect.count": 1900, "lights.direct.count": 128}
SETS = [x for k, v in SMALL.items() for x in ("--set", f"{k}={json.dumps(v)}")]
EPS = 0.02  # configs/cornell.yaml's render.eps


@pytest.fixture(scope="module")
def gathered(tmp_path_factory):
    out = tmp_path_factory.mktemp("gather") / "g"
    assert main(["scaling", CORNELL, "--gather", "4,1", "--out", str(out), "--no-progress", *SETS]) == 0
    return out, list(csv.DictReader((out / "gather_scaling.csv").open()))


def test_a_row_per_gather_count_and_integrator(gathered):
    out, rows = gathered
    assert [(r["gather"], r["integrator"]) for r in rows] == [
        ("1", "lightcuts"), ("1", "multidimensional"), ("4", "lightcuts"), ("4", "multidimensional")]
    assert sorted(p.name for p in out.iterdir()) == ["gather_scaling.csv", "gather_scaling.png", "report.html"]
    assert (out / "gather_scaling.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for r in rows:
        assert float(r["image_s"]) > 0 and float(r["shadow_rays_per_pixel"]) > 0
        assert float(r["cut_per_gather"]) == pytest.approx(float(r["cut_per_pixel"]) / int(r["gather"]))
        assert (r["image_diff_median"] == "") == (r["integrator"] == "lightcuts")


def test_one_gather_point_is_the_lightcut(gathered):
    # With one gather point the multidimensional cut is the lightcut: the same nodes, an image within eps.
    _, rows = gathered
    lc, md = (r for r in rows if r["gather"] == "1")
    assert md["cut_per_pixel"] == lc["cut_per_pixel"] and md["shadow_rays_per_pixel"] == lc["shadow_rays_per_pixel"]
    assert float(md["image_diff_max"]) <= EPS


def test_cut_per_pixel_is_what_each_render_evaluates_per_pixel(gathered):
    # lightcuts: the mean cut per eye ray times the eye rays per pixel; multidimensional: its pairs per pixel.
    import lightcuts

    _, rows = gathered
    for r in rows:
        if r["gather"] != "4":
            continue
        cfg = lightcuts.load_config(CORNELL, **SMALL, **{"render.spp": 4, "render.integrator": r["integrator"]})
        report = lightcuts.render(cfg, progress=False).report
        per_ray = 4 if r["integrator"] == "lightcuts" else 1
        assert float(r["cut_per_pixel"]) == pytest.approx(report["cut_size_mean"] * per_ray, rel=1e-6)
        assert float(r["shadow_rays_per_pixel"]) == report["shadow_rays_per_pixel"]


@pytest.mark.parametrize("extra, message", [
    (["--gather", "0"], "--gather '0': expected comma-separated positive integers"),
    (["--gather", "x"], "--gather 'x': expected comma-separated positive integers"),
    (["--gather", "1,-4"], "--gather '1,-4': expected comma-separated positive integers"),
    (["--gather", "4", "--sizes", "1000"], "--gather: not combined with --sizes"),
    (["--gather", "4", "--render"], "--gather: not combined with --render"),
    (["--gather", "4", "--repeats", "2"], "--gather: not combined with --repeats"),
    (["--gather", "4", "--set", "camera.aperture=0.1", "--set", "render.integrator=multidimensional"],
     "--gather: camera.aperture 0.1: the lightcuts integrator"),
])
def test_bad_gather_options_one_line_before_any_work(tmp_path, capsys, monkeypatch, extra, message):
    import lightcuts.lights.generate
    import lightcuts.scene.build

    def no_work(*args, **kwargs):
        raise AssertionError("work started")

    monkeypatch.setattr(lightcuts.scene.build, "scene_from_config", no_work)
    monkeypatch.setattr(lightcuts.lights.generate, "lights_from_config", no_work)
    assert main(["scaling", CORNELL, "--out", str(tmp_path / "g"), "--no-progress", *extra]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {message}"), lines
    assert not (tmp_path / "g").exists()


@pytest.mark.slow
def test_bad_gather_value_from_the_command_line(tmp_path):
    rc, calls, err = cli_recording_work(["scaling", CORNELL, "--gather", "0", "--out", str(tmp_path / "g")], tmp_path)
    assert rc == 2 and calls == [] and err.strip() == "error: --gather '0': expected comma-separated positive integers"
    assert not (tmp_path / "g").exists()
