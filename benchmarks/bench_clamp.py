"""The clamp at two scales: lightcuts' energy against a reference on one room and on the same rooms
spread over a few hundred metres (docs/performance.md, "The clamp at every scale").

The scene (:func:`spread_rooms`): closed rooms of ``ROOM`` = 10 x 4 x 10 m on a ``side`` x ``side``
grid ``pitch`` metres apart on a ground quad, each lit by a 2 x 2 m ceiling lamp, with two blocks and
a red and a green wall; the camera in room 0. One room alone has a diagonal of about 15 m; 3 x 3
rooms 135 m apart about 400 m. Indirect VPLs scale with the rooms (``--vpls`` per room), so the
VPLs' density per room is the same at both scales.

For each scene it renders the default clamp (``render.clamp`` unset: mode density), the old default
(mode diagonal, min_distance 0.05), clamping off and the path integrator (``render.integrator:
path``, ``--path-spp``), and prints each one's energy against the path tracer and against clamping
off, the pixels that see an emitter left out (lightcuts.report.images.compare_images), with the
clamp radius and clamped fraction of report.json.

    python benchmarks/bench_clamp.py --size 48 --path-spp 512
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: A room's inside, metres (x, y, z), walls 0.2 m thick.
ROOM = (10.0, 4.0, 10.0)
WALL = 0.2


def _box(lo, hi) -> tuple[list, list]:
    """The 8 corners and 12 outward triangles (1-based in the caller) of the box [lo, hi]."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 4, 7, 3), (1, 2, 6, 5), (0, 1, 5, 4), (3, 7, 6, 2)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, f


def spread_rooms(folder: Path, side: int, pitch: float, vpls_per_room: int, size: int) -> Path:
    """Write rooms.obj/.mtl and rooms.yaml (module docstring) into ``folder``; returns the YAML's path."""
    w, h, d = ROOM
    verts, faces = [], []  # faces: (material, (i, j, k)) 0-based

    def add(box, material):
        v, f = _box(*box)
        base = len(verts)
        verts.extend(v)
        faces.extend((material, (base + a, base + b, base + c)) for a, b, c in f)

    for i in range(side):
        for k in range(side):
            ox, oz = i * pitch, k * pitch
            t = WALL
            add(((ox - t, -t, oz - t), (ox + w + t, 0.0, oz + d + t)), "white")  # floor slab
            add(((ox - t, h, oz - t), (ox + w + t, h + t, oz + d + t)), "white")  # ceiling slab
            add(((ox - t, 0.0, oz - t), (ox, h, oz + d + t)), "red")
            add(((ox + w, 0.0, oz - t), (ox + w + t, h, oz + d + t)), "green")
            add(((ox, 0.0, oz - t), (ox + w, h, oz)), "white")
            add(((ox, 0.0, oz + d), (ox + w, h, oz + d + t)), "white")
            add(((ox + 2.0, 0.0, oz + 5.5), (ox + 4.5, 2.5, oz + 8.0)), "white")  # tall block
            add(((ox + 6.0, 0.0, oz + 4.0), (ox + 8.5, 1.2, oz + 6.5)), "white")  # short block
    extent = (side - 1) * pitch + w
    m = 2.0
    ground = [(-m, -WALL - 0.01, -m), (extent + m, -WALL - 0.01, -m), (extent + m, -WALL - 0.01, extent + m),
              (-m, -WALL - 0.01, extent + m)]
    base = len(verts)
    verts.extend(ground)
    faces += [("white", (base, base + 2, base + 1)), ("white", (base, base + 3, base + 2))]
    lines = ["mtllib rooms.mtl"] + [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in verts]
    for material in ("white", "red", "green"):
        lines.append(f"usemtl {material}")
        lines += [f"f {a + 1} {b + 1} {c + 1}" for mat, (a, b, c) in faces if mat == material]
    (folder / "rooms.obj").write_text("\n".join(lines) + "\n")
    (folder / "rooms.mtl").write_text("newmtl white\nKd 0.7 0.7 0.7\nnewmtl red\nKd 0.63 0.06 0.05\n"
                                      "newmtl green\nKd 0.14 0.45 0.09\n")
    lamps = {"shape": "quad", "normal": [0, -1, 0], "size": [2.0, 2.0], "radiance": [20.0, 18.0, 15.0],
             "grid": {"lo": [w / 2 - pitch / 2, h - 0.01, d / 2 - pitch / 2],  # cell centres: the rooms'
                      "hi": [w / 2 + (side - 0.5) * pitch, h - 0.01, d / 2 + (side - 0.5) * pitch],
                      "count": [side, 1, side]}}
    cfg = {"name": f"rooms-{side}x{side}", "seed": 1, "scene": {"meshes": [{"file": "rooms.obj"}], "emitters": [lamps]},
           "camera": {"position": [w / 2, 2.0, 0.4], "look_at": [w / 2, 1.6, d], "up": [0, 1, 0], "fov": 70,
                      "resolution": [size, size]},
           "lights": {"direct": {"count": 1024 * side * side},
                      "indirect": {"count": vpls_per_room * side * side}}}
    path = folder / "rooms.yaml"
    path.write_text(json.dumps(cfg, indent=1))
    return path


#: The renders of each scene: (label, config overrides).
RUNS = (("default (density)", {}),
        ("old default (diagonal 0.05)", {"render.clamp.min_distance": 0.05}),
        ("clamping off", {"render.clamp.enabled": False}))


def measure(path: Path, path_spp: int) -> list[dict]:
    """Each of RUNS and the path tracer on the config at ``path``: label, energy against the path
    tracer and against clamping off, clamp radius, clamped fraction."""
    import lightcuts
    from lightcuts.integrators.primary import emitter_mask
    from lightcuts.pipeline.plan import plan_run
    from lightcuts.report.images import compare_images

    images, rows = {}, []
    for label, over in RUNS:
        r = lightcuts.render(lightcuts.load_config(path, **over))
        images[label] = r.image
        rows.append({"label": label, "radius": r.report["clamping"]["radius"],
                     "clamped": r.report["clamping"]["clamped_energy_fraction"],
                     "diagonal": r.report["scene"]["diagonal"], "image_seconds": r.report["image_seconds"]})
    cfg = lightcuts.load_config(path, **{"render.integrator": "path", "render.spp": path_spp})
    ref = lightcuts.render(cfg).image
    plan = plan_run(cfg, render=True)
    scene = plan.scene()
    with plan.make_caster(scene) as caster:
        mask = emitter_mask(scene, caster, None, False)
    for row in rows:
        row["vs_path"] = compare_images(images[row["label"]], ref, mask=mask)["energy_ratio"]
        row["vs_off"] = compare_images(images[row["label"]], images["clamping off"], mask=mask)["energy_ratio"]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=48, help="image width and height, pixels")
    ap.add_argument("--vpls", type=int, default=40_000, help="indirect VPLs per room")
    ap.add_argument("--path-spp", type=int, default=512, help="the path tracer's samples per pixel")
    ap.add_argument("--side", type=int, default=3, help="rooms per side of the large scene")
    ap.add_argument("--pitch", type=float, default=135.0, help="metres between the large scene's rooms")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for side, pitch in ((1, 0.0), (a.side, a.pitch)):
            folder = Path(tmp) / f"s{side}"
            folder.mkdir()
            for row in measure(spread_rooms(folder, side, pitch, a.vpls, a.size), a.path_spp):
                print(f"{side}x{side} rooms, diagonal {row['diagonal']:.0f} m: {row['label']}: radius "
                      f"{row['radius']:.3f} m, clamped {row['clamped']:.4f}, energy vs path "
                      f"{row['vs_path']:.4f}, vs clamping off {row['vs_off']:.4f}, image {row['image_seconds']:.2f} s",
                      flush=True)


if __name__ == "__main__":
    main()
