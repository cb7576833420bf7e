"""``lightcuts accel``: every caster answers the same rays; a wrong caster is counted, not hidden."""

import json
from pathlib import Path

import numpy as np

from lightcuts.cli import main

ROOT = Path(__file__).parents[2]
SMALL = ["--set", "camera.resolution=[24,20]", "--set", "lights.indirect.count=500", "--repeats", "1",
         "--no-progress"]


def test_casters_side_by_side_and_a_wrong_one_is_counted(tmp_path, scratch_registries):
    from lightcuts.accel import RAY_CASTERS
    from lightcuts.accel.embree.embree import EmbreeCaster

    class MissesEveryOtherRay(EmbreeCaster):
        def intersect(self, org, dirs, tnear=0.0, tfar=np.inf):
            t, prim = super().intersect(org, dirs, tnear, tfar)
            prim[::2] = -1
            return t, prim

    RAY_CASTERS.register("misses", MissesEveryOtherRay, kernel_callable=False)
    out = tmp_path / "acc"
    assert main(["accel", str(ROOT / "configs/cornell.yaml"), "--casters", "embree,embreex,misses", "--out",
                 str(out), *SMALL]) == 0
    rows = json.loads((out / "report.json").read_text())["rows"]
    assert [r["caster"] for r in rows] == ["embree", "embreex", "misses"]
    w, h = 24, 20
    for r in rows:
        assert r["triangles"] == 38 and r["eye_rays"] == w * h and r["eye_s"] > 0 and r["shadows_s"] > 0
        assert 16 * w * h < r["shadow_image_rays"] <= 2 * 16 * w * h
    assert rows[1]["eye_mismatch"] == 0 and rows[1]["shadow_mismatch"] == 0
    # Most eye rays see the box: dropping every other hit is seen on about half the rays.
    assert 0.3 * w * h < rows[2]["eye_mismatch"] <= w * h // 2
    assert 0.3 * 16 * w * h < rows[2]["shadow_mismatch"]
    table = (out / "table.md").read_text()
    assert "| embreex | 38 |" in table and "E(cost)" not in table  # no caster here reports SAH statistics


def test_rooms_sweep(tmp_path):
    out = tmp_path / "sweep"
    assert main(["accel", str(ROOT / "configs/rooms.yaml"), "--sweep", "rooms", "--rooms", "1,2", "--casters",
                 "embree,hug,recursive-grid-50,recursive-grid-150", "--out", str(out), "--set",
                 "scene.procedural.triangles=12000", *SMALL]) == 0
    report = json.loads((out / "report.json").read_text())
    rows = report["rows"]
    assert [(r["rooms"], r["caster"]) for r in rows] == [
        (n, c) for n in (1, 2) for c in ("embree", "hug", "recursive-grid-50", "recursive-grid-150")]
    one, two = (next(r for r in rows if r["rooms"] == n and r["caster"] == "hug") for n in (1, 2))
    assert 1.8 < two["triangles"] / one["triangles"] < 2.2 and two["memory_bytes"] > one["memory_bytes"]
    assert all(r["eye_mismatch"] <= 2 for r in rows)  # the grids answer the eye rays as Embree does
    table = (out / "table.md").read_text()
    assert "HUG memory / recursive-grid-50" in table and table.count("| hug |") == 3
    assert (out / "sweep.png").read_bytes()[:4] == b"\x89PNG" and (out / "sweep.csv").is_file()


def test_sweep_needs_a_rooms_scene(tmp_path):
    from conftest import cli_recording_work

    rc, calls, err = cli_recording_work(["accel", str(ROOT / "configs/cornell.yaml"), "--sweep", "rooms",
                                         "--out", str(tmp_path / "s")], tmp_path)
    assert rc == 2 and calls == [] and len(err.strip().splitlines()) == 1 and "not a rooms scene" in err
