"""The Mitsuba 3 reference renderer (lightcuts.mitsuba, ``lightcuts reference``): the export keeps
the scene (triangles, camera, emitted power), Mitsuba's direct light matches lightcuts' in energy,
the environment map has the same orientation, and a missing Mitsuba gives one line and exit 2.
Tests that render skip only where Mitsuba cannot be imported."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lightcuts.lights.lightset import LUMINANCE
from lightcuts.mitsuba.export import envmap_for_mitsuba, phong_alpha, phong_bsdf

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "configs" / "cornell.yaml"


@pytest.fixture
def mi():
    pytest.importorskip("mitsuba")
    from lightcuts.mitsuba import load_mitsuba

    return load_mitsuba()


def _cli(argv) -> int:
    from lightcuts.cli import main

    return main([str(a) for a in argv])


def _report(folder: Path) -> dict:
    return json.loads((folder / "report.json").read_text())


def test_phong_blend_sums_to_lightcuts_reflectances():
    rd, rs, n = np.array([0.45, 0.44, 0.42]), np.array([0.25, 0.2, 0.25]), 60.0
    b = phong_bsdf(rd, rs, n)
    w = b["weight"]
    np.testing.assert_allclose((1 - w) * np.array(b["bsdf_0"]["reflectance"]["value"]), rd, rtol=1e-12)
    np.testing.assert_allclose(w * np.array(b["bsdf_1"]["specular_reflectance"]["value"]), rs, rtol=1e-12)
    assert b["bsdf_1"]["alpha"] == pytest.approx(math.sqrt(1 / 121)) == phong_alpha(n)
    assert phong_bsdf(rd, [0, 0, 0], 0)["type"] == "diffuse"  # no specular: exact Lambert


def test_envmap_resampling_keeps_cells_and_their_integral():
    rng = np.random.default_rng(0)
    px = rng.random((6, 10, 3)).astype(np.float32)
    k = 4
    m = envmap_for_mitsuba(px, k)
    assert m.shape == (6 * k + 1, 10 * k, 3)
    # grid points inside a cell carry the cell's value; on a horizontal cell edge the mean
    np.testing.assert_array_equal(m[1:k, ::k], np.broadcast_to(px[0], (k - 1, 10, 3)))
    np.testing.assert_allclose(m[k, ::k], 0.5 * (px[0] + px[1]), rtol=1e-6)
    np.testing.assert_array_equal(m[-1, ::k], px[-1])
    # bilinear between the rows integrates (per unit v) to the piecewise-constant map's integral
    trapezoid = 0.5 * (m[1:] + m[:-1]).mean(axis=0)
    np.testing.assert_allclose(trapezoid[::k], px.mean(axis=0), rtol=1e-5)


def test_export_keeps_triangles_camera_and_emitted_power(mi):
    from lightcuts.config import load_config
    from lightcuts.mitsuba.export import emitted_power, mitsuba_emitted_power
    from lightcuts.mitsuba.render import load_scene, sample_count
    from lightcuts.scene.build import scene_from_config

    cfg = load_config(ROOT / "configs" / "cornell-glossy.yaml", ["camera.resolution=[40,30]",
                                                                 "render.crop=[4,2,36,28]"])
    scene = scene_from_config(cfg)
    ms = load_scene(cfg, scene, None, spp=16, integrator="path")
    assert sum(s.face_count() for s in ms.shapes()) == scene.n_faces
    assert sum(s.surface_area() for s in ms.shapes()) == pytest.approx(scene.face_areas.sum(), rel=1e-5)
    assert len(ms.emitters()) == 1
    np.testing.assert_allclose(mitsuba_emitted_power(ms), emitted_power(scene), rtol=1e-5)
    np.testing.assert_allclose(emitted_power(scene), math.pi * 105 * 130 * np.array([17, 12, 4]), rtol=1e-9)

    cam = scene.camera
    sensor = ms.sensors()[0]
    m = np.array(sensor.world_transform().matrix, np.float64)
    np.testing.assert_allclose(m[:3, 3], cam.position, rtol=1e-6)
    right, up, fwd = cam.frame()
    np.testing.assert_allclose(m[:3, 2], fwd, atol=1e-6)  # Mitsuba's camera looks along its local +z
    np.testing.assert_allclose(m[:3, 1], up, atol=1e-6)
    np.testing.assert_allclose(m[:3, 0], -right, atol=1e-6)  # local +x is the image's left
    x_fov = float(mi.traverse(sensor)["x_fov"])
    y_fov = 2 * math.degrees(math.atan(math.tan(math.radians(x_fov) / 2) * cam.height / cam.width))
    assert y_fov == pytest.approx(cam.fov, rel=1e-5)
    assert list(sensor.film().size()) == [40, 30]
    assert list(sensor.film().crop_size()) == [32, 26] and list(sensor.film().crop_offset()) == [4, 2]
    assert sample_count(ms) == 16



@pytest.mark.parametrize("focus", [None, 900.0])
def test_a_lens_exports_as_a_thin_lens_focused_where_lightcuts_focuses(mi, focus):
    # camera.aperture > 0 (the multidimensional integrator's lens): Mitsuba's thinlens, the same lens
    # radius and plane of focus (perpendicular to the view axis at focus_distance, else at look_at).
    from lightcuts.config import load_config
    from lightcuts.mitsuba.render import load_scene
    from lightcuts.scene.build import scene_from_config

    sets = ["camera.resolution=[16,12]", "camera.aperture=20", "render.integrator=multidimensional"]
    cfg = load_config(CORNELL, sets + ([f"camera.focus_distance={focus}"] if focus else []))
    scene = scene_from_config(cfg)
    params = mi.traverse(load_scene(cfg, scene, None, spp=4).sensors()[0])
    cam = scene.camera
    assert params["aperture_radius"] == pytest.approx(20.0)
    expected = focus or float(np.linalg.norm(np.subtract(cam.look_at, cam.position)))
    assert params["focus_distance"] == pytest.approx(expected, rel=1e-6)
    pinhole = mi.traverse(load_scene(load_config(CORNELL, sets[:1]), scene, None, spp=4).sensors()[0])
    assert "aperture_radius" not in pinhole


def test_cornell_direct_light_matches_mitsuba(mi, tmp_path, capsys):
    """Direct light only, lightcuts (1024 direct lights, no VPLs) against Mitsuba's direct
    integrator: within 1% in energy. The crop leaves out the directly seen light, whose
    sub-pixel edges (69% of the full frame's energy at 64x64) need hundreds of samples on both
    sides to settle to 1%."""
    out = tmp_path / "ref"
    assert _cli(["reference", CORNELL, "--integrator", "direct", "--spp", 256, "--out", out, "--no-progress",
                 "--set", "camera.resolution=[64,64]", "--set", "render.crop=[0,16,64,64]",
                 "--set", "render.spp=16"]) == 0
    r = _report(out)
    assert r["lightcuts"]["lights_indirect"] == 0 and r["lightcuts"]["lights"] == {"oriented": 1024}
    # two independent halves of at least 128 spp each (132: the next count Mitsuba's multi-jittered sampler factors)
    assert r["mitsuba"]["variant"] == "scalar_rgb" and r["mitsuba"]["spp"] == 264
    assert r["mitsuba"]["half_seeds"] == [1, 0] and "reference_noise" in r["comparison"]
    c = r["comparison"]
    assert abs(c["energy_ratio"] - 1) < 0.01, c
    assert c["block8"]["median"] < 0.02, c
    assert sorted(p.name for p in out.iterdir()) == ["lightcuts.exr", "lightcuts.png", "mitsuba.exr",
                                                      "mitsuba.png", "report.html", "report.json"]
    assert "energy lightcuts/Mitsuba" in capsys.readouterr().out


def test_sun_and_sky_direct_light_matches_mitsuba(mi, tmp_path):
    """A floor under the sun and a rotated, scaled procedural sky: the directional lights carry the
    same irradiance as Mitsuba's directional and envmap emitters."""
    (tmp_path / "floor.obj").write_text("v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 3 2\nf 1 4 3\n")
    (tmp_path / "run.yaml").write_text(
        "name: sky\nseed: 3\nscene: {meshes: [{file: floor.obj, material: {albedo: [0.6, 0.5, 0.4]}}]}\n"
        "camera: {position: [0, 4, 0.01], look_at: [0, 0, 0], up: [0, 1, 0], fov: 40, resolution: [32, 32]}\n"
        "lights:\n  direct: {count: 0}\n  sun: {direction: [0.3, 0.8, 0.2], irradiance: [3, 2, 1]}\n"
        "  environment: {procedural: {sun_irradiance: 0}, count: 2048, rotate: 30, scale: 2}\n")
    out = tmp_path / "ref"
    assert _cli(["reference", tmp_path / "run.yaml", "--integrator", "direct", "--spp", 64, "--out", out,
                 "--no-progress"]) == 0
    c = _report(out)["comparison"]
    assert abs(c["energy_ratio"] - 1) < 0.01, c


def test_environment_map_orientation_matches(mi):
    """Eye rays that miss: Mitsuba's background equals lightcuts' map lookup along the same rays
    (a rotated, scaled map of random cells); 5 degrees more rotation would not."""
    from lightcuts.config.schema import config_from_dict
    from lightcuts.lights.environment import EnvironmentMap
    from lightcuts.mitsuba.render import render_mitsuba
    from lightcuts.integrators.camera import eye_rays
    from lightcuts.scene.scene import Camera, Scene

    rng = np.random.default_rng(3)
    pixels = (2 * rng.random((8, 16, 3))).astype(np.float32)
    env = EnvironmentMap(pixels, rotate=37.0, scale=1.5)
    cam = Camera([0, 0, 0], [1.0, 0.3, 0.5], [0, 1, 0], 80.0, 48, 32)
    scene = Scene([[0, 0, 10], [0.01, 0, 10], [0, 0.01, 10]], [[0, 1, 2]], 0.5, 0, 0, 0, cam)  # behind the camera
    cfg = config_from_dict({"scene": {"builtin": "cornell"}})
    image, seconds = render_mitsuba(cfg, scene, env, spp=64, integrator="direct")
    assert image.shape == (32, 48, 3) and image.dtype == np.float32 and seconds > 0
    _, dirs = eye_rays(cam, spp=64, seed=1)
    ref = image.astype(np.float64) @ LUMINANCE

    def error(e):
        lum = e.radiance(dirs.reshape(-1, 3)).reshape(dirs.shape).mean(axis=2) @ LUMINANCE
        return np.abs(lum - ref) / ref

    rel = error(env)
    assert rel.mean() < 0.01 and np.percentile(rel, 90) < 0.02, (rel.mean(), np.percentile(rel, 90))
    assert error(EnvironmentMap(pixels, rotate=42.0, scale=1.5)).mean() > 0.05


def test_spp_for_seconds_follows_the_time(mi):
    from lightcuts.config import load_config
    from lightcuts.mitsuba.render import spp_for_seconds
    from lightcuts.scene.build import scene_from_config

    cfg = load_config(CORNELL, ["camera.resolution=[16,16]"])
    scene = scene_from_config(cfg)
    short = spp_for_seconds(cfg, scene, None, 1e-6, "direct")
    long = spp_for_seconds(cfg, scene, None, 100.0, "direct")
    assert short == 1 and isinstance(long, int) and long > 1000


def test_missing_mitsuba_is_one_line_and_exit_2(tmp_path):
    code = ("import sys; sys.modules['mitsuba'] = None\n"
            "from lightcuts.cli import main\n"
            f"sys.exit(main(['reference', {str(CORNELL)!r}, '--out', {str(tmp_path / 'ref')!r}]))\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and lines[0].endswith("pip install 'lightcuts[mitsuba]'")
    assert not (tmp_path / "ref").exists()


def test_a_new_render_keeps_the_nested_reference(tmp_path):
    """renders/<name>/reference/ survives the render that replaces renders/<name>/."""
    from lightcuts.io import SUBRUN_FOLDERS, check_output_dir, output_set

    run = tmp_path / "renders" / "x"
    with output_set(run / "reference") as tmp:
        (tmp / "report.json").write_text("{}")
    check_output_dir(run, "name")  # a folder holding only a nested reference is a run's folder
    with output_set(run, keep=SUBRUN_FOLDERS) as tmp:  # as lightcuts render writes its set
        (tmp / "image.exr").write_text("new")
    assert sorted(p.name for p in run.iterdir()) == ["image.exr", "reference"]
    assert (run / "reference" / "report.json").read_text() == "{}"
    assert not [p for p in run.parent.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("option, value", [("--spp", 0), ("--max-depth", 0), ("--max-depth", -2)])
def test_bad_options_are_one_line_errors(tmp_path, capsys, option, value):
    assert _cli(["reference", CORNELL, option, value, "--out", tmp_path / "ref"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {option}: {value}")
    assert not (tmp_path / "ref").exists()


SMALL = ["--set", "camera.resolution=[24,24]", "--set", "lights.indirect.count=1500",
         "--set", "lights.direct.count=128"]


def test_reference_curve_measures_both_renderers_at_the_same_times(mi, tmp_path, capsys):
    out = tmp_path / "curve"
    assert _cli(["reference", CORNELL, "--curve", "--passes", 3, "--spp", 16, "--out", out, "--no-progress",
                 "--set", "render.compensation=true", *SMALL]) == 0
    r = _report(out)
    rows = r["rows"]
    lc = [x for x in rows if x["method"] == "lightcuts"]
    ms = [x for x in rows if x["method"] == "mitsuba"]
    assert [x["passes"] for x in lc] == [1, 2, 3] and len(ms) == 3
    assert all(a["seconds"] < b["seconds"] for a, b in zip(lc, lc[1:]))
    assert all(x["spp"] >= 1 and 0.8 < x["energy_ratio"] < 1.2 for x in ms)
    assert set(r["slope"]) == {"pixel_median", "block8_median"} and len(r["verdict"]) == 3
    assert r["lightcuts"]["compensation"] is True and r["reference"]["spp"] == 16
    csv = (out / "curve.csv").read_text().splitlines()
    assert csv[0].startswith("method,passes,spp,seconds") and len(csv) == 7
    assert sorted(p.name for p in out.iterdir()) == ["curve.csv", "curve.png", "lightcuts.exr", "lightcuts.png",
                                                      "mitsuba.exr", "mitsuba.png", "report.html", "report.json"]
    assert "slope" in capsys.readouterr().out


def test_reference_split_has_a_row_per_remedy(mi, tmp_path):
    from lightcuts.pipeline.convergence import SPLIT_ROWS

    out = tmp_path / "split"
    assert _cli(["reference", CORNELL, "--split", "--passes", 2, "--spp", 16, "--out", out, "--no-progress",
                 *SMALL]) == 0
    rows = _report(out)["rows"]
    assert [x["label"] for x in rows] == [label.format(passes=2) for label, *_ in SPLIT_ROWS]
    assert all(0.7 < x["energy_ratio"] < 1.3 for x in rows), rows
    assert len((out / "split.csv").read_text().splitlines()) == len(SPLIT_ROWS) + 1


@pytest.mark.parametrize("argv, message", [
    (["--passes", "4"], "--passes: goes with --curve or --split"),
    (["--curve", "--integrator", "direct"], "--curve: compares with the path tracer"),
    (["--curve", "--passes", "0"], "--passes: 0 must be an integer from 1 to"),
])
def test_bad_study_options_are_one_line_errors(tmp_path, capsys, argv, message):
    assert _cli(["reference", CORNELL, *argv, "--out", tmp_path / "ref"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "ref").exists()


def test_the_curve_helpers():
    from lightcuts.pipeline.convergence import loglog_slope, pass_counts

    assert pass_counts(1) == [1] and pass_counts(64) == [1, 2, 4, 8, 16, 32, 64] and pass_counts(6) == [1, 2, 4, 6]
    t = np.array([1.0, 2.0, 4.0, 8.0])
    assert loglog_slope(t, 3.0 * t ** -0.5) == pytest.approx(-0.5)
    assert loglog_slope([1.0], [1.0]) is None and loglog_slope([1.0, 2.0], [0.0, 1.0]) is None


def test_lightcuts_does_not_import_mitsuba_until_used():
    code = ("import sys, lightcuts.cli, lightcuts.commands.reference, lightcuts.mitsuba.render\n"
            "lightcuts.cli.build_parser()\n"
            "print('mitsuba' in sys.modules, 'drjit' in sys.modules)\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0 and r.stdout.split() == ["False", "False"], r.stderr


def test_a_textured_quad_renders_as_in_mitsuba(mi, tmp_path):
    """The checkerboard quad of tests/scene/test_textures.py (one square odd) under a sun: Mitsuba's
    image (bitmap texture, flipped v) matches lightcuts' per 8 x 8 block, so every square lands
    where lightcuts puts it, with its value."""
    from PIL import Image

    from lightcuts.mitsuba.render import render_mitsuba
    from lightcuts.scene.build import scene_from_config
    import lightcuts

    i = np.arange(32) // 8
    tex = np.where(((i[:, None] + i[None, :]) % 2 == 0)[:, :, None], np.array([200, 50, 50], np.uint8),
                   np.array([30, 120, 220], np.uint8)).astype(np.uint8)
    tex[:8, :8] = [250, 250, 40]  # one square unlike the others: a flip or a mirror shows
    Image.fromarray(tex).save(tmp_path / "tex.png")
    (tmp_path / "quad.obj").write_text(
        "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (tmp_path / "quad.mtl").write_text("newmtl m\nKd 0.7 0.8 0.9\nmap_Kd tex.png\n")
    (tmp_path / "run.yaml").write_text(
        "scene: {meshes: [{file: quad.obj}]}\n"
        "camera: {position: [0, 0, 3], look_at: [0, 0, 0], up: [0, 1, 0], fov: 30, resolution: [32, 32]}\n"
        "lights: {sun: {direction: [0, 0.3, 1], irradiance: [3, 3, 3]}}\n")
    cfg = lightcuts.load_config(tmp_path / "run.yaml")
    ours = lightcuts.render(cfg, progress=False).image.astype(np.float64)
    theirs, _ = render_mitsuba(cfg, scene_from_config(cfg), None, spp=64, integrator="direct")
    # pixel centres' texture coordinates; compare the pixels a texel and a half away from any square's edge
    t = 3 * math.tan(math.radians(15))
    c = (2 * (np.arange(32) + 0.5) / 32 - 1) * t
    u, v = np.meshgrid((c + 1) / 2, (1 - c) / 2)  # image rows run down, v up
    frac = lambda x: np.abs((4 * x) - np.round(4 * x)) / 4  # noqa: E731
    inside = (frac(u) > 1.5 / 32) & (frac(v) > 1.5 / 32)
    assert inside.sum() > 300
    np.testing.assert_allclose(theirs[inside], ours[inside], rtol=0.02)
    odd = inside & (u < 0.25) & (v > 0.75)  # the odd square is at the texture's top left
    assert odd.sum() > 0 and np.all(ours[odd, 2] < 0.1)
