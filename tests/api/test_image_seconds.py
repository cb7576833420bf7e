"""report.json's image_seconds: from the loaded scene to the finished image (lights, trees, every
pass), compiling left out, the sum of its parts; and the clamp radius each pass used."""

import time
from pathlib import Path

import pytest

import lightcuts

CORNELL = Path(__file__).resolve().parents[2] / "configs" / "cornell.yaml"
SMALL = {"camera.resolution": [12, 12], "lights.direct.count": 64, "lights.indirect.count": 3000}


def _render(**over):
    return lightcuts.render(lightcuts.load_config(CORNELL, **{**SMALL, **over})).report


def test_image_seconds_is_lights_trees_and_every_pass():
    r = _render(**{"render.passes": 3})
    parts = r["image_seconds_parts"]
    assert set(parts) == {"lights", "trees", "passes"} and min(parts.values()) > 0
    assert r["image_seconds"] == pytest.approx(parts["lights"] + parts["trees"] + parts["passes"], rel=1e-12)
    assert parts["passes"] == pytest.approx(sum(p["seconds"] for p in r["passes"]), rel=1e-12)
    assert parts["trees"] == r["build_seconds"]
    assert parts["lights"] <= r["preprocess_seconds"]  # the lights are part of the preprocessing
    # later passes make their own lights and trees: they are in image_seconds
    assert all(p["lights_seconds"] > 0 and p["build_seconds"] > 0 for p in r["passes"][1:])
    # every pass's clamp radius recorded, pass 0's in the clamping block
    radii = [p["clamp_radius"] for p in r["passes"]]
    assert r["clamping"]["radius"] == radii[0] and all(x > 0 for x in radii) and len(set(radii)) == 3


def test_image_seconds_leaves_compiling_out(monkeypatch):
    """With every second counted as compiling, the lights and trees leave nothing in image_seconds."""
    from lightcuts.pipeline import warmup

    start = time.perf_counter()
    monkeypatch.setattr(warmup, "compile_seconds", lambda: time.perf_counter() - start)
    r = _render()
    assert abs(r["image_seconds_parts"]["lights"]) < 1e-3 and abs(r["image_seconds_parts"]["trees"]) < 1e-3
    assert r["image_seconds"] == pytest.approx(r["image_seconds_parts"]["passes"], abs=2e-3)
    assert r["image_seconds_parts"]["passes"] == pytest.approx(r["render_seconds"], abs=1e-3)


def test_clamp_off_records_radius_zero():
    r = _render(**{"render.clamp.enabled": False})
    assert r["clamping"]["radius"] == 0.0 and r["clamping"]["clamped_energy_fraction"] == 0.0


def test_compare_rows_have_image_seconds(monkeypatch):
    """A compare row's image_seconds: the shared lights' time, its trees' and its image's."""
    from lightcuts.pipeline import comparing

    seen = {}
    real = comparing.compute_row

    def spy(cfg, plan, label, scene, caster, lights, envmap, shared_seconds, lights_seconds, *a, **k):
        seen[label] = lights_seconds
        return real(cfg, plan, label, scene, caster, lights, envmap, shared_seconds, lights_seconds, *a, **k)

    monkeypatch.setattr(comparing, "compute_row", spy)
    c = lightcuts.compare(lightcuts.load_config(CORNELL, **SMALL), "agglomerative,divisive-6d", pixels=0,
                          progress=False)
    for row in c.report["rows"]:
        assert 0 < seen[row["label"]] < row["preprocess_s"] - row["build_s"]
        assert row["image_seconds"] == pytest.approx(seen[row["label"]] + row["build_s"] + row["image_s"], rel=1e-12)
