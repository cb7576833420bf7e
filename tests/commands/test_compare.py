"""``lightcuts compare``: rows equal the individual renders, one colour scale, resume and --force."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import cli_recording_work
from lightcuts.cli import main
from lightcuts.commands.compare import sample_pixels
from lightcuts.errors import LightcutsError
from lightcuts.report.compare import cut_colours

ROOT = Path(__file__).parents[2]
SMALL = ["--set", "camera.resolution=[40,40]", "--set", "lights.indirect.count=1500",
         "--set", "lights.direct.count=128"]
BUILDERS = "agglomerative,divisive-6d,divisive-3d"


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare") / "cmp"
    assert main(["compare", str(ROOT / "configs/cornell.yaml"), "--builders", BUILDERS, "--pixels", "200",
                 "--out", str(out), "--no-progress", "--set", "render.tonemap={type: aces, exposure: 1.5}",
                 *SMALL]) == 0
    return out, json.loads((out / "report.json").read_text())


def test_each_row_image_as_exr_and_png_with_one_tone_map(compared):
    from lightcuts.report.images import read_exr
    from lightcuts.report.tonemap import srgb8

    out, report = compared
    images = {}
    for label in BUILDERS.split(","):
        images[label] = read_exr(out / f"image-{label}.exr")
        np.testing.assert_array_equal(images[label], np.load(out / "rows" / f"{label}.npz")["image"])
        png = np.asarray(Image.open(out / f"image-{label}.png"))
        np.testing.assert_array_equal(png, srgb8(images[label], "aces", 1.5))
    assert not np.array_equal(images["agglomerative"], images["divisive-3d"])  # each row its own image


def test_report_html_holds_each_rows_image_and_cut_sizes_and_the_sampled_reference(compared):
    from lightcuts.report.html import viewer_values

    out, report = compared
    text = (out / "report.html").read_text()
    data = json.loads(text.split('id="lc-data">', 1)[1].split("</script>", 1)[0])
    labels = BUILDERS.split(",")
    assert [layer["name"] for layer in data["layers"]] == (labels + [f"cut: {b}" for b in labels]
                                                           + ["cut: agglomerative - divisive-6d"])
    diff = data["scales"]["diff"]
    assert diff["map"] == "RdBu_r" and diff["min"] == -diff["max"] and diff["max"] >= 1
    assert data["tonemap"] == {"type": "aces", "exposure": 1.5}
    assert data["scales"]["cut"]["max"] == report["cut_scale_max"]
    assert data["sample"]["xy"]["shape"] == [200, 2] and data["reference"] is None
    assert len(data["layers"][0]["values"]["b64"]) < 40 * 40 * 6 * 4 / 3 + 4  # float16, deflated
    stored = np.load(out / "rows" / "agglomerative.npz")["image"]
    assert viewer_values(stored).shape == (40, 40, 3)


def test_default_difference_panel_is_of_two_rows_that_differ(compared, tmp_path, capsys):
    out, report = compared
    # divisive-6d is the baseline; agglomerative, the first row, differs from it
    assert report["diff"] == ["agglomerative", "divisive-6d"]
    assert "baseline divisive-6d" in report["diff_chosen"]
    # agglomerative and agglomerative-heap build the same tree: never a panel of the two
    same = tmp_path / "same"
    assert main(["compare", str(ROOT / "configs/cornell.yaml"), "--builders", "agglomerative-heap,agglomerative",
                 "--pixels", "0", "--out", str(same), "--no-progress", *SMALL]) == 0
    r = json.loads((same / "report.json").read_text())
    assert r["diff"] is None and "same cut sizes" in r["diff_chosen"]
    assert "difference panel: none (every row has the same cut sizes" in capsys.readouterr().out


def test_default_diff_rules():
    from lightcuts.pipeline.comparing import default_diff

    a, b = np.zeros((2, 3)), np.ones((2, 3))
    cuts = {"heap": a, "local": a.copy(), "d6": b, "d3": b + 1}
    assert default_diff(["heap", "local", "d6", "d3"], cuts, "d6")[0] == ("heap", "d6")
    assert default_diff(["heap", "local", "d6", "d3"], cuts, None)[0] == ("heap", "d6")
    assert default_diff(["heap", "local", "d6", "d3"], {**cuts, "d6": a}, "d6")[0] == ("d3", "d6")
    assert default_diff(["heap", "local", "d6"], {**cuts, "d6": a}, "d6")[0] is None
    assert default_diff(["heap", "local"], cuts, None)[0] is None


def test_rows_equal_the_individual_renders(compared, tmp_path):
    out, report = compared
    assert [r["label"] for r in report["rows"]] == BUILDERS.split(",")
    for row in report["rows"]:
        single = tmp_path / row["label"]
        assert main(["render", str(ROOT / "configs/cornell.yaml"), "--out", str(single), "--no-progress",
                     "--set", f"tree.builder={row['label']}", *SMALL]) == 0
        r = json.loads((single / "report.json").read_text())
        assert row["cut_mean"] == r["cut_size_mean"] and row["cut_max"] == r["cut_size_max"]
        assert row["shadow_rays_per_pixel"] == r["shadow_rays_per_pixel"]
        assert row["builder"] == r["builder"] and row["metric"] == r["metric"] and row["lights"] == r["lights"]
        assert row["summed_s"] == pytest.approx(row["preprocess_s"] + row["image_s"])
        assert 0 < row["err_median"] <= row["err_p99"] < 0.5 and row["pixels_compared"] > 100
    table = (out / "table.md").read_text()
    assert all(f"| {b} |" in table for b in BUILDERS.split(","))
    assert (out / "table.csv").read_text().count("\n") == 4
    assert report["machine"]["cores"] >= 1 and report["machine"]["numba"] and report["machine"]["embree"]


def test_heatmaps_share_one_scale(compared):
    out, report = compared
    cuts = {}
    for label in BUILDERS.split(","):
        z = np.load(out / "rows" / f"{label}.npz")
        cuts[label] = z["cut"]
        png = np.asarray(Image.open(out / f"cutsize-{label}.png").convert("RGB"))
        assert png.shape[:2] == cuts[label].shape
        assert (png == cut_colours(cuts[label], report["cut_scale_max"])).all()
    vmax = max(float(c.max()) for c in cuts.values())
    assert report["cut_scale_max"] == vmax
    # The same cut size has the same colour in every row's map, and only the largest one is the top colour.
    a, b = (np.asarray(Image.open(out / f"cutsize-{x}.png").convert("RGB")) for x in ("agglomerative", "divisive-3d"))
    same = cuts["agglomerative"] == cuts["divisive-3d"]
    assert same.any() and (a[same] == b[same]).all()
    top = cut_colours(np.array([[vmax]]), vmax)[0, 0]
    holder = next(c for c in cuts.values() if c.max() == vmax)
    assert (cut_colours(holder, vmax)[holder == vmax] == top).all()
    assert not (cut_colours(holder, vmax)[holder < 0.9 * vmax] == top).all(axis=-1).any()


def test_resume_skips_finished_rows_and_recomputes_changed_ones(tmp_path):
    args = ["compare", str(ROOT / "configs/cornell.yaml"), "--builders", "divisive-6d,divisive-3d", "--pixels", "50",
            "--out", str(tmp_path / "cmp"), "--no-progress", *SMALL]
    rc, calls, err = cli_recording_work(args, tmp_path)
    assert rc == 0 and calls.count("build_tree") >= 2, err
    first = json.loads((tmp_path / "cmp" / "report.json").read_text())["rows"]
    rc, calls, err = cli_recording_work(args, tmp_path)
    assert rc == 0 and calls == [], err  # every row stored: no scene, no lights, no tree
    again = json.loads((tmp_path / "cmp" / "report.json").read_text())["rows"]
    assert again == first
    # A new row computes only that row (the trees of one builder: its untimed warm-up and the timed one).
    rc, calls, err = cli_recording_work(args[:3] + ["divisive-6d,divisive-3d,agglomerative"] + args[4:], tmp_path)
    assert rc == 0 and calls.count("scene_from_config") == 1 and calls.count("build_tree") == 2, err
    # A changed setting recomputes every row; so does --force.
    for extra in (["--set", "render.eps=0.05"], ["--force"]):
        rc, calls, err = cli_recording_work(args + extra, tmp_path)
        assert rc == 0 and calls.count("build_tree") == 4, (extra, err)
    eps = json.loads((tmp_path / "cmp" / "report.json").read_text())
    assert eps["settings"]["render"]["eps"] == 0.02  # the last run was --force at the config's eps


def test_an_interrupted_compare_keeps_its_finished_rows(tmp_path, scratch_registries):
    from lightcuts.trees.registry import BUILDERS

    def failing(*args):
        raise LightcutsError("stopped")

    BUILDERS.register("failing", failing, reads=())
    out = tmp_path / "cmp"
    args = ["compare", str(ROOT / "configs/cornell.yaml"), "--pixels", "20", "--out", str(out), "--no-progress", *SMALL]
    assert main(args + ["--builders", "divisive-3d,failing"]) == 2  # "error: stopped"
    assert sorted(p.name for p in (out / "rows").iterdir()) == ["divisive-3d.npz", "reference.npz"]
    assert not (out / "table.md").exists()
    stored = (out / "rows" / "divisive-3d.npz").stat().st_mtime_ns
    assert main(args + ["--builders", "divisive-3d"]) == 0
    assert (out / "rows" / "divisive-3d.npz").stat().st_mtime_ns == stored
    assert (out / "table.md").exists()


def test_pixel_sample_is_seeded_distinct_and_inside_the_window():
    a = sample_pixels(64, 48, None, 300, seed=5)
    assert (a == sample_pixels(64, 48, None, 300, seed=5)).all()
    assert not (a == sample_pixels(64, 48, None, 300, seed=6)).all()
    assert len({tuple(p) for p in a}) == 300 and (a[:, 0] < 64).all() and (a[:, 1] < 48).all()
    crop = sample_pixels(64, 48, (10, 5, 20, 9), 1000, seed=5)
    assert len(crop) == 40 and crop[:, 0].min() == 10 and crop[:, 0].max() == 19 and crop[:, 1].max() == 8


@pytest.mark.parametrize("extra, message", [
    (["--builders", "agglomerative,nope"], "--builders: unknown builder 'nope'"),
    (["--builders", "divisive-3d,divisive-3d"], "--builders 'divisive-3d,divisive-3d': a name is given twice"),
    (["--builders", "divisive-3d,divisive-6d", "--diff", "divisive-3d,saoh"], "--diff 'divisive-3d,saoh'"),
    (["--builders", "divisive-3d", "--metrics", "walter2008"], "--metrics: none of the builders"),
    (["--metrics", "nope"], "--metrics: unknown metric 'nope'"),
    (["--pixels", "-1"], "--pixels -1: must be from 0 to 33,554,432"),
])
def test_bad_options_one_line_nothing_built(tmp_path, extra, message):
    rc, calls, err = cli_recording_work(["compare", str(ROOT / "configs/cornell.yaml"), "--out",
                                         str(tmp_path / "cmp"), *extra], tmp_path)
    assert rc == 2 and calls == [] and not (tmp_path / "cmp").exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err


def test_mitsuba_row_at_equal_time(tmp_path):
    pytest.importorskip("mitsuba")
    out = tmp_path / "cmp"
    assert main(["compare", str(ROOT / "configs/cornell.yaml"), "--builders", "divisive-6d,agglomerative",
                 "--pixels", "0", "--out", str(out), "--no-progress", "--mitsuba", "--mitsuba-spp", "32",
                 "--mitsuba-passes", "2", *SMALL]) == 0
    m = json.loads((out / "report.json").read_text())["mitsuba"]
    row = next(r for r in json.loads((out / "report.json").read_text())["rows"] if r["label"] == "agglomerative")
    assert m["lightcuts_row"] == "agglomerative" and m["budget_s"] == row["image_s"] == m["lightcuts"]["seconds"]
    assert m["equal_time"]["spp"] >= 1 and m["reference_spp"] == 32
    # Both renderers compute the same light transport (up to clamping and the path tracer's noise).
    for r in (m["lightcuts"], m["equal_time"]):
        assert 0.85 < r["energy_ratio"] < 1.15, r
    # The pixels that see the light quad are left out of every measure, as lightcuts' own studies do.
    masked = [m[k]["masked_pixels"] for k in ("lightcuts", "equal_time", "converging", "converging_equal_time")]
    assert len(set(masked)) == 1 and masked[0] > 0, masked
    c, ce = m["converging"], m["converging_equal_time"]
    assert c["label"] == "agglomerative, 2 passes, compensation, stochastic" and c["seconds"] > 0
    assert ce["spp"] >= 1 and 0.85 < c["energy_ratio"] < 1.15 and 0.85 < ce["energy_ratio"] < 1.15
    table = (out / "table.md").read_text()
    assert "Lightcuts and path tracing at equal time" in table and c["label"] in table
    for name in ("reference", "equal_time", "converging_equal_time"):
        assert (out / f"mitsuba-{name}.exr").is_file() and (out / f"mitsuba-{name}.png").is_file()


def test_a_render_keeps_the_compare_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = str(ROOT / "configs/cornell.yaml")
    from lightcuts.io import run_dir

    run = tmp_path / run_dir("cornell", SMALL[1::2])  # the folder of a run with these --set overrides
    assert main(["compare", cfg, "--builders", "divisive-3d", "--pixels", "0", "--no-progress", *SMALL]) == 0
    table = (run / "compare/table.md").read_text()
    assert main(["render", cfg, "--no-progress", *SMALL]) == 0
    assert (run / "image.exr").is_file()
    assert (run / "compare/table.md").read_text() == table
    assert (run / "compare/rows/divisive-3d.npz").is_file()


def test_multidimensional_rows_are_the_pairs_per_pixel_of_its_renders(tmp_path):
    # Each row's cut sizes are what lightcuts.render of the same config reports: (gather, light) pairs
    # per pixel, named so in table.md, table.csv and report.json; its error is against all the pairs.
    import lightcuts

    md = {"render.integrator": "multidimensional", "render.spp": 4, "camera.resolution": [24, 18],
          "lights.indirect.count": 600, "lights.direct.count": 64}
    sets = [x for k, v in md.items() for x in ("--set", f"{k}={json.dumps(v)}")]
    out = tmp_path / "cmp"
    assert main(["compare", str(ROOT / "configs/cornell.yaml"), "--builders", "agglomerative,divisive-6d",
                 "--pixels", "40", "--out", str(out), "--no-progress", *sets]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["cut_unit"] == "pairs per pixel"
    assert "| Avg cutsize (pairs per pixel) |" in (out / "table.md").read_text()
    assert (out / "table.csv").read_text().count(",pairs per pixel,") == 2
    for row in report["rows"]:
        single = lightcuts.render(lightcuts.load_config(ROOT / "configs/cornell.yaml", **md,
                                                        **{"tree.builder": row["label"]}), progress=False)
        assert single.report["cut_size_unit"] == row["cut_unit"] == "pairs per pixel"
        assert row["cut_mean"] == single.report["cut_size_mean"] and row["cut_max"] == single.report["cut_size_max"]
        assert row["shadow_rays_per_pixel"] == single.report["shadow_rays_per_pixel"]
        np.testing.assert_array_equal(np.load(out / "rows" / f"{row['label']}.npz")["cut"], single.cut_size)
        assert 0 < row["err_median"] < 0.05 and row["pixels_compared"] > 20
