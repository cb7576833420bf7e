"""``lightcuts study``: rows from text and files, a tiny run end to end, its figures as defined."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from lightcuts.cli import main
from lightcuts.errors import LightcutsError
from lightcuts.pipeline.study_rows import parse_row, read_rows, resolve_rows

ROOT = Path(__file__).parents[2]
#: A 32 x 32 window of a 64 x 64 Cornell box holding the light (its pixels masked), few lights.
SMALL = {"name": "tiny", "seed": 1, "scene": {"builtin": "cornell"}, "camera": {"resolution": [64, 64]},
         "lights": {"direct": {"count": 64}, "indirect": {"count": 256}}, "render": {"crop": [16, 0, 48, 32]}}


@pytest.fixture(scope="module")
def config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("study") / "tiny.yaml"
    path.write_text(yaml.safe_dump(SMALL))
    return path


@pytest.fixture(scope="module")
def studied(config):
    out = config.parent / "out"
    assert main(["study", str(config), "--row", "lightcuts samples=1,2", "--row", "path samples=1,4,16,64",
                 "--reference-spp", "64", "--times", "0.001,0.01,1000", "--budget", "1000", "--out", str(out),
                 "--no-progress"]) == 0
    return out, json.loads((out / "report.json").read_text())


def test_row_text_forms():
    assert parse_row("path", "r") == {"integrator": "path"}
    assert parse_row("path:max_depth=8,light_sampler=power render.eps=0.05 label=p8 ladder=passes", "r") == {
        "integrator": {"type": "path", "max_depth": 8, "light_sampler": "power"}, "set": ["render.eps=0.05"],
        "label": "p8", "ladder": "passes"}
    assert parse_row("tracer:mitsuba samples=1,4", "r") == {"tracer": "mitsuba", "samples": "1,4"}
    assert parse_row("lightcuts 'render.integrator.max_cut=10' builders=agglomerative,saoh converging=false", "r") == {
        "integrator": "lightcuts", "set": ["render.integrator.max_cut=10"], "builders": "agglomerative,saoh",
        "converging": "false"}


@pytest.mark.parametrize("text, message", [
    ("", "starts with no integrator"),
    ("render.eps=1", "starts with no integrator"),
    ("path colour=red", "'colour' is not a row option"),
    ("path render.eps", "expected KEY=VALUE"),
    ("path:max_depth", "integrator parameter 'max_depth': expected PARAM=VALUE"),
    ("path 'unclosed", "No closing quotation"),
])
def test_row_text_errors(text, message):
    with pytest.raises(LightcutsError, match=message) as exc:
        parse_row(text, f"--row {text!r}")
    assert str(exc.value).startswith(f"--row {text!r}: ")


def _rows(config, *texts, builders=None, overrides=()):
    return resolve_rows(config, list(overrides), [(f"--row {t!r}", parse_row(t, f"--row {t!r}")) for t in texts],
                        builders)


def test_rows_resolved_with_builders_and_converging_settings(config):
    rows = _rows(config, "lightcuts", "lightcuts converging=false label=plain builders=divisive-6d", "path",
                 "tracer:lightcuts", builders="agglomerative,saoh")
    assert [r.label for r in rows] == ["lightcuts/agglomerative", "lightcuts/saoh", "plain/divisive-6d", "path",
                                       "tracer:lightcuts"]
    assert [r.builder for r in rows] == ["agglomerative", "saoh", "divisive-6d", None, None]
    assert [r.plan.tree.name for r in rows[:3]] == ["agglomerative", "saoh", "divisive-6d"]
    assert [r.group for r in rows] == ["lightcuts", "lightcuts", "plain", "path", "tracer:lightcuts"]
    assert [r.ladder for r in rows] == ["passes", "passes", "passes", "spp", "spp"]
    assert [r.uses_trees for r in rows] == [True, True, True, False, False]
    lc, plain, path = rows[0].cfg.render, rows[2].cfg.render, rows[3].cfg.render
    assert (lc.compensation, lc.representatives) == (True, "stochastic")  # the converging settings
    assert (plain.compensation, plain.representatives) == (False, "fixed")
    assert (path.compensation, path.integrator) == (False, "path")
    assert rows[4].tracer == "lightcuts" and rows[4].plan is None
    # a row's own override wins over the converging settings
    row, = _rows(config, "lightcuts render.representatives=fixed")
    assert (row.cfg.render.compensation, row.cfg.render.representatives) == (True, "fixed")


def test_ladder_bounded_by_the_limits(config):
    from lightcuts.limits import MAX_EYE_RAYS, MAX_PASSES, MAX_SPP

    lc, path = _rows(config, "lightcuts", "path")
    assert lc.max_samples == MAX_PASSES and path.max_samples == MAX_SPP
    big, = _rows(config, "path", overrides=["camera.resolution=[8192,4096]", "render.crop=null"])
    assert big.max_samples == MAX_EYE_RAYS // (8192 * 4096)  # 2048 spp of 2^25 pixels
    with pytest.raises(LightcutsError, match="samples '1,5000': expected increasing counts from 1 to 4,096"):
        _rows(config, "lightcuts samples=1,5000")


def test_an_integrator_registered_later_is_a_row_with_its_parameters(config):
    """Rows are overrides: a new integrator and its parameter resolve as soon as they are registered,
    and one whose object says it uses light trees is crossed with the builders."""
    from lightcuts.integrators.path import Path as PathIntegrator
    from lightcuts.integrators.registry import INTEGRATORS
    from lightcuts.registry import Param, declaration, declare

    params = {**declaration(PathIntegrator)["params"], "light_sampler": Param(str, "power", choices=("power", "tree"))}
    with INTEGRATORS.scratch():
        @INTEGRATORS.register("sampling-path")
        @declare(lens=False, cut_unit="path vertices per eye ray", kernels="lightcuts.integrators.path",
                 reference=False, forest=False, params=params)
        class SamplingPath(PathIntegrator):
            def __init__(self, *, spp=1, max_depth=64, light_sampler="power", tree=None):
                super().__init__(spp=spp, max_depth=max_depth, tree=tree)
                self.uses_trees = self.param("light_sampler", light_sampler) == "tree"

        rows = _rows(config, "sampling-path:light_sampler=tree", "sampling-path:light_sampler=power",
                     builders="agglomerative,divisive-3d")
        assert [r.label for r in rows] == ["sampling-path:light_sampler=tree/agglomerative",
                                           "sampling-path:light_sampler=tree/divisive-3d",
                                           "sampling-path:light_sampler=power"]
        assert [r.ladder for r in rows] == ["passes", "passes", "spp"]
        with pytest.raises(LightcutsError, match="render.integrator.light_sampler"):
            _rows(config, "sampling-path:light_sampler=cone")
    with pytest.raises(LightcutsError, match="sampling-path"):  # gone with its registration
        _rows(config, "sampling-path")


@pytest.mark.parametrize("texts, message", [
    (["nope"], "--row 'nope': render.integrator: unknown integrator 'nope'"),
    (["path render.epss=0.1"], "--row 'path render.epss=0.1': --set render.epss: unknown key"),
    (["path:colour=red"], "--row 'path:colour=red': render.integrator.colour"),
    (["path builders=agglomerative"], "--row 'path builders=agglomerative': builders: integrator 'path' uses no "
                                      "light trees"),
    (["lightcuts builders=nope"], "--row 'lightcuts builders=nope': builders: unknown builder 'nope'"),
    (["path camera.resolution=[32,32]"], "camera: the rows share the study's scene"),
    (["lightcuts 'lights.sun={direction: [0, -1, 0], irradiance: [1, 1, 1]}'"], "lights.sun: the rows share"),
    (["tracer:nope"], "--row 'tracer:nope': tracer: unknown reference renderer 'nope'"),
    (["tracer:lightcuts render.eps=0.1"], "set: a path tracer row renders the study's config as it is"),
    (["tracer:lightcuts ladder=passes"], "ladder passes: a path tracer row counts samples per pixel"),
    (["path ladder=laps"], "ladder 'laps': expected passes or spp"),
    (["path samples=4,2"], "samples '4,2': expected increasing counts"),
    (["path samples=x"], "samples 'x': expected sample counts"),
    (["path converging=maybe"], "converging 'maybe': expected true or false"),
    (["path", "path"], "row 'path': two rows have this label"),
])
def test_bad_rows_name_the_row(config, texts, message):
    with pytest.raises(LightcutsError) as exc:
        _rows(config, *texts)
    assert message in str(exc.value), str(exc.value)
    assert "\n" not in str(exc.value)


def test_rows_file(config, tmp_path):
    path = tmp_path / "rows.yaml"
    path.write_text(yaml.safe_dump({"rows": [
        "path samples=1,2",
        {"integrator": {"type": "path", "max_depth": 4}, "set": {"render.eps": 0.05}, "label": "short paths"},
        {"integrator": "lightcuts", "builders": ["agglomerative", "divisive-6d"], "set": ["render.eps=0.05"]},
        {"tracer": "lightcuts", "samples": [1, 8]}]}))
    rows = resolve_rows(config, [], read_rows(path))
    assert [r.label for r in rows] == ["path", "short paths", "lightcuts render.eps=0.05/agglomerative",
                                       "lightcuts render.eps=0.05/divisive-6d", "tracer:lightcuts"]
    assert rows[1].cfg.render.integrator == {"type": "path", "max_depth": 4} and rows[1].cfg.render.eps == 0.05
    assert rows[0].samples == [1, 2] and rows[4].samples == [1, 8]
    for content, message in ((["path", 3], "row 2: expected a text"), ({"rows": []}, "expected a list of rows"),
                             ([{"integrator": "path", "colour": 1}], "row 1: 'colour' is not a row key"),
                             ("rows: [unclosed", "invalid YAML"),
                             ([{"integrator": "path", "set": "render.eps=1"}], "set: expected a list")):
        path.write_text(content if isinstance(content, str) else yaml.safe_dump(content))
        with pytest.raises(LightcutsError, match=message):
            resolve_rows(config, [], read_rows(path))
    with pytest.raises(LightcutsError, match="--rows .*nowhere.yaml: cannot read"):
        read_rows(tmp_path / "nowhere.yaml")


def test_outputs_and_table(studied):
    out, report = studied
    names = {p.name for p in out.iterdir()}
    assert names == {"table.md", "table.csv", "points.csv", "report.json", "report.html", "error-time.png",
                     "reference.exr", "reference.png", "image-lightcuts-agglomerative.exr",
                     "image-lightcuts-agglomerative.png", "image-path.exr", "image-path.png"}
    rows = list(csv.DictReader((out / "table.csv").open()))
    assert [r["label"] for r in rows] == ["lightcuts/agglomerative", "path"]
    points = list(csv.DictReader((out / "points.csv").open()))
    assert [(p["label"], int(p["samples"]), p["ladder"]) for p in points] == [
        ("lightcuts/agglomerative", 1, "passes"), ("lightcuts/agglomerative", 2, "passes"),
        ("path", 1, "spp"), ("path", 4, "spp"), ("path", 16, "spp"), ("path", 64, "spp")]
    assert report["reference"]["renderer"] == "lightcuts" and report["reference"]["spp"] == 64
    assert report["masked_pixels"] > 0 and report["resolution"] == [32, 32]
    assert "relMSE at 0.01 s" in (out / "table.md").read_text()
    html = (out / "report.html").read_text()
    data = json.loads(html.split('id="lc-data">', 1)[1].split("</script>", 1)[0])
    assert [layer["name"] for layer in data["layers"]] == ["reference (lightcuts, 64 spp)",
                                                           "lightcuts/agglomerative (2 passes)", "path (64 spp)"]
    assert data["reference"] == 0 and "error against time" in html


def test_figures_follow_their_definitions(studied):
    from lightcuts.report.efficiency import at_time, subtract, subtract_rms

    _, report = studied
    ref = report["reference"]
    for p in report["points"]:
        assert p["seconds"] == pytest.approx(p["lights_seconds"] + p["build_seconds"] + p["render_seconds"])
        assert p["relmse"] == subtract(p["relmse_raw"], ref["relmse"])
        assert p["block8_rms"] == subtract_rms(p["block8_rms_raw"], ref["block8_rms"])
        assert p["efficiency"] == pytest.approx(p["relmse"] * p["seconds"])
    path = [p for p in report["points"] if p["label"] == "path"]
    assert all(p["lights_seconds"] == p["build_seconds"] == 0 for p in path)  # no lights, no trees
    assert [p["relmse_raw"] for p in path] == sorted((p["relmse_raw"] for p in path), reverse=True)
    # the path row at the reference's sample count has about the reference's own noise once that is taken off
    assert 0.6 < path[-1]["relmse"] / ref["relmse"] < 1.5
    lc = [p for p in report["points"] if p["label"] == "lightcuts/agglomerative"]
    assert lc[1]["seconds"] > lc[0]["seconds"] and all(p["lights_seconds"] > 0 for p in lc)
    for row in report["rows"]:
        pts = [p for p in report["points"] if p["label"] == row["label"]]
        assert (row["samples"], row["seconds"], row["efficiency"]) == (pts[-1]["samples"], pts[-1]["seconds"],
                                                                      pts[-1]["efficiency"])
        secs = [p["seconds"] for p in pts]
        assert row["relmse_at_1000s"] is None  # beyond the ladder: not reached
        t = 0.01
        if secs[0] <= t <= secs[-1]:
            assert row["relmse_at_0.01s"] == subtract(at_time(secs, [p["relmse_raw"] for p in pts], t), ref["relmse"])
        else:
            assert row["relmse_at_0.01s"] is None
    assert all(r["ratio_best_builder"] is None for r in report["rows"])  # one builder per row


def test_passes_ladder_image_is_the_render_of_that_many_passes(studied, config):
    """The point at 2 passes is the image ``render.passes: 2`` gives, byte for byte."""
    import lightcuts
    from lightcuts.report.images import read_exr

    out, _ = studied
    cfg = lightcuts.load_config(config, **{"render.passes": 2, "render.compensation": True,
                                           "render.representatives": "stochastic"})
    np.testing.assert_array_equal(read_exr(out / "image-lightcuts-agglomerative.exr"),
                                  lightcuts.render(cfg, progress=False).image)


def test_reference_seeds_are_their_own():
    from lightcuts.pipeline.study import reference_seeds

    for seed in (0, 1, 2**32 + 1, 2**63 - 1):
        a, b = reference_seeds(seed)
        assert len({a % 2**32, b % 2**32, seed % 2**32}) == 3
    assert reference_seeds(5) == reference_seeds(5) != reference_seeds(6)


def test_default_rows_and_builders_crossing(config, monkeypatch, capsys):
    import lightcuts.pipeline.study as study

    seen = []
    monkeypatch.setattr(study, "study_run", lambda cfg, plan, rows, **kw: seen.append((rows, kw)) or
                        (_ for _ in ()).throw(LightcutsError("stopped")))
    assert main(["study", str(config), "--builders", "agglomerative,divisive-3d", "--times", "5,20"]) == 2
    rows, kw = seen[0]
    assert [r.label for r in rows] == ["lightcuts/agglomerative", "lightcuts/divisive-3d", "path"]
    assert kw["budget"] == 20 and kw["times"] == [5.0, 20.0] and kw["reference"] == "lightcuts"
    assert capsys.readouterr().err.strip() == "error: stopped"


def test_a_mitsuba_row_at_equal_time(config):
    """Mitsuba 3's path tracer as a row (the equal-time figure against it): its spp ladder as given,
    its time the render alone, its error falling with its samples."""
    pytest.importorskip("mitsuba")
    from lightcuts.config import load_config
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.study import study_run

    cfg = load_config(config)
    rows = _rows(config, "tracer:mitsuba samples=1,16")
    s = study_run(cfg, plan_run(cfg, render=True), rows, reference="lightcuts", reference_spp=16, times=[1000.0],
                  progress=False, log=lambda *a: None)
    pts = s.points
    assert [p["samples"] for p in pts] == [1, 16] and s.report["rows"][0]["tracer"] == "mitsuba"
    assert all(p["seconds"] == p["render_seconds"] > 0 and p["lights_seconds"] == 0 for p in pts)
    assert pts[1]["relmse_raw"] < pts[0]["relmse_raw"] / 4
    assert s.images["tracer:mitsuba"].shape == (32, 32, 3)


def test_masked_figures_recomputed_from_the_written_images(studied, config):
    """The last point's measured relMSE is relmse(row image, reference) with the emitter mask the
    scene casts: masked pixels (the light itself) are out of it."""
    from lightcuts.config import load_config
    from lightcuts.integrators.primary import emitter_mask
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.report.efficiency import relmse
    from lightcuts.report.images import read_exr

    out, report = studied
    plan = plan_run(load_config(config), render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        mask = emitter_mask(scene, caster, SMALL["render"]["crop"])
    assert mask.sum() == report["masked_pixels"] > 0
    image, reference = read_exr(out / "image-path.exr"), read_exr(out / "reference.exr")
    last = [p for p in report["points"] if p["label"] == "path"][-1]
    assert last["relmse_raw"] == pytest.approx(relmse(image, reference, mask), rel=1e-5)
    assert relmse(image, reference) > 1.1 * last["relmse_raw"]  # the light's edge pixels add to it


def test_table_rows_from_synthetic_ladders():
    """A row's figures are its last point's; its error at a time the measured values interpolated in
    log-log, the reference's share taken off after; builder ratios within a group only."""
    from lightcuts.pipeline.study import _rows
    from lightcuts.pipeline.study_rows import StudyRow

    rows = [StudyRow("a/x", "r", "a", None, ladder="spp"), StudyRow("a/y", "r", "a", None, ladder="spp"),
            StudyRow("b", "r", "b", None)]
    noise = {"relmse": 0.01, "block8_rms": 0.01}
    points = []
    for label, scale in (("a/x", 1.0), ("a/y", 3.0), ("b", 2.0)):
        for k, t in ((1, 1.0), (2, 2.0), (4, 4.0)):
            raw = scale * 0.4 / k + noise["relmse"]
            points.append({"label": label, "samples": k, "seconds": t, "relmse_raw": raw, "relmse": raw - 0.01,
                           "block8_rms_raw": 0.05 * scale / k ** 0.5, "block8_rms": None, "efficiency": t * (raw - 0.01)})
    table = _rows(rows, points, [3.0, 8.0], noise)
    ax, ay, b = table
    assert (ax["samples"], ax["seconds"], ax["efficiency"]) == (4, 4.0, points[2]["efficiency"])
    raw3 = np.exp(np.log(0.4 / 2 + 0.01) * (1 - np.log(1.5) / np.log(2)) + np.log(0.4 / 4 + 0.01) * np.log(1.5) / np.log(2))
    assert ax["relmse_at_3s"] == pytest.approx(raw3 - 0.01, rel=1e-12)
    rms3 = 0.05 / 3 ** 0.5 * 1.0  # 1 / sqrt(k) is a straight line in log-log: exact
    assert ax["block8_rms_at_3s"] == pytest.approx(np.sqrt(rms3 ** 2 - 0.01 ** 2), rel=1e-9)
    assert ax["relmse_at_8s"] is None and ax["block8_rms_at_8s"] is None
    assert (ax["ratio_best_builder"], ay["ratio_best_builder"], ax["ratio_samples"]) == (1.0, pytest.approx(3.0), 4)
    assert b["ratio_best_builder"] is None  # alone in its group


def test_builders_option_checked_as_itself(config):
    with pytest.raises(LightcutsError, match=r"^--builders: unknown builder 'nope'"):
        _rows(config, "path", builders="agglomerative,nope")


def test_budget_ends_every_ladder(config):
    """Each ladder stops at its first point whose time reaches the budget."""
    from lightcuts.config import load_config
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.pipeline.study import study_run

    cfg = load_config(config)
    s = study_run(cfg, plan_run(cfg, render=True), _rows(config, "lightcuts", "path"), reference="lightcuts",
                  reference_spp=4, times=[1e-9], progress=False, log=lambda *a: None)
    assert [(p["label"], p["samples"]) for p in s.points] == [("lightcuts/agglomerative", 1), ("path", 1)]
    assert s.report["budget"] == 1e-9


def test_times_at_the_limit():
    from lightcuts.commands.study import parse_times
    from lightcuts.limits import MAX_POINTS

    assert parse_times(",".join(str(i) for i in range(1, MAX_POINTS + 1)))[-1] == MAX_POINTS
    with pytest.raises(LightcutsError, match=f"--times .*: expected 1 to {MAX_POINTS} increasing seconds"):
        parse_times(",".join(str(i) for i in range(1, MAX_POINTS + 2)))
    with pytest.raises(LightcutsError, match="increasing"):
        parse_times("60,10")
