"""report.html without a browser: the arrays' encoding, the page's structure, escaping, and which
images each kind of run puts in its viewer."""

import base64
import json
import zlib

import numpy as np
import pytest

from lightcuts.report.html import Layer, Page, Scale, Table, encode, page_html, viewer_values, write_report


def _data(text: str) -> dict:
    return json.loads(text.split('id="lc-data">', 1)[1].split("</script>", 1)[0])


def _decode(a: dict, bits: np.ndarray | None = None) -> np.ndarray:
    """encode undone: inflate, unshuffle the bytes, XOR with the base's float16 ``bits``, multiply
    by the power of two."""
    typed = {"f16": np.float16, "f32": np.float32, "u8": np.uint8}[a["dtype"]]
    raw = np.frombuffer(zlib.decompress(base64.b64decode(a["b64"])), np.uint8)
    values = raw.reshape(np.dtype(typed).itemsize, -1).T.copy().view(typed).reshape(a["shape"])
    if bits is not None:
        values = (values.view(np.uint16) ^ bits).view(np.float16)
    return values.astype(np.float64) * 2.0 ** a["scale_log2"]


def _bits(a: dict) -> np.ndarray:
    raw = np.frombuffer(zlib.decompress(base64.b64decode(a["b64"])), np.uint8)
    return raw.reshape(2, -1).T.copy().view(np.uint16).reshape(a["shape"])


def test_images_are_stored_as_bit_differences_from_the_first():
    """An image equal to the first (two builders that make the same tree) costs next to nothing;
    one that differs decodes to itself."""
    rng = np.random.default_rng(2)
    first = (rng.random((48, 64, 3)) * 3).astype(np.float32)
    other = first * (1 + 0.01 * rng.standard_normal(first.shape)).astype(np.float32)
    page = Page("t", layers=[Layer("a", first), Layer("cut", first[..., 0], "c"), Layer("same", first.copy()),
                             Layer("other", other)], scales={"c": Scale(3.0, "x")})
    layers = _data(page_html(page))["layers"]
    assert [layer["values"]["xor"] for layer in layers] == [None, None, 0, 0]  # scalar maps stay whole
    base = _bits(layers[0]["values"])
    for layer, image in zip(layers[2:], (first, other)):
        np.testing.assert_array_equal(_decode(layer["values"], base), viewer_values(image))
    assert len(layers[2]["values"]["b64"]) < 0.01 * len(layers[0]["values"]["b64"])


@pytest.mark.parametrize("top", [1e-9, 0.7, 65504.0, 3e6, 1e30])
def test_float16_encoding_keeps_three_digits_at_any_scale(top):
    rng = np.random.default_rng(0)
    a = (rng.random((9, 7, 3)) * top).astype(np.float32)
    a[0, 0] = [top, 0.0, top * 1e-6]
    got = _decode(encode(a))
    np.testing.assert_array_equal(got, viewer_values(a))
    big = a > top * 1e-4  # below that, float16's subnormals (still within 2^-24 of the top)
    assert np.all(np.abs(got[big] - a[big]) <= a[big] * 2.0 ** -11)
    assert np.isfinite(got).all() and got.max() == pytest.approx(top, rel=2 ** -11)


def test_nan_and_infinity_survive_and_u8_is_bytes():
    a = np.array([[[np.nan, np.inf, 1.0]]], np.float32)
    got = _decode(encode(a))
    assert np.isnan(got[0, 0, 0]) and got[0, 0, 1] == np.inf and got[0, 0, 2] == 1.0
    mask = np.random.default_rng(1).random((5, 6)) > 0.5
    assert (_decode(encode(mask.astype(np.uint8), "u8")) == mask).all()


def test_page_holds_everything_inline_and_escapes_names(tmp_path):
    evil = "</script><script>alert(1)</script>"
    page = Page(f"run {evil}", layers=[Layer(evil, np.ones((4, 5, 3))), Layer("cut", np.arange(20.0).reshape(4, 5),
                                                                             "cut")],
                scales={"cut": Scale(19.0, "nodes")}, mask=np.eye(4, 5, dtype=bool),
                tables=[Table("Rows", [("a", "A <b>", "{:.2f}"), ("b", "B", None)], [{"a": 1.234, "b": evil},
                                                                                       {"a": None, "b": 2}])],
                record={"note": evil})
    stats = write_report(tmp_path / "report.html", page)
    text = (tmp_path / "report.html").read_text()
    assert stats["bytes"] == len(text.encode())
    assert text.count("<script") == 2 and text.count("</script>") == 2  # the data and the viewer, nothing else
    data = _data(text)
    assert data["layers"][0]["name"] == evil and data["layers"][1]["kind"] == "scalar"
    assert (_decode(data["mask"]) == np.eye(4, 5)).all()
    assert '<td class="n" data-v="1.234">1.23</td>' in text and "<td></td>" in text and "A &lt;b&gt;" in text
    assert "http" not in text and "<link" not in text
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_a_page_without_images_has_no_viewer():
    text = page_html(Page("t", tables=[Table("x", [("a", "A", None)], [{"a": 1}])]))
    assert 'id="lc-canvas"' not in text and _data(text)["layers"] == []


def test_the_viewer_files_are_package_data():
    """An installed (not editable) lightcuts must carry viewer.js and viewer.css: pyproject.toml's
    package-data names every file of lightcuts/report/viewer/."""
    import fnmatch
    import tomllib
    from pathlib import Path

    root = Path(__file__).parents[2]
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"][
        "lightcuts.report"]
    viewer = root / "lightcuts" / "report" / "viewer"
    files = [f"viewer/{p.name}" for p in viewer.iterdir()]
    assert sorted(files) == ["viewer/viewer.css", "viewer/viewer.js"]
    assert all(any(fnmatch.fnmatch(f, pat) for pat in patterns) for f in files)
