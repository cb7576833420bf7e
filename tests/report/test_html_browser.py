"""report.html in a real browser: headless Chromium driven by Selenium opens each kind of report,
flips images, zooms, pans, moves the exposure and the tone map, turns on the error view, sorts a
table, and the canvas holds exactly the pixels the Python side computes; no console error.

The browser is Debian's ``chromium`` and ``chromium-driver`` (``.ci/run`` installs them). Without
them these tests skip, except under CI (``CI=true``), where they fail.
"""

from __future__ import annotations

import base64
import io
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lightcuts.report.html import colormap, viewer_values
from lightcuts.report.images import read_exr
from lightcuts.report.tonemap import OPERATORS, srgb8

ROOT = Path(__file__).parents[2]
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--window-size=1280,1000")
SMALL = ["--set", "lights.indirect.count=1500", "--set", "lights.direct.count=128", "--no-progress"]
#: They start a browser: left out of the quick loop (pytest -m "not slow").
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """One headless Chromium for the module (a fresh profile); skipped without it, failed under CI."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not shutil.which(p)]
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        missing.append("selenium")
    if missing:
        message = f"the browser tests need {', '.join(missing)} (apt-get install chromium chromium-driver)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(message)
        pytest.skip(message)
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS + (f"--user-data-dir={tmp_path_factory.mktemp('chromium')}",):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(CHROMEDRIVER))
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A tiny run of every command that writes report.html: kind -> its folder."""
    from lightcuts.cli import main

    base = tmp_path_factory.mktemp("reports")
    cornell = str(ROOT / "configs/cornell.yaml")
    argv = {
        "render": ["render", cornell, "--reference", "--set", "camera.resolution=[40,30]",
                   "--set", "render.tonemap={type: reinhard, exposure: 0.5}"],
        "compare": ["compare", cornell, "--builders", "agglomerative,divisive-6d,divisive-3d", "--pixels", "150",
                    "--set", "camera.resolution=[40,30]"],
        "reference": ["reference", cornell, "--renderer", "lightcuts", "--spp", "4",
                      "--set", "camera.resolution=[32,24]"],
        "accel": ["accel", cornell, "--casters", "embree,bvh-sah", "--repeats", "1", "--set",
                  "camera.resolution=[24,24]"],
        "scaling": ["scaling", cornell, "--sizes", "300,600", "--builders", "divisive-3d,agglomerative", "--repeats",
                    "1"],
    }
    out = {}
    for kind, args in argv.items():
        out[kind] = base / kind
        assert main(args + ["--out", str(out[kind])] + SMALL) == 0, kind
    return out


def _open(driver, folder: Path):
    driver.get((folder / "report.html").as_uri())
    for _ in range(200):
        if driver.execute_script("return document.body.dataset.ready"):
            break
        time.sleep(0.025)
    assert driver.execute_script("return document.body.dataset.ready") == "1"


def _errors(driver) -> list:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def _canvas(driver) -> np.ndarray:
    """The viewer's canvas as (h, w, 3) uint8 (read as a PNG: lossless)."""
    url = driver.execute_script("return document.getElementById('lc-canvas').toDataURL('image/png')")
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB"))


def _view(driver) -> dict:
    return driver.execute_script("return Object.assign({}, window.lcViewer.state.view)")


def _shown(driver, w: int, h: int) -> np.ndarray:
    """At 1:1, the image's pixels on the canvas."""
    v = _view(driver)
    assert v["s"] == 1 and v["x"] == int(v["x"]) and v["y"] == int(v["y"])
    return _canvas(driver)[int(v["y"]):int(v["y"]) + h, int(v["x"]):int(v["x"]) + w]


def _key(driver, key: str):
    driver.execute_script("document.dispatchEvent(new KeyboardEvent('keydown', {key: arguments[0]}))", key)


def _set(driver, element_id: str, value, event: str):
    driver.execute_script("const e = document.getElementById(arguments[0]); e.value = arguments[1];"
                          "e.dispatchEvent(new Event(arguments[2]))", element_id, str(value), event)


def _click(driver, element_id: str):
    driver.find_element("id", element_id).click()


def _lum(a):
    return 0.2126 * a[..., 0] + 0.7152 * a[..., 1] + 0.0722 * a[..., 2]


@pytest.mark.parametrize("kind, images, tables", [("render", 3, 1), ("compare", 7, 1), ("reference", 2, 1),
                                                  ("accel", 0, 1), ("scaling", 0, 1)])
def test_each_kind_of_report_opens_offline_without_console_errors(browser, runs, kind, images, tables):
    _open(browser, runs[kind])
    buttons = browser.execute_script("return document.querySelectorAll('#lc-layers button').length")
    assert buttons == images
    n_tables = browser.execute_script("return document.querySelectorAll('table.lc-sortable').length")
    assert n_tables >= tables + 1  # the run's and the machine's
    text = (runs[kind] / "report.html").read_text()
    assert "http://" not in text.split("<script>")[0] and "<link" not in text and 'src="http' not in text
    assert _errors(browser) == []


def test_pixels_are_the_tone_mapped_linear_values(browser, runs):
    """At 1:1 the canvas holds srgb8 of the image's float16 values, for the config's tone map and
    after each change of operator and exposure."""
    folder = runs["render"]
    _open(browser, folder)
    _click(browser, "lc-one")
    image = viewer_values(read_exr(folder / "image.exr"))
    h, w = image.shape[:2]
    assert (_shown(browser, w, h) == srgb8(image, "reinhard", 0.5)).all()
    for op, exposure in (("aces", 1.5), ("clip", -1.0), ("hable", 2.0)):
        _set(browser, "lc-tonemap", op, "change")
        _set(browser, "lc-exposure", exposure, "input")
        shown = _shown(browser, w, h)
        assert (shown == srgb8(image, op, exposure)).all(), (op, exposure)
    _key(browser, "]")  # half a stop up
    assert (_shown(browser, w, h) == srgb8(image, "hable", 2.5)).all()
    assert _errors(browser) == []


def test_number_keys_and_buttons_flip_the_images(browser, runs):
    from lightcuts.report.compare import cut_colours

    folder = runs["render"]
    _open(browser, folder)
    _click(browser, "lc-one")
    reference = viewer_values(read_exr(folder / "reference.exr"))
    h, w = reference.shape[:2]
    _key(browser, "2")
    assert (_shown(browser, w, h) == srgb8(reference, "reinhard", 0.5)).all()
    browser.find_elements("css selector", "#lc-layers button")[2].click()  # the cut sizes
    report = json.loads((folder / "report.json").read_text())
    # the cut-size map is not tone-mapped: the exposure leaves it alone
    _set(browser, "lc-exposure", 3, "input")
    cuts = _cut_of(folder)
    assert cuts.max() == report["cut_size_max"] and cuts.mean() == pytest.approx(report["cut_size_mean"])
    assert (_shown(browser, w, h) == cut_colours(cuts, report["cut_size_max"])).all()
    _key(browser, "1")
    assert (_shown(browser, w, h) == srgb8(viewer_values(read_exr(folder / "image.exr")), "reinhard", 3.0)).all()
    assert _errors(browser) == []


def test_compare_rows_flip_to_their_own_pixels(browser, runs):
    """The rows after the first travel as bit differences from it: each decodes to its own image."""
    folder = runs["compare"]
    _open(browser, folder)
    _click(browser, "lc-one")
    for key, label in (("3", "divisive-3d"), ("2", "divisive-6d"), ("1", "agglomerative")):
        _key(browser, key)
        image = viewer_values(read_exr(folder / f"image-{label}.exr"))
        assert (_shown(browser, 40, 30) == srgb8(image)).all(), label
    # the seventh: the difference of the --diff rows' cut sizes on a symmetric diverging scale
    a, b = json.loads((folder / "report.json").read_text())["diff"]
    cut = {k: np.load(folder / "rows" / f"{k}.npz")["cut"].astype(np.float64) for k in (a, b)}
    diff = cut[a] - cut[b]
    lim = max(1.0, np.abs(diff).max())
    _key(browser, "7")
    assert (_shown(browser, 40, 30) == _diverging(viewer_values(diff), lim)).all()
    assert _errors(browser) == []


def _cut_of(folder: Path) -> np.ndarray:
    """The render's cut sizes, from the page's own data (report.html is all the render wrote of them)."""
    text = (folder / "report.html").read_text()
    data = json.loads(text.split('id="lc-data">', 1)[1].split("</script>", 1)[0])
    return _decode(next(layer for layer in data["layers"] if layer["kind"] == "scalar")["values"])


def _decode(a: dict) -> np.ndarray:
    """html.encode undone in Python (inflate, unshuffle, scale)."""
    import zlib

    typed = {"f16": np.float16, "f32": np.float32, "u8": np.uint8}[a["dtype"]]
    size = np.dtype(typed).itemsize
    raw = np.frombuffer(zlib.decompress(base64.b64decode(a["b64"])), np.uint8)
    values = raw.reshape(size, -1).T.copy().view(typed).reshape(a["shape"]).astype(np.float64)
    return values * 2.0 ** a["scale_log2"]


def test_zoom_and_pan_are_shared_by_every_image(browser, runs):
    from selenium.webdriver.common.action_chains import ActionChains

    folder = runs["render"]
    _open(browser, folder)
    canvas = browser.find_element("id", "lc-canvas")
    before = _view(browser)
    # the wheel zooms about the cursor: the image point under it stays put
    browser.execute_script("const c = arguments[0], r = c.getBoundingClientRect();"
                           "c.dispatchEvent(new WheelEvent('wheel', {deltaY: -300, clientX: r.left + 600,"
                           "clientY: r.top + 300, bubbles: true, cancelable: true}))", canvas)
    v = _view(browser)
    assert v["s"] == pytest.approx(before["s"] * 1.2 ** 3)
    assert (600 - v["x"]) / v["s"] == pytest.approx((600 - before["x"]) / before["s"])
    ActionChains(browser).move_to_element_with_offset(canvas, 0, 0).click_and_hold().move_by_offset(-37, 21) \
        .release().perform()
    panned = _view(browser)
    assert (panned["x"] - v["x"], panned["y"] - v["y"]) == (-37, 21)
    image = srgb8(viewer_values(read_exr(folder / "image.exr")), "reinhard", 0.5)
    reference = srgb8(viewer_values(read_exr(folder / "reference.exr")), "reinhard", 0.5)
    for key, expected in (("1", image), ("2", reference)):
        _key(browser, key)
        assert _view(browser) == panned  # flipping keeps the view
        shown = _canvas(browser)
        checked = 0
        for cy in range(3, shown.shape[0], 23):
            for cx in range(5, shown.shape[1], 29):
                fx, fy = (cx + 0.5 - panned["x"]) / panned["s"], (cy + 0.5 - panned["y"]) / panned["s"]
                if not (0 <= fx < image.shape[1] and 0 <= fy < image.shape[0]):
                    continue
                if min(fx % 1, 1 - fx % 1, fy % 1, 1 - fy % 1) * panned["s"] < 0.6:
                    continue  # within a canvas pixel of an image pixel's edge
                assert (shown[cy, cx] == expected[int(fy), int(fx)]).all(), (key, cx, cy)
                checked += 1
        assert checked > 100
    _click(browser, "lc-fit")
    assert _view(browser) == before
    assert _errors(browser) == []


def _diverging(error: np.ndarray, span: float) -> np.ndarray:
    lut = np.frombuffer(colormap("RdBu_r"), np.uint8).reshape(256, 3)
    return lut[np.clip(np.floor((error / span + 1) / 2 * 256), 0, 255).astype(int)]


def test_error_view_against_a_whole_reference(browser, runs):
    folder = runs["render"]
    _open(browser, folder)
    _click(browser, "lc-one")
    _key(browser, "e")
    _set(browser, "lc-range", 0.05, "change")
    image, reference = (viewer_values(read_exr(folder / f)) for f in ("image.exr", "reference.exr"))
    ref = _lum(reference)
    expected = _diverging((_lum(image) - ref) / np.where(ref > 0, ref, 1), 0.05)
    expected[~(ref > 0.01 * ref.mean())] = 32  # too dark to measure
    shown = _shown(browser, *image.shape[1::-1])
    assert (shown == expected).all()
    assert len(np.unique(shown.reshape(-1, 3), axis=0)) > 20  # the errors differ pixel by pixel
    assert _errors(browser) == []


def test_error_view_greys_the_pixels_that_see_an_emitter(browser, runs):
    folder = runs["reference"]
    _open(browser, folder)
    _click(browser, "lc-one")
    _key(browser, "e")
    image, path = (viewer_values(read_exr(folder / f)) for f in ("lightcuts.exr", "path.exr"))
    shown = _shown(browser, *image.shape[1::-1])
    masked = (shown == 96).all(axis=-1)
    report = json.loads((folder / "report.json").read_text())
    assert masked.sum() == report["comparison"]["masked_pixels"] > 0
    ref = _lum(path)
    keep = ~masked & (ref > 0.01 * ref[~masked].mean())
    expected = _diverging((_lum(image) - ref) / np.where(ref > 0, ref, 1), 0.1)
    assert (shown[keep] == expected[keep]).all()
    assert _errors(browser) == []


def test_error_view_at_the_sampled_reference_pixels(browser, runs):
    """compare's reference is known at a sample of pixels: a square of each one's error colour."""
    folder = runs["compare"]
    _open(browser, folder)
    _click(browser, "lc-one")
    for _ in range(5):
        _click(browser, "lc-zoom-in")  # 1.5^5 = 7.6 canvas pixels an image pixel: a square each
    _key(browser, "e")
    from lightcuts.commands.compare import sample_pixels

    assert json.loads((folder / "report.json").read_text())["pixels"] == 150
    xy = sample_pixels(40, 30, None, 150, seed=1)  # the config's seed
    ref = np.load(folder / "rows" / "reference.npz")["image"].astype(np.float64)
    image = viewer_values(read_exr(folder / "image-agglomerative.exr"))
    v, shown = _view(browser), _canvas(browser)
    lref = _lum(ref)
    floor = 0.01 * lref.mean()
    assert v["s"] == pytest.approx(1.5 ** 5)
    measured = [(x, y, lr) for (x, y), lr in zip(xy, lref) if lr > floor]
    assert len(measured) > 100
    for x, y, lr in measured:
        cx, cy = int(v["x"] + (x + 0.5) * v["s"]), int(v["y"] + (y + 0.5) * v["s"])
        assert (shown[cy, cx] == _diverging(np.array((_lum(image[y, x]) - lr) / lr), 0.1)).all(), (x, y)
    # away from the squares, the image dimmed to 35%
    near = np.zeros((30, 40), bool)
    for x, y in xy:
        near[max(0, y - 1):y + 2, max(0, x - 1):x + 2] = True
    dimmed = np.round(srgb8(image) * 0.35)
    assert (~near).sum() > 50
    for y, x in zip(*np.nonzero(~near)):
        assert (shown[int(v["y"] + (y + 0.5) * v["s"]), int(v["x"] + (x + 0.5) * v["s"])] == dimmed[y, x]).all()
    assert _errors(browser) == []


@pytest.mark.parametrize("op", OPERATORS)
def test_javascript_and_python_tone_maps_agree(browser, runs, op):
    _open(browser, runs["render"])
    values = [[0.0, 0.0, 0.0], [0.18, 0.5, 0.9], [3.0, 0.7, 0.2], [0.002, 0.001, 0.0005], [40.0, 10.0, 1.0],
              [1e-7, 5.0, 1e6], [float("nan"), float("inf"), -1.0]]
    as_json = [[str(x) if not np.isfinite(x) else x for x in v] for v in values]  # JSON has no NaN, inf
    for exposure in (0.0, 1.3, -2.7):
        got = browser.execute_script(
            "const f = (x) => typeof x === 'string' ? Number(x.replace('inf', 'Infinity')) : x;"
            "return arguments[0].map((v) => Array.from(window.lcViewer.toneMap(f(v[0]), f(v[1]), f(v[2]),"
            " arguments[1], Math.pow(2, arguments[2]), [0, 0, 0])));", as_json, op, exposure)
        expected = srgb8(np.array([values]), op, exposure)[0]
        assert np.array_equal(np.array(got), expected), (op, exposure)


def test_tables_sort_by_a_column(browser, runs):
    _open(browser, runs["compare"])
    header = browser.find_elements("css selector", "table.lc-sortable th")[3]  # Avg cutsize
    assert header.text.startswith("Avg cutsize")
    values = ("return Array.from(document.querySelector('table.lc-sortable').tBodies[0].rows)"
              ".map(r => +r.cells[3].dataset.v)")
    header.click()
    up = browser.execute_script(values)
    header.click()
    down = browser.execute_script(values)
    assert up == sorted(up) and down == sorted(up, reverse=True) and len(set(up)) == 3
    assert _errors(browser) == []
