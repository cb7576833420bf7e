"""Regenerate the README's gallery, ``docs/images/*.png``: every shipped config's image, a compare's
cut-size panel and a screenshot of a compare's report.html.

    python tools/gallery.py [--width 320] [--out docs/images]

Each config is rendered as shipped but at ``--width`` pixels wide (its aspect kept; the depth of
field kitchen and the Fig. 8 configs keep their gather points), through its own tone map; the
compare is ``lightcuts compare configs/cornell.yaml`` at 192 x 192 with the default rows; the
screenshot is headless Chromium (as the browser tests drive it) showing that compare's report.html
with the error view on. PNGs are stored with a 256-colour palette to stay small. Takes a few
minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: (config, gallery file), in the README's order.
CONFIGS = (("cornell.yaml", "cornell.png"), ("cornell-glossy.yaml", "cornell-glossy.png"),
           ("sun-env.yaml", "sun-env.png"), ("kitchen.yaml", "kitchen.png"), ("kitchen-dof.yaml", "kitchen-dof.png"), ("rooms.yaml", "rooms.png"),
           ("mesh-gallery.yaml", "mesh-gallery.png"))


def save_small(image, path: Path, width: int | None = None) -> None:
    """A PIL image as a 256-colour PNG, resized to ``width`` (aspect kept) when given."""
    from PIL import Image

    if width is not None and image.width != width:
        image = image.resize((width, round(image.height * width / image.width)), Image.LANCZOS)
    image.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.FLOYDSTEINBERG).save(
        path, optimize=True)
    print(f"{path}: {path.stat().st_size / 1024:.0f} KB", flush=True)


def screenshot(html: Path, out: Path, width: int, profile: Path) -> None:
    """report.html in headless Chromium (its profile in the folder ``profile``), the error view on,
    the top of the page."""
    import io

    from PIL import Image
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--window-size=1100,900", f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(options=options, service=Service("/usr/bin/chromedriver"))
    try:
        driver.get(html.as_uri())
        for _ in range(200):
            if driver.execute_script("return document.body.dataset.ready"):
                break
            time.sleep(0.05)
        driver.execute_script("const r = document.getElementById('lc-range'); r.value = '0.02';"
                              "r.dispatchEvent(new Event('change'));"
                              "document.dispatchEvent(new KeyboardEvent('keydown', {key: '2'}));"
                              "document.dispatchEvent(new KeyboardEvent('keydown', {key: 'e'}));")
        time.sleep(0.3)
        shot = Image.open(io.BytesIO(driver.get_screenshot_as_png()))
    finally:
        driver.quit()
    save_small(shot.crop((0, 0, shot.width, min(shot.height, 860))), out, width)


def main(argv=None) -> int:
    from lightcuts.cli import main as cli

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=320, help="width of the render images (default 320)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "images"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="lightcuts-gallery-") as work:
        make(Path(work), out, args.width, cli)
    return 0


def make(work: Path, out: Path, width: int, cli) -> None:
    """Render, compare and screenshot in ``work``; the small PNGs into ``out``."""
    from PIL import Image

    from lightcuts.config import load_config

    for config, name in CONFIGS:
        cfg = load_config(ROOT / "configs" / config)
        w, h = cfg.camera.resolution or (512, 512)
        size = f"camera.resolution=[{width},{round(h * width / w)}]"
        t0 = time.perf_counter()
        assert cli(["render", str(ROOT / "configs" / config), "--out", str(work / name), "--no-progress",
                    "--set", size]) == 0, config
        print(f"{config}: {time.perf_counter() - t0:.1f} s", flush=True)
        save_small(Image.open(work / name / "image.png"), out / name)
    assert cli(["compare", str(ROOT / "configs/cornell.yaml"), "--out", str(work / "compare"), "--no-progress",
                "--set", "camera.resolution=[192,192]"]) == 0
    save_small(Image.open(work / "compare" / "cutsizes.png"), out / "compare-cutsizes.png", 960)
    screenshot(work / "compare" / "report.html", out / "report-html.png", 800, work / "chromium")


if __name__ == "__main__":
    sys.exit(main())
