"""``lightcuts reference --renderer lightcuts``: the run against lightcuts' own path tracer (the exact
BRDF), which needs no Mitsuba; the runs it cannot render are refused before any work."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lightcuts.cli import main

ROOT = Path(__file__).resolve().parents[2]
SMALL = ["--set", "lights.indirect.count=1500", "--set", "lights.direct.count=128"]


def _cli(argv) -> int:
    return main([str(a) for a in argv])


def test_converging_run_against_the_exact_path_tracer(tmp_path):
    """The glossy Cornell box with compensation and passes has the path tracer's energy (within 3%
    at this size and these counts), and the files are the path tracer's. The crop leaves out the
    directly seen light, whose sub-pixel edges hold most of the frame's energy and need hundreds of
    eye rays to settle."""
    out = tmp_path / "ref"
    assert _cli(["reference", ROOT / "configs/cornell-glossy.yaml", "--renderer", "lightcuts", "--spp", 256,
                 "--out", out, "--no-progress", "--set", "render.compensation=true", "--set", "render.passes=4",
                 "--set", "render.representatives=stochastic", *SMALL, "--set", "camera.resolution=[32,32]",
                 "--set", "render.crop=[0,8,32,32]"]) == 0
    r = json.loads((out / "report.json").read_text())
    assert r["path_tracer"]["renderer"] == "lightcuts" and r["path_tracer"]["spp"] == 256
    assert "mitsuba" not in r and r["phong_approximated"] is False
    assert r["lightcuts"]["passes"] == 4 and r["lightcuts"]["compensation"] is True
    assert abs(r["comparison"]["energy_ratio"] - 1) < 0.03, r["comparison"]
    assert sorted(p.name for p in out.iterdir()) == ["lightcuts.exr", "lightcuts.png", "path.exr", "path.png",
                                                      "report.html", "report.json"]


def test_figures_leave_out_the_emitter_and_stand_beside_the_path_tracers_noise(tmp_path, capsys):
    """The whole Cornell box, its light in view: the light's pixels are left out of the figures,
    the path tracer's image is the mean of two independent halves, and each figure has the noise
    those halves measure beside it."""
    import numpy as np

    from lightcuts.accel import make_caster
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.config import load_config
    from lightcuts.integrators.path import path_trace
    from lightcuts.integrators.primary import emitter_mask
    from lightcuts.report.images import read_exr

    out, size = tmp_path / "ref", ["--set", "camera.resolution=[24,24]"]
    assert _cli(["reference", ROOT / "configs/cornell.yaml", "--renderer", "lightcuts", "--spp", 7, "--out", out,
                 "--no-progress", *SMALL, *size]) == 0
    r = json.loads((out / "report.json").read_text())
    c, pt = r["comparison"], r["path_tracer"]
    assert pt["spp"] == 8 and pt["half_seeds"] == [1, 0]  # 7 rounded up to two halves of 4; seeds 1 and 1 ^ 1
    cfg = load_config(ROOT / "configs/cornell.yaml", SMALL[1::2] + size[1::2])
    scene = plan_run(cfg).scene()
    with make_caster(scene) as caster:
        mask = emitter_mask(scene, caster)
        halves = [path_trace(scene, caster, spp=4, seed=s)[0] for s in (1, 0)]
    np.testing.assert_array_equal(read_exr(out / "path.exr"), (halves[0] + halves[1]) / 2)
    assert c["masked_pixels"] == mask.sum() > 0 and c["pixel"]["pixels"] <= 24 * 24 - mask.sum()
    assert c["energy_ratio"] != c["energy_ratio_frame"]
    noise = c["reference_noise"]
    assert noise["pixel"]["pixels"] == c["pixel"]["pixels"] and noise["energy_ratio"] > 0
    assert 0 < noise["pixel"]["median"] and 0 < noise["block8"]["median"]
    assert "emitter" in r["emitter_mask"]
    text = (out / "report.html").read_text()
    data = json.loads(text.split('id="lc-data">', 1)[1].split("</script>", 1)[0])
    assert [layer["name"] for layer in data["layers"]] == ["lightcuts", "path"] and data["reference"] == 1
    assert data["mask"]["shape"] == [24, 24] and "noise" in text
    printed = capsys.readouterr().out
    assert f"{mask.sum()} pixels seeing an emitter directly left out" in printed
    assert f"median {100 * c['pixel']['median']:.2f}% (noise {100 * noise['pixel']['median']:.2f}%)" in printed


def test_the_path_integrator_renders_the_reference_commands_path_image(tmp_path):
    """``lightcuts render`` with ``render.integrator: path`` and ``lightcuts reference --renderer
    lightcuts`` at the same seed and samples per pixel give the same image file, byte for byte:
    one path tracer, whichever command runs it (one sample per pixel: above it the reference is the
    mean of two independent halves)."""
    common = ["--no-progress", "--set", "seed=7", "--set", "camera.resolution=[24,20]",
              "--set", "render.crop=[2,3,22,17]", *SMALL]
    assert _cli(["reference", ROOT / "configs/cornell.yaml", "--renderer", "lightcuts", "--spp", 1,
                 "--out", tmp_path / "ref", *common]) == 0
    assert _cli(["render", ROOT / "configs/cornell.yaml", "--set", "render.integrator=path", "--set", "render.spp=1",
                 "--out", tmp_path / "render", *common]) == 0
    assert (tmp_path / "render" / "image.exr").read_bytes() == (tmp_path / "ref" / "path.exr").read_bytes()
    r = json.loads((tmp_path / "render" / "report.json").read_text())
    assert r["cut_size_unit"] == "path vertices per eye ray" and r["resolution"] == [20, 14]
    assert 1 <= r["cut_size_mean"] <= 64 and r["shadow_rays_per_pixel"] > 0


def test_a_path_run_against_the_path_tracer_makes_no_lights_or_trees(tmp_path, monkeypatch):
    """``lightcuts reference`` of a run whose integrator is the path tracer renders lightcuts' side
    without the config's lights and trees (cornell's 100,000 VPLs): none made, none reported, none timed."""
    from lightcuts.pipeline.plan import Plan

    def refuse(*args, **kwargs):
        raise AssertionError("made the config's lights or trees")

    monkeypatch.setattr(Plan, "lights", refuse)
    monkeypatch.setattr(Plan, "trees", refuse)
    out = tmp_path / "ref"
    assert _cli(["reference", ROOT / "configs/cornell.yaml", "--renderer", "lightcuts", "--spp", 1, "--out", out,
                 "--no-progress", "--set", "camera.resolution=[12,12]", "--set", "render.passes=2",
                 "--set", "render.integrator={type: path, max_depth: 4}"]) == 0
    lc = json.loads((out / "report.json").read_text())["lightcuts"]
    assert lc["lights"] == {} and lc["lights_indirect"] == 0
    assert lc["image_seconds_parts"]["lights"] == lc["image_seconds_parts"]["trees"] == 0.0
    assert lc["image_seconds"] == lc["image_seconds_parts"]["passes"] > 0


@pytest.mark.parametrize("config, argv, message", [
    ("sun-env.yaml", [], "--renderer lightcuts: its path tracer renders emitting triangles"),
    ("cornell.yaml", ["--integrator", "direct"], "--integrator direct needs --renderer mitsuba"),
    ("cornell.yaml", ["--max-depth", "3"], "--max-depth: goes with --renderer mitsuba"),
])
def test_runs_the_path_tracer_cannot_render_are_refused(tmp_path, capsys, config, argv, message):
    assert _cli(["reference", ROOT / "configs" / config, "--renderer", "lightcuts", *argv,
                 "--out", tmp_path / "ref"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "ref").exists()
