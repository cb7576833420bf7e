"""Tone maps: each operator's formula, exposure in stops, defined output for any float, the config
key and ``lightcuts convert``."""

import math

import numpy as np
import pytest
from PIL import Image

from lightcuts.report.tonemap import OPERATORS, display, srgb8


def _srgb(y):
    return 12.92 * y if y <= 0.0031308 else 1.055 * y ** (1 / 2.4) - 0.055


def _hable(x):
    a, b, c, d, e, f = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f


def _expected(rgb, op):
    """The module docstring's formulas, one pixel at a time in plain Python."""
    r, g, b = rgb
    if op == "clip":
        y = [r, g, b]
    elif op == "reinhard":
        lum = 0.2126 * r + 0.7152 * g + 0.0722 * b
        y = [v / (1 + lum) for v in rgb]
    elif op == "aces":
        y = [v * (2.51 * v + 0.03) / (v * (2.43 * v + 0.59) + 0.14) for v in rgb]
    else:
        y = [_hable(2 * v) / _hable(11.2) for v in rgb]
    return [math.floor(_srgb(min(max(v, 0.0), 1.0)) * 255 + 0.5) for v in y]


PIXELS = [(0.0, 0.0, 0.0), (0.18, 0.18, 0.18), (0.5, 0.25, 0.05), (1.0, 1.0, 1.0), (3.0, 0.7, 0.2),
          (0.002, 0.001, 0.0005), (40.0, 10.0, 1.0)]


@pytest.mark.parametrize("op", OPERATORS)
def test_each_operator_follows_its_formula(op):
    got = srgb8(np.array([PIXELS]), op)[0]
    assert [list(map(int, p)) for p in got] == [_expected(p, op) for p in PIXELS]


@pytest.mark.parametrize("op", OPERATORS)
def test_exposure_is_stops_before_the_operator(op):
    x = np.array([PIXELS])
    np.testing.assert_array_equal(srgb8(x, op, 1.0), srgb8(2.0 * x, op))
    np.testing.assert_array_equal(srgb8(x, op, -2.0), srgb8(x / 4.0, op))
    grey = np.linspace(0, 20, 200)[None, :, None].repeat(3, axis=2)
    assert (np.diff(display(grey, op)[0, :, 0]) >= 0).all()  # brighter in, never darker out


def test_operators_differ_where_they_should():
    x = np.array([[[4.0, 2.0, 0.5]]])
    clip, rein, aces, hable = (srgb8(x, op)[0, 0] for op in OPERATORS)
    assert tuple(clip[:2]) == (255, 255)  # clipped: the two bright channels alike
    assert rein[0] > rein[1] > rein[2] and aces[0] > aces[1] and hable[0] > hable[1]
    # Reinhard scales the three channels by one factor: their ratio stays the input's
    y = display(np.array([[[0.6, 0.3, 0.1]]]), "reinhard")[0, 0]
    np.testing.assert_allclose(y / y[0], [1.0, 0.5, 1 / 6])


def test_any_float_gives_a_defined_pixel():
    x = np.array([[[np.nan, -1.0, np.inf], [1e38, 0.5, -np.inf]]], np.float32)
    for op in OPERATORS:
        for exposure in (0.0, 1000.0, -1000.0):
            with np.errstate(all="raise"):
                out = srgb8(x, op, exposure)
            assert out.dtype == np.uint8 and out.shape == x.shape
        assert tuple(srgb8(x, op)[0, 0][:2]) == (0, 0)  # NaN and negatives are black
        assert srgb8(x, op)[0, 1, 0] == 255


def test_unknown_operator_refused():
    with pytest.raises(ValueError, match="filmic"):
        display(np.zeros((1, 1, 3)), "filmic")


def test_config_tonemap_forms(tmp_path):
    from lightcuts.commands.convert import OPERATORS as CLI_OPERATORS
    from lightcuts.config import load_config
    from lightcuts.config.schema import ToneMap
    from lightcuts.errors import LightcutsError

    assert CLI_OPERATORS == OPERATORS and ToneMap.model_fields["type"].annotation.__args__ == OPERATORS
    (tmp_path / "c.yaml").write_text("scene: {builtin: cornell}\n")
    assert load_config(tmp_path / "c.yaml").render.tonemap == ToneMap(type="clip", exposure=0.0)
    t = load_config(tmp_path / "c.yaml", ["render.tonemap=aces"]).render.tonemap
    assert (t.type, t.exposure) == ("aces", 0.0)
    t = load_config(tmp_path / "c.yaml", ["render.tonemap={type: hable, exposure: -1.5}"]).render.tonemap
    assert (t.type, t.exposure) == ("hable", -1.5)
    with pytest.raises(LightcutsError, match=r"render: exposure: set render.tonemap.exposure"):
        load_config(tmp_path / "c.yaml", ["render.exposure=1"])
    with pytest.raises(LightcutsError, match=r"render.tonemap.type"):
        load_config(tmp_path / "c.yaml", ["render.tonemap=filmic"])


def test_render_png_uses_the_config_tonemap(tmp_path):
    from lightcuts.report.images import write_png
    from lightcuts.config.schema import ToneMap

    rgb = np.random.default_rng(1).random((6, 5, 3)) * 4
    write_png(tmp_path / "a.png", rgb, ToneMap(type="aces", exposure=0.5))
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), srgb8(rgb, "aces", 0.5))


def test_convert_writes_the_tone_mapped_png(tmp_path, capsys):
    from lightcuts.cli import main
    from lightcuts.report.images import write_exr

    rgb = np.random.default_rng(2).random((7, 9, 3)).astype(np.float32) * 8
    write_exr(tmp_path / "im.exr", rgb)
    assert main(["convert", str(tmp_path / "im.exr"), "--tonemap", "reinhard", "--exposure", "-1"]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "im.png")), srgb8(rgb, "reinhard", -1.0))
    assert main(["convert", str(tmp_path / "im.exr"), "--out", str(tmp_path / "sub" / "x.png")]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "sub" / "x.png")), srgb8(rgb))
    assert "9x7, reinhard, exposure -1" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--out", "x.jpg"], "--out 'x.jpg': must end in .png"),
    (["--exposure", "1e4"], "--exposure 10000.0: must be within [-1000, 1000] stops"),
    (["--out", "sub.png"], "--out 'sub.png': is a folder"),
])
def test_convert_refuses_bad_options_before_writing(tmp_path, monkeypatch, capsys, argv, message):
    from lightcuts.cli import main
    from lightcuts.report.images import write_exr

    monkeypatch.chdir(tmp_path)
    write_exr("im.exr", np.ones((2, 3, 3), np.float32))
    (tmp_path / "sub.png").mkdir()
    assert main(["convert", "im.exr", *argv]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"error: {message}"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["im.exr", "sub.png"]
    assert not any((tmp_path / "sub.png").iterdir())
