"""Image outputs: EXR round trip, sRGB encoding, heatmap, relative-error statistics."""

import numpy as np
import pytest
from PIL import Image

from lightcuts.errors import LightcutsError
from lightcuts.report.images import read_exr, relative_error, to_srgb8, write_exr, write_heatmap, write_png


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
    np.testing.assert_array_equal(to_srgb8(lin), np.clip(np.round(expected * 255), 0, 255).astype(np.uint8))
    # one stop of exposure doubles the linear value before encoding
    np.testing.assert_array_equal(to_srgb8(lin * 2.0), to_srgb8(lin, exposure=1.0))


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
