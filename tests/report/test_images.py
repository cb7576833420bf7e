"""Image outputs: EXR round trip, sRGB encoding, heatmap, relative-error statistics."""

import numpy as np
import pytest
from PIL import Image

from lightcuts.errors import LightcutsError
from lightcuts.report.images import read_exr, relative_error, write_exr, write_heatmap, write_png
from lightcuts.report.tonemap import srgb8


def test_exr_round_trip_is_exact(tmp_path):
    rgb = np.random.default_rng(0).random((7, 5, 3)) * 100.0
    write_exr(tmp_path / "a.exr", rgb[:, ::-1])  # a non-contiguous view must still write the right pixels
    back = read_exr(tmp_path / "a.exr")
    assert back.shape == (7, 5, 3)
    np.testing.assert_array_equal(back, rgb[:, ::-1].astype(np.float32))
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]  # no temporary left behind


def test_read_exr_errors(tmp_path):
    with pytest.raises(LightcutsError, match="no such EXR"):
        read_exr(tmp_path / "none.exr")
    (tmp_path / "bad.exr").write_bytes(b"not an exr")
    with pytest.raises(LightcutsError, match="bad.exr: cannot read EXR"):
        read_exr(tmp_path / "bad.exr")


def test_srgb_encoding_matches_the_standard_curve():
    lin = np.array([[[0.0, 0.0031308, 0.18], [0.5, 1.0, 4.0]]])
    expected = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.clip(lin, 0, 1) ** (1 / 2.4) - 0.055)
    np.testing.assert_array_equal(srgb8(lin), np.clip(np.round(expected * 255), 0, 255).astype(np.uint8))
    # one stop of exposure doubles the linear value before encoding
    np.testing.assert_array_equal(srgb8(lin * 2.0), srgb8(lin, exposure=1.0))


def test_png_and_heatmap_written(tmp_path):
    rgb = np.zeros((4, 6, 3))
    rgb[1, 2] = [1.0, 0.5, 0.0]
    write_png(tmp_path / "i.png", rgb)
    img = np.asarray(Image.open(tmp_path / "i.png"))
    assert img.shape == (4, 6, 3) and tuple(img[1, 2]) == (255, 188, 0) and img[0, 0].sum() == 0
    write_heatmap(tmp_path / "h.png", np.arange(24, dtype=float).reshape(4, 6))
    assert Image.open(tmp_path / "h.png").size[0] > 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.png", "i.png"]


def test_relative_error_statistics():
    ref = np.ones((10, 10, 3))
    img = ref.copy()
    img[0, :5] *= 1.1  # 5 pixels 10% too bright
    img[9, 9] = 0.0    # and one black
    e = relative_error(img, ref)
    assert e["pixels"] == 100
    assert e["median"] == pytest.approx(0.0)
    assert e["max"] == pytest.approx(1.0)
    assert e["mean"] == pytest.approx((5 * 0.1 + 1.0) / 100)
    dark = ref.copy()
    dark[5:] = 1e-6  # pixels below the floor are not compared
    assert relative_error(dark, dark)["pixels"] == 50


def test_masked_pixels_leave_every_figure():
    from lightcuts.report.images import compare_images

    rng = np.random.default_rng(3)
    ref = 0.5 + rng.random((32, 32, 3))
    img = ref * 0.97  # lit surfaces 3% dark
    mask = np.zeros((32, 32), bool)
    mask[2:6, 10:20] = True  # an emitter seen directly: the same very bright radiance in both
    ref[mask] = img[mask] = 1000.0
    c = compare_images(img, ref, mask=mask)
    assert c["energy_ratio"] == pytest.approx(0.97) and c["masked_pixels"] == 40
    assert c["energy_ratio_frame"] > 0.99  # the emitter's energy hides the gap in the whole frame
    assert c["pixel"]["pixels"] == 32 * 32 - 40 and c["pixel"]["median"] == pytest.approx(0.03)
    assert c["block8"]["pixels"] == 16 - 2  # the two tiles holding a masked pixel are left out
    whole = compare_images(img, ref)
    assert whole["energy_ratio"] == whole["energy_ratio_frame"] == c["energy_ratio_frame"]
    assert whole["pixel"]["pixels"] == 32 * 32 and whole["masked_pixels"] == 0


def test_reference_noise_from_two_halves():
    from lightcuts.report.images import compare_images

    rng = np.random.default_rng(4)
    truth = np.full((256, 256, 3), 2.0)
    sigma = 0.2  # per pixel and channel in each half
    a, b = (truth + rng.normal(0, sigma, truth.shape) for _ in range(2))
    ref = (a + b) / 2
    exact = compare_images(truth, ref, halves=(a, b))
    noise = exact["reference_noise"]
    # an exact image's error against a noisy reference is that noise, and the estimate says so
    for part in ("pixel", "block8"):
        assert noise[part]["pixels"] == exact[part]["pixels"]
        assert noise[part]["median"] == pytest.approx(exact[part]["median"], rel=0.15)
    # the relative spread of the reference's mean: sigma_lum / sqrt(2 n) / mean
    sigma_lum = sigma * np.sqrt((np.array([0.2126, 0.7152, 0.0722]) ** 2).sum())
    assert noise["energy_ratio"] == pytest.approx(sigma_lum / np.sqrt(2 * 256 * 256) / 2.0, rel=0.05)
    # a 5% bias stands far above the noise of the 8x8 block means
    biased = compare_images(truth * 1.05, ref, halves=(a, b))
    assert biased["block8"]["median"] > 5 * biased["reference_noise"]["block8"]["median"]
    assert biased["reference_noise"] == noise  # the noise is the reference's alone
