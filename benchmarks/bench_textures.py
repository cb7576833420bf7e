"""What albedo textures cost: a scene rendered with and without textures on every material.

The textured copies of a mesh: its OBJ beside a copy of its MTL in which every material gets a
``map_Kd`` of its own, a generated ``--texture-size`` square PNG: ``white`` (every texel 1, so the
image, the lights and the cuts are the untextured ones and the difference is the lookups alone) and
``noise`` (seeded value noise, sRGB codes 150 to 255: a stone-like pattern, darker, so its lights and
cuts differ too). The versions render the same config (``lightcuts.render``), interleaved
``--repeats`` times; per version the medians of the report's preprocess (scene with its images,
caster, lights: the particle tracer reads textures), build and render seconds, the mean cut and the
image's mean luminance. Prints a table and writes ``benchmarks/results/textures.csv``.

    PYTHONPATH=. python benchmarks/bench_textures.py benchmarks/scenes/sibenik.yaml
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def noise_texture(rng, size: int, white: bool = False) -> np.ndarray:
    """(size, size, 3) uint8: bilinearly upsampled 16 x 16 random codes in [150, 255], tinted (all
    255 if ``white``)."""
    if white:
        return np.full((size, size, 3), 255, np.uint8)
    coarse = rng.uniform(150, 255, size=(17, 17))
    x = np.linspace(0, 16, size, endpoint=False)
    i, t = x.astype(int), x - x.astype(int)
    rows = coarse[i] * (1 - t)[:, None] + coarse[i + 1] * t[:, None]
    grey = rows[:, i] * (1 - t)[None, :] + rows[:, i + 1] * t[None, :]
    tint = rng.uniform(0.9, 1.0, size=3)
    return np.clip(grey[:, :, None] * tint, 0, 255).astype(np.uint8)


def textured_copy(obj: Path, folder: Path, size: int, white: bool, seed: int = 0) -> Path:
    """The OBJ (symlinked) beside its MTL with a generated map_Kd per material; returns the OBJ's path."""
    from PIL import Image

    text = obj.read_text(errors="replace")
    libs = re.findall(r"^mtllib\s+(.+)$", text, re.M)
    rng = np.random.default_rng(seed)
    for lib in libs:
        out = []
        for line in (obj.parent / lib.strip()).read_text(errors="replace").splitlines():
            out.append(line)
            m = re.match(r"\s*newmtl\s+(.+)", line)
            if m:
                name = f"tex_{len(out)}.png"
                Image.fromarray(noise_texture(rng, size, white)).save(folder / name)
                out.append(f"map_Kd {name}")
        (folder / lib.strip()).write_text("\n".join(out) + "\n")
    link = folder / obj.name
    link.symlink_to(obj.resolve())
    return link


def main() -> None:
    import yaml

    import lightcuts
    from lightcuts.io import save_csv
    from lightcuts.lights.lightset import LUMINANCE

    p = argparse.ArgumentParser()
    p.add_argument("config")
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--set", nargs="*", default=[], help="config overrides KEY=VALUE")
    a = p.parse_args()
    overrides = {k: yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in a.set)}
    cfg = lightcuts.load_config(a.config, **overrides)
    obj = cfg.resolve(cfg.scene.meshes[0].file)
    rows = {"untextured": [], "white": [], "noise": []}
    with tempfile.TemporaryDirectory() as tmp:
        versions = {"untextured": cfg}
        for name in ("white", "noise"):
            (Path(tmp) / name).mkdir()
            path = textured_copy(Path(obj), Path(tmp) / name, a.texture_size, white=name == "white")
            versions[name] = lightcuts.load_config(a.config, **{**overrides, "scene.meshes.0.file": str(path)})
        for c in versions.values():  # numba's caches, before timing
            lightcuts.render(c, progress=False)
        for _ in range(a.repeats):
            for name, c in versions.items():
                r = lightcuts.render(c, progress=False)
                rows[name].append((r.report["preprocess_seconds"], r.report["build_seconds"],
                                   r.report["render_seconds"], r.report["cut_size_mean"],
                                   float((r.image.astype(np.float64) @ LUMINANCE).mean())))
    table = []
    for name, runs in rows.items():
        med = [statistics.median(x[k] for x in runs) for k in range(5)]
        table.append({"version": name, "preprocess_s": med[0], "build_s": med[1], "render_s": med[2],
                      "cut_mean": med[3], "mean_luminance": med[4], "repeats": a.repeats,
                      "texture_size": a.texture_size})
    for t in table:
        t["render_ratio"] = t["render_s"] / table[0]["render_s"]
    print(f"{'version':<12} {'preprocess s':>12} {'build s':>8} {'render s':>9} {'render x':>9} {'cut':>7} {'mean L':>8}")
    for t in table:
        print(f"{t['version']:<12} {t['preprocess_s']:12.2f} {t['build_s']:8.2f} {t['render_s']:9.2f} "
              f"{t['render_ratio']:9.3f} {t['cut_mean']:7.1f} {t['mean_luminance']:8.4f}")
    save_csv(ROOT / "benchmarks" / "results" / "textures.csv", table)


if __name__ == "__main__":
    main()
