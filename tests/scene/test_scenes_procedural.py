"""The procedural scenes (kitchen, building of rooms, gallery): deterministic, the requested triangle
count, the size range, watertight solids, emitters facing into their rooms, shipped configs build."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from lightcuts.config.schema import load_config
from lightcuts.errors import LightcutsError
from lightcuts.scene import gallery, kitchen, rooms
from lightcuts.scene.build import image_size, scene_from_config
from lightcuts.scene.registry import make_scene
from lightcuts.scene.shapes import Curved, pose, resolutions

ROOT = Path(__file__).parents[2]
SMALL = 12_000


def _bytes(scene, tmp_path, name) -> bytes:
    return scene.save(tmp_path / f"{name}.npz").read_bytes()


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    a = make_scene(dict(type="kitchen", triangles=SMALL, seed=3))
    b = make_scene(dict(type="kitchen", triangles=SMALL, seed=3))
    c = make_scene(dict(type="kitchen", triangles=SMALL, seed=4))
    assert _bytes(a, tmp_path, "a") == _bytes(b, tmp_path, "b")
    assert _bytes(a, tmp_path, "a") != _bytes(c, tmp_path, "c")
    r1 = make_scene(dict(type="rooms", rooms=2, triangles=SMALL, seed=3))
    r2 = make_scene(dict(type="rooms", rooms=2, triangles=SMALL, seed=3))
    assert _bytes(r1, tmp_path, "r1") == _bytes(r2, tmp_path, "r2")


@pytest.mark.parametrize("target", [SMALL, 40_000, 150_000])
def test_triangle_count_honoured(target):
    n = kitchen.kitchen_parts(target, 0).n_faces
    assert abs(n - target) <= 0.01 * target, n


def test_resolutions_hit_budget_and_favour_large_objects():
    items = [Curved("cylinder", (0.01, 0.1), pose(), "metal", w) for w in (0.3, 1.0, 3.0)]
    items.append(Curved("sphere", (0.1,), pose(), "metal", 2.0))
    k = resolutions(items, 5000)
    total = 4 * k[:3].sum() + 4 * (k[3] + k[3] % 2) * (k[3] + k[3] % 2 - 2)
    assert abs(total - 5000) < 0.05 * 5000
    assert k[0] <= k[1] <= k[2]


def test_kitchen_sizes_span_three_orders_of_magnitude():
    parts = kitchen.kitchen_parts(SMALL, 0)
    extents = parts.extents()
    assert extents.max() >= kitchen.W
    assert extents.max() / extents.min() >= 1000
    # the same from the scene's connected components (vertices joined by faces)
    scene = parts.to_scene(kitchen.PALETTE)
    label = np.arange(len(scene.vertices))
    while True:
        low = label[scene.faces].min(axis=1)
        new = label.copy()
        np.minimum.at(new, scene.faces.ravel(), np.repeat(low, 3))
        new = new[new]
        if np.array_equal(new, label):
            break
        label = new
    # one component per solid, one per emitter quad
    assert len(np.unique(label)) == sum(1 if c else len(f) // 2 for f, c in zip(parts.faces, parts.closed))
    order = np.argsort(label, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(label[order]) != 0])
    lo = np.minimum.reduceat(scene.vertices[order], starts)
    hi = np.maximum.reduceat(scene.vertices[order], starts)
    sizes = (hi - lo).max(axis=1)
    assert sizes.max() / sizes.min() >= 1000


@pytest.mark.parametrize("make", [lambda: kitchen.kitchen_parts(SMALL, 1),
                                  lambda: rooms.building_parts(3, SMALL, 1),
                                  lambda: gallery.gallery_parts(np.array([[0.3, 0.5, 0.3], [1.0, 1.2, 0.4]]))],
                         ids=["kitchen", "rooms", "gallery"])
def test_solids_watertight_emitters_open_quads(make):
    parts = make()
    assert any(parts.closed) and not all(parts.closed)
    for v, f, closed, mat in zip(parts.vertices, parts.faces, parts.closed, parts.materials):
        m = trimesh.Trimesh(v, f, process=False)
        if closed:
            assert m.is_watertight and m.is_winding_consistent and m.volume > 0, mat
        else:
            assert len(f) % 2 == 0 and len(v) == 2 * len(f)  # separate quads


def _room_centres(n_rooms):
    centre = np.array([kitchen.W / 2, kitchen.H / 2, kitchen.D / 2, 1.0])
    return np.array([(r["matrix"] @ centre)[:3] for r in rooms.layout(n_rooms)])


def _check_emitters_face_room(scene, centres, half_extent):
    """Every emitting triangle is inside its (nearest) room and its normal points at the room's centre."""
    e = scene.emitters
    assert len(e)
    mid = scene.triangles[e].mean(axis=1)
    room = np.argmin(np.linalg.norm(mid[:, None, [0, 2]] - centres[None, :, [0, 2]], axis=2), axis=1)
    to_centre = centres[room] - mid
    assert np.all(np.einsum("ij,ij->i", scene.face_normals[e], to_centre) > 0)
    assert np.all(np.abs(to_centre) < half_extent)


@pytest.mark.parametrize("n_rooms", [1, 2, 8])
def test_rooms_emitters_face_their_room(n_rooms):
    scene = make_scene(dict(type="rooms", rooms=n_rooms, triangles=SMALL))
    _check_emitters_face_room(scene, _room_centres(n_rooms), np.array([kitchen.W, kitchen.H, kitchen.D]) / 2)
    n_quads = len(scene.emitters) // 2
    if n_rooms == 8:
        assert n_quads >= 1000
    # the camera stands inside the first room
    lo = np.array([0.0, 0.0, 0.0])
    assert np.all(scene.camera.position > lo) and np.all(scene.camera.position < [kitchen.W, kitchen.H, kitchen.D])


def test_rooms_triangles_grow_linearly():
    counts = {n: rooms.building_parts(n, SMALL, 0).n_faces for n in (1, 2, 4)}
    for n, c in counts.items():
        assert abs(c - n * SMALL) <= 0.03 * n * SMALL, counts


def test_rooms_doorways_connect_every_room():
    """Neighbouring rooms (same row, adjacent columns; facing rows, same column) both cut a doorway."""
    lay = rooms.layout(6)
    assert [len(r["doors"]) for r in lay] == [2, 3, 2, 2, 3, 2]
    assert sum(r["window"] for r in lay) == 2


def test_gallery_stands_exhibits_on_plinths(tmp_path):
    box = trimesh.creation.box(extents=[0.2, 0.4, 0.2])
    path = tmp_path / "box.obj"
    box.export(path)
    text = ("name: g\nscene:\n  procedural: {type: gallery}\n  meshes:\n"
            f"    - {{file: {path}, scale: 2}}\n    - {{file: {path}, translate: [0, 0.1, 0]}}\n")
    (tmp_path / "g.yaml").write_text(text)
    scene = scene_from_config(load_config(tmp_path / "g.yaml"))
    n_room = gallery.gallery_parts(np.zeros((2, 3))).n_faces
    spots = gallery.plinth_spots(2)
    for i, (size, lift) in enumerate([(np.array([0.4, 0.8, 0.4]), 0.0), (np.array([0.2, 0.4, 0.2]), 0.1)]):
        v = scene.vertices[np.unique(scene.faces[n_room + 12 * i: n_room + 12 * (i + 1)])]
        assert np.allclose(v.min(axis=0)[1], gallery.plinth_size(size)[1] + lift)
        assert np.allclose(0.5 * (v.min(axis=0) + v.max(axis=0))[[0, 2]], spots[i])
    _check_emitters_face_room(scene, np.array([[gallery.GW / 2, gallery.GH / 2, gallery.GD / 2]]),
                              np.array([gallery.GW, gallery.GH, gallery.GD]) / 2)


def test_material_overrides_by_surface_name():
    base = make_scene(dict(type="kitchen", triangles=SMALL))
    over = make_scene(dict(type="kitchen", triangles=SMALL), {"worktop": {"exponent": 900}})
    changed = base.exponent != over.exponent
    assert changed.any() and np.all(over.exponent[changed] == 900)
    assert np.array_equal(base.albedo, over.albedo)
    with pytest.raises(LightcutsError, match=r"scene\.materials\.sofa: unknown surface"):
        make_scene(dict(type="kitchen", triangles=SMALL), {"sofa": {}})


@pytest.mark.parametrize("name", ["kitchen", "rooms", "mesh-gallery"])
def test_shipped_config_builds(name):
    cfg = load_config(ROOT / "configs" / f"{name}.yaml")
    scene = scene_from_config(cfg)
    assert (scene.camera.width, scene.camera.height) == image_size(cfg)
    lo, hi = scene.bounds
    assert np.all(scene.camera.position > lo) and np.all(scene.camera.position < hi)
    assert len(scene.emitters) >= 100
    if name != "mesh-gallery":
        assert abs(scene.n_faces - cfg.scene.procedural["triangles"] * cfg.scene.procedural.get("rooms", 1)) \
            <= 0.03 * scene.n_faces


def test_default_camera_and_image_size(tmp_path):
    (tmp_path / "k.yaml").write_text("scene: {procedural: {type: kitchen, triangles: 12000}}\n")
    cfg = load_config(tmp_path / "k.yaml")
    scene = scene_from_config(cfg)
    assert image_size(cfg) == (scene.camera.width, scene.camera.height) == kitchen.RESOLUTION
    assert np.all(scene.camera.position > 0) and np.all(scene.camera.position < [kitchen.W, kitchen.H, kitchen.D])


@pytest.mark.parametrize("n_rooms, axis", [(4, 0), (2, 2)], ids=["side", "front"])
def test_doorway_is_open(n_rooms, axis):
    """The segment from room 0 through its side doorway (4 rooms: 2 side by side, 2 facing them) or
    its front doorway (2 rooms facing each other) meets no part's bounding box; beside it, a wall."""
    parts = rooms.building_parts(n_rooms, SMALL, 0)
    t = np.linspace(-0.5, 2 * kitchen.T + 0.5, 200)
    if axis == 0:
        points = np.stack([kitchen.W + t, np.full_like(t, 1.0), np.full_like(t, 0.5 * sum(kitchen.SIDE_DOOR))], 1)
    else:
        points = np.stack([np.full_like(t, 0.5 * kitchen.W), np.full_like(t, 1.0), kitchen.D + t], 1)

    def blocked(p):
        return [bool(np.any(np.all((p > v.min(axis=0)) & (p < v.max(axis=0)), axis=1))) for v in parts.vertices]

    assert not any(blocked(points))
    points[:, 2 - axis] += 0.8  # beside the doorway (0.9 m wide)
    assert any(blocked(points))
