"""SHA-256 of every output of the shipped configs, to show that a change moves no byte.

    python tools/output_hashes.py OUT.json [--quick] [--configs cornell,kitchen]

Runs, in a subprocess each, ``lightcuts render`` on every config in ``configs/`` (image.exr,
image.png, cutsize.png), ``lightcuts lights`` (every light file), ``lightcuts tree`` for every
builder that takes the config's lights, and ``lightcuts render`` with a non-Embree caster on
``cornell.yaml``; writes ``{output: sha256}``. Times (report.json) are not hashed. ``--quick``
renders at a quarter of each side. Compare two runs with ``diff``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUILDERS = ("agglomerative", "agglomerative-heap", "divisive-6d", "divisive-3d", "saoh")
IMAGES = ("image.exr", "image.png", "cutsize.png")


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(args: list[str]) -> None:
    r = subprocess.run([sys.executable, "-m", "lightcuts", *args], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"lightcuts {' '.join(args)} failed:\n{r.stderr[-2000:]}")


def resolution(config: Path, quick: bool) -> list[str]:
    if not quick:
        return []
    from lightcuts.config import load_config
    from lightcuts.scene.build import image_size

    w, h = image_size(load_config(config))
    return ["--set", f"camera.resolution=[{max(w // 4, 1)},{max(h // 4, 1)}]"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--configs", default=None, help="comma-separated config stems (default: all)")
    a = ap.parse_args()
    configs = sorted((ROOT / "configs").glob("*.yaml"))
    if a.configs:
        configs = [c for c in configs if c.stem in a.configs.split(",")]
    hashes: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for cfg in configs:
            res = resolution(cfg, a.quick)
            out = tmp / f"render-{cfg.stem}"
            run(["render", str(cfg), "--out", str(out), *res])
            for f in IMAGES:
                hashes[f"{cfg.stem}/render/{f}"] = sha(out / f)
            lights = tmp / f"lights-{cfg.stem}.npz"
            run(["lights", str(cfg), "--out", str(lights)])
            for f in sorted(tmp.glob(f"lights-{cfg.stem}*.npz")):
                hashes[f"{cfg.stem}/lights/{f.name}"] = sha(f)
            if cfg.stem in ("cornell", "sun-env"):
                for b in BUILDERS:
                    t = tmp / f"tree-{cfg.stem}-{b}.npz"
                    run(["tree", str(cfg), "--builder", b, "--out", str(t)])
                    for f in sorted(tmp.glob(f"tree-{cfg.stem}-{b}*.npz")):
                        hashes[f"{cfg.stem}/tree/{f.name}"] = sha(f)
            if cfg.stem == "cornell":
                out = tmp / "render-cornell-bvh"
                run(["render", str(cfg), "--out", str(out), "--set", "render.ray_caster=bvh-sah",
                     "--set", "camera.resolution=[128,128]"])
                for f in IMAGES:
                    hashes[f"cornell/render-bvh-sah/{f}"] = sha(out / f)
            print(cfg.stem, "done", file=sys.stderr, flush=True)
    tmp_out = Path(a.out).with_suffix(".tmp")
    tmp_out.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
    os.replace(tmp_out, a.out)


if __name__ == "__main__":
    main()
