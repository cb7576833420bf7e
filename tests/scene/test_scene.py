"""Scene stage: the Cornell box against the published data, mesh loaders, config -> Scene."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from trimesh.visual.material import PBRMaterial

from lightcuts.config.schema import Material, config_from_dict
from lightcuts.errors import LightcutsError
from lightcuts.scene import Scene
from lightcuts.scene.build import DEFAULT_FOV, framing_camera, scene_from_config
from lightcuts.scene.cornell import SURFACES, cornell_box, cornell_face_ranges
from lightcuts.scene.loaders import concatenate_scenes, euler_xyz, load_mesh

# ---------------------------------------------------------------------------------------------
# The Cornell box: numbers typed in again from the "Cornell Box Data" page (independent of the
# module's copy), millimetres, in the published vertex order.

PUBLISHED = {
    "light": [[[343.0, 548.8, 227.0], [343.0, 548.8, 332.0], [213.0, 548.8, 332.0], [213.0, 548.8, 227.0]]],
    "floor": [[[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]]],
    "back_wall": [[[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2], [556.0, 548.8, 559.2]]],
    "right_wall": [[[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]]],
    "left_wall": [[[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2], [556.0, 548.8, 0.0]]],
    "short_block": [
        [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
        [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
        [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
        [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
        [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
    ],
    "tall_block": [
        [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
        [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
        [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
        [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
        [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
    ],
}
PUBLISHED_CEILING = [[556.0, 548.8, 0.0], [556.0, 548.8, 559.2], [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]]
BOX_CENTRE = np.array([278.0, 274.4, 279.6])


@pytest.fixture(scope="module")
def cbox() -> Scene:
    return cornell_box()


def _ids(name):
    return np.array(cornell_face_ranges()[name])


def test_cornell_quads_are_the_published_ones_in_published_order(cbox):
    for name, quads in PUBLISHED.items():
        tri = cbox.triangles[_ids(name)]
        assert len(tri) == 2 * len(quads), name
        # quad (v0, v1, v2, v3) -> triangles (v0, v1, v2), (v0, v2, v3)
        got = np.concatenate([tri[0::2], tri[1::2, 2:3]], axis=1)
        np.testing.assert_array_equal(got, np.array(quads), err_msg=name)


def test_cornell_ceiling_is_the_published_quad_minus_the_light(cbox):
    tri = cbox.triangles[_ids("ceiling")]
    corners = {tuple(p) for p in tri.reshape(-1, 3)}
    assert corners == {tuple(p) for p in PUBLISHED_CEILING} | {tuple(p) for p in PUBLISHED["light"][0]}
    assert np.all(tri[..., 1] == 548.8)
    areas = cbox.face_areas
    assert np.all(areas[_ids("ceiling")] > 0)
    assert math.isclose(areas[_ids("ceiling")].sum() + areas[_ids("light")].sum(), 556.0 * 559.2, rel_tol=1e-12)
    # No ceiling triangle overlaps the light: every ceiling centroid is outside the light rectangle.
    c = tri.mean(axis=1)
    inside = (c[:, 0] > 213) & (c[:, 0] < 343) & (c[:, 2] > 227) & (c[:, 2] < 332)
    assert not inside.any()


def test_cornell_surface_list_and_bounds(cbox):
    assert set(cornell_face_ranges()) == set(SURFACES)
    assert cbox.n_faces == sum(len(r) for r in cornell_face_ranges().values()) == 38
    np.testing.assert_array_equal(cbox.bounds, [[0.0, 0.0, 0.0], [556.0, 548.8, 559.2]])
    assert cbox.name == "cornell"


def test_cornell_normals_point_into_the_box(cbox):
    n = cbox.face_normals
    expected_axis = {"floor": [0, 1, 0], "ceiling": [0, -1, 0], "light": [0, -1, 0], "back_wall": [0, 0, -1],
                     "right_wall": [1, 0, 0], "left_wall": [-1, 0, 0]}
    for name, axis in expected_axis.items():
        ids = _ids(name)
        assert np.all(n[ids] @ np.array(axis, float) > 0.999), name  # left wall leans by ~0.3 degrees
        centroids = cbox.triangles[ids].mean(axis=1)
        assert np.all(np.einsum("ij,ij->i", BOX_CENTRE - centroids, n[ids]) > 0), name
    for name in ("short_block", "tall_block"):
        ids = _ids(name)
        tri = cbox.triangles[ids]
        block_centre = tri.reshape(-1, 3).mean(axis=0)
        outwards = np.einsum("ij,ij->i", tri.mean(axis=1) - block_centre, n[ids])
        assert np.all(outwards > 0), name
        assert np.allclose(n[ids[:2]], [0, 1, 0])  # the top quad faces up


def test_cornell_emitter(cbox):
    light = _ids("light")
    np.testing.assert_array_equal(cbox.emitters, light)
    assert len(cbox.emitters) == 2
    assert math.isclose(cbox.face_areas[light].sum(), 130.0 * 105.0, rel_tol=1e-12)
    np.testing.assert_array_equal(cbox.emission[light], [[17.0, 12.0, 4.0]] * 2)
    np.testing.assert_allclose(cbox.face_normals[light], [[0.0, -1.0, 0.0]] * 2)
    assert np.all(cbox.emission[np.setdiff1d(np.arange(cbox.n_faces), light)] == 0)


def test_cornell_materials(cbox):
    white, red, green = [0.725, 0.71, 0.68], [0.63, 0.065, 0.05], [0.14, 0.45, 0.091]
    for name, rgb in [("floor", white), ("ceiling", white), ("back_wall", white), ("short_block", white),
                      ("tall_block", white), ("left_wall", red), ("right_wall", green),
                      ("light", [0.78, 0.78, 0.78])]:
        assert np.all(cbox.albedo[_ids(name)] == rgb), name
    assert np.all(cbox.specular == 0) and np.all(cbox.exponent == 0)


def test_cornell_camera(cbox):
    cam = cbox.camera
    np.testing.assert_array_equal(cam.position, [278.0, 273.0, -800.0])
    np.testing.assert_array_equal(cam.look_at, [278.0, 273.0, 0.0])
    np.testing.assert_array_equal(cam.up, [0.0, 1.0, 0.0])
    assert abs(cam.fov - math.degrees(2 * math.atan(0.0125 / 0.035))) < 1e-6
    assert abs(cam.fov - 39.3076481) < 1e-6
    assert (cam.width, cam.height) == (512, 512)
    right, up, fwd = cam.frame()
    # Red wall (x ~ 556) on the image's left: the camera's right is -x.
    np.testing.assert_allclose(right, [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(fwd, [0, 0, 1], atol=1e-15)


def test_cornell_camera_sees_the_whole_opening(cbox):
    cam = cbox.camera
    right, up, fwd = cam.frame()
    tan_half = math.tan(math.radians(cam.fov) / 2)
    front = cbox.vertices[cbox.vertices[:, 2] == 0.0]
    d = front - cam.position
    assert len(front) >= 8
    assert np.all(np.abs(d @ right) / (d @ fwd) < tan_half)
    assert np.all(np.abs(d @ up) / (d @ fwd) < tan_half)


def test_cornell_override_replaces_only_given_fields():
    s = cornell_box({"floor": {"specular": [0.3, 0.3, 0.3], "exponent": 40},
                     "light": Material(emission=[1.0, 2.0, 3.0]),
                     "left_wall": {"albedo": [0.1, 0.2, 0.3]}})
    fl, li, lw = _ids("floor"), _ids("light"), _ids("left_wall")
    assert np.all(s.specular[fl] == 0.3) and np.all(s.exponent[fl] == 40)
    assert np.all(s.albedo[fl] == [0.725, 0.71, 0.68])  # not given: kept
    assert np.all(s.emission[li] == [1.0, 2.0, 3.0]) and np.all(s.albedo[li] == 0.78)
    assert np.all(s.albedo[lw] == [0.1, 0.2, 0.3])
    others = np.setdiff1d(np.arange(s.n_faces), np.concatenate([fl, li, lw]))
    ref = cornell_box()
    for a in ("albedo", "specular", "exponent", "emission"):
        np.testing.assert_array_equal(getattr(s, a)[others], getattr(ref, a)[others])
    np.testing.assert_array_equal(s.vertices, ref.vertices)


@pytest.mark.parametrize("materials, key", [
    ({"sofa": {"albedo": [1, 1, 1]}}, "scene.materials.sofa"),
    ({"floor": {"albedo": [-1, 0, 0]}}, "scene.materials.floor.albedo"),
    ({"floor": {"colour": [1, 0, 0]}}, "scene.materials.floor.colour"),
    ({"floor": 3}, "scene.materials.floor"),
    ({"light": {"emission": [float("inf"), 0, 0]}}, "scene.materials.light.emission"),
    ({"floor": {"albedo": [float("nan"), 0, 0]}}, "scene.materials.floor.albedo"),
])
def test_cornell_bad_override(materials, key):
    with pytest.raises(LightcutsError, match=key.replace(".", r"\.")) as e:
        cornell_box(materials)
    assert "\n" not in str(e.value)


# ---------------------------------------------------------------------------------------------
# Loaders

OBJ = """\
mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 5 0 0
v 6 0 0
v 5 1 0
v 9 0 0
v 9 1 0
v 9 0 1
v 20 0 0
v 21 0 0
v 20 1 0
usemtl glossy
f 1 2 3 4
usemtl lamp
f 5 6 7
usemtl matte
f 8 9 10
usemtl not_in_mtl
f 11 12 13
"""
MTL = """\
# comment
newmtl glossy
Kd 0.725 0.71 0.68
Ks 0.2 0.25 0.3
Ns 37.5
illum 2

newmtl lamp
Kd 0.78 0.78 0.78
Ke 17 12 4

newmtl matte
Kd 0.3
Ks 0.5 0.5 0.5
Ns 96
illum 1
"""


def _face_at(scene, centroid):
    c = scene.triangles.mean(axis=1)
    i = np.flatnonzero(np.linalg.norm(c - np.asarray(centroid, float), axis=1) < 1e-9)
    assert len(i) == 1, (centroid, c)
    return i[0]


@pytest.fixture
def obj_file(tmp_path):
    (tmp_path / "m.mtl").write_text(MTL)
    p = tmp_path / "mesh.obj"
    p.write_text(OBJ)
    return p


def test_obj_mtl_materials_per_usemtl_group(obj_file):
    s = load_mesh(obj_file)
    assert s.n_faces == 5 and s.camera is None and s.name == "mesh"
    quad = [_face_at(s, [2 / 3, 1 / 3, 0]), _face_at(s, [1 / 3, 2 / 3, 0])]
    lamp = _face_at(s, [16 / 3, 1 / 3, 0])
    matte = _face_at(s, [9, 1 / 3, 1 / 3])
    nomat = _face_at(s, [61 / 3, 1 / 3, 0])
    # Full precision (not trimesh's 8-bit colours).
    assert np.all(s.albedo[quad] == [0.725, 0.71, 0.68])
    assert np.all(s.specular[quad] == [0.2, 0.25, 0.3]) and np.all(s.exponent[quad] == 37.5)
    assert np.all(s.emission[quad] == 0)
    assert np.all(s.albedo[lamp] == 0.78) and np.all(s.emission[lamp] == [17, 12, 4])
    assert np.all(s.specular[lamp] == 0) and s.exponent[lamp] == 0
    # A single Kd value is grey (trimesh's own MTL parser drops the whole file's materials on it);
    # illum 1 means no highlight.
    assert np.all(s.albedo[matte] == 0.3) and np.all(s.specular[matte] == 0)
    assert np.all(s.albedo[nomat] == 0.5) and np.all(s.emission[nomat] == 0)
    np.testing.assert_array_equal(s.emitters, [lamp])
    # Winding kept: all these faces were written counter-clockwise seen from +z (or +x).
    np.testing.assert_allclose(s.face_normals[[*quad, lamp, nomat]], [[0, 0, 1]] * 4)
    np.testing.assert_allclose(s.face_normals[matte], [1, 0, 0])


def test_obj_missing_mtl_warns_and_uses_default(tmp_path):
    p = _write(tmp_path, "lonely.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
    with pytest.warns(UserWarning, match=r"gone\.mtl: no such file") as w:
        s = load_mesh(p)
    assert str(p) in str(w[0].message)
    assert np.all(s.albedo == 0.5)


def test_obj_with_two_material_libraries(tmp_path):
    (tmp_path / "a.mtl").write_text("newmtl one\nKd 0.1 0.2 0.3\n")
    (tmp_path / "b.mtl").write_text("newmtl two\nKe 4 5 6\n")
    p = _write(tmp_path, "two.obj", "mtllib a.mtl b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 0 0\nv 6 0 0\nv 5 1 0\n"
                                    "usemtl one\nf 1 2 3\nusemtl two\nf 4 5 6\n")
    s = load_mesh(p)
    one, two = _face_at(s, [1 / 3, 1 / 3, 0]), _face_at(s, [16 / 3, 1 / 3, 0])
    assert np.all(s.albedo[one] == [0.1, 0.2, 0.3]) and np.all(s.emission[one] == 0)
    assert np.all(s.albedo[two] == 0.5) and np.all(s.emission[two] == [4, 5, 6])


def test_obj_without_mtl_is_grey_diffuse(tmp_path):
    p = tmp_path / "plain.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    s = load_mesh(p)
    assert s.n_faces == 1
    assert np.all(s.albedo == 0.5) and np.all(s.specular == 0) and np.all(s.emission == 0)


def test_material_override_replaces_file_materials(obj_file):
    s = load_mesh(obj_file, material={"albedo": [0.2, 0.3, 0.4]})
    assert np.all(s.albedo == [0.2, 0.3, 0.4])
    assert np.all(s.specular == 0) and np.all(s.exponent == 0) and np.all(s.emission == 0)
    s = load_mesh(obj_file, material=Material(specular=[0.1] * 3, exponent=20, emission=[1, 1, 1]))
    assert np.all(s.albedo == 0.5) and np.all(s.exponent == 20) and len(s.emitters) == 5


def test_transform_moves_a_known_vertex(tmp_path):
    p = tmp_path / "t.obj"
    p.write_text("v 0 1 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    # scale [1, 2, 3]: (0,1,0) -> (0,2,0); about x by 90: -> (0,0,2); about z by 90: stays; + t.
    # (Rotating about z first would give (-2,0,0): the order matters.)
    s = load_mesh(p, scale=[1, 2, 3], rotate=[90, 0, 90], translate=[10, 20, 30])
    tri = s.triangles[0]
    np.testing.assert_allclose(tri[0], [10, 20, 32], atol=1e-12)
    np.testing.assert_allclose(tri[1], [10, 21, 30], atol=1e-12)  # (1,0,0) -> Rx: same -> Rz: (0,1,0)
    np.testing.assert_allclose(tri[2], [13, 20, 30], atol=1e-12)  # (0,0,3) -> Rx: (0,-3,0) -> Rz: (3,0,0)
    s = load_mesh(p, scale=2.0)
    np.testing.assert_allclose(s.triangles[0], [[0, 2, 0], [2, 0, 0], [0, 0, 2]])


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-360, 360), min_size=3, max_size=3))
def test_euler_rotation_is_proper_and_rotates_normals(angles):
    r = euler_xyz(angles)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert abs(np.linalg.det(r) - 1) < 1e-12
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 2, 0]], [[1.0, 1, 1], [1, 3, 2], [-1, 0, 4]]])
    s0 = Scene(tri.reshape(-1, 3), [[0, 1, 2], [3, 4, 5]], 0.5, 0, 0, 0)
    s1 = Scene(tri.reshape(-1, 3) @ r.T, [[0, 1, 2], [3, 4, 5]], 0.5, 0, 0, 0)
    np.testing.assert_allclose(s1.face_normals, s0.face_normals @ r.T, atol=1e-12)
    np.testing.assert_allclose(s1.face_areas, s0.face_areas, rtol=1e-12)


@pytest.mark.parametrize("scale", [[-1, 1, 1], [2, -3, 1], [-1, -1, -1], [-2.0, 1, 0.5]])
def test_mirroring_keeps_normals_outward(tmp_path, scale):
    p = tmp_path / "box.ply"
    trimesh.creation.box(extents=[1, 2, 3]).export(p)
    s = load_mesh(p, scale=scale, translate=[5, 0, 0])
    centre = 0.5 * (s.bounds[0] + s.bounds[1])
    out = np.einsum("ij,ij->i", s.triangles.mean(axis=1) - centre, s.face_normals)
    assert np.all(out > 0)


def test_ply_roundtrip(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=2)
    p = tmp_path / "sphere.ply"
    mesh.export(p)
    s = load_mesh(p)
    assert s.n_faces == len(mesh.faces)
    np.testing.assert_allclose(np.sort(s.triangles.reshape(-1, 3), axis=0),
                               np.sort(mesh.vertices[mesh.faces].reshape(-1, 3), axis=0), atol=1e-6)
    assert np.all(s.albedo == 0.5) and np.all(s.emission == 0)
    np.testing.assert_allclose(s.face_normals, mesh.face_normals, atol=1e-6)  # winding kept
    s = load_mesh(p, material={"emission": [2, 2, 2]})
    assert len(s.emitters) == s.n_faces


def _glb_scene():
    """Two instances of a unit box (one translated, one mirrored) plus a lamp triangle."""
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(baseColorFactor=[0.6, 0.4, 0.2, 1.0], metallicFactor=0.0, roughnessFactor=1.0))
    lamp = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False)
    lamp.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(emissiveFactor=[1.0, 0.5, 0.25]))
    sc = trimesh.Scene()
    t = np.eye(4)
    t[:3, 3] = [10, 0, 0]
    sc.add_geometry(box, node_name="moved", geom_name="box", transform=t)
    m = np.diag([-1.0, 1, 1, 1])
    m[:3, 3] = [-10, 0, 0]
    sc.add_geometry(box, node_name="mirrored", geom_name="box", transform=m)
    t2 = np.eye(4)
    t2[:3, 3] = [0, 5, 0]
    sc.add_geometry(lamp, node_name="lamp", geom_name="lamp", transform=t2)
    return sc


@pytest.mark.parametrize("ext", ["glb", "gltf"])
def test_gltf_bakes_node_transforms_and_reads_materials(tmp_path, ext):
    p = tmp_path / f"scene.{ext}"
    if ext == "glb":
        _glb_scene().export(p)
    else:
        files = trimesh.exchange.gltf.export_gltf(_glb_scene(), embed_buffers=True)
        p.write_bytes(files["model.gltf"])
    s = load_mesh(p, translate=[0, 0, 100])
    assert s.n_faces == 12 + 12 + 1
    c = s.triangles.mean(axis=1)
    moved, mirrored, lamp = c[:, 0] > 5, c[:, 0] < -5, np.abs(c[:, 0]) < 5
    assert moved.sum() == 12 and mirrored.sum() == 12 and lamp.sum() == 1
    np.testing.assert_allclose(s.vertices[np.unique(s.faces[moved])].min(axis=0), [9.5, -0.5, 99.5], atol=1e-6)
    np.testing.assert_allclose(s.vertices[np.unique(s.faces[mirrored])].max(axis=0), [-9.5, 0.5, 100.5],
                               atol=1e-6)
    np.testing.assert_allclose(s.triangles[lamp][0], [[0, 5, 100], [1, 5, 100], [0, 6, 100]], atol=1e-6)
    for sel, centre in ((moved, [10, 0, 100]), (mirrored, [-10, 0, 100])):
        out = np.einsum("ij,ij->i", c[sel] - centre, s.face_normals[sel])
        assert np.all(out > 0)
    # baseColorFactor goes through trimesh as 8-bit RGBA; a dielectric (metallic 0) keeps 0.96 of it
    # as diffuse albedo and reflects 0.04 in a Phong lobe, here of exponent 0 (roughness 1).
    np.testing.assert_allclose(s.albedo[moved | mirrored], [[0.576, 0.384, 0.192]] * 24, atol=0.5 / 255)
    np.testing.assert_allclose(s.specular[moved | mirrored], 0.04)
    assert np.all(s.exponent[moved | mirrored] == 0)
    # the lamp's material gives no metallicFactor: glTF's default 1, a metal of base colour 1
    np.testing.assert_allclose(s.albedo[lamp], 0.0)
    np.testing.assert_allclose(s.specular[lamp], 1.0)
    np.testing.assert_allclose(s.emission[lamp], [[1.0, 0.5, 0.25]])
    assert np.all(s.emission[~lamp] == 0)
    s = load_mesh(p, material={"albedo": [0.1, 0.1, 0.1]})
    assert np.all(s.albedo == 0.1) and np.all(s.emission == 0)


def test_concatenate_scenes(obj_file):
    a = cornell_box()
    b = load_mesh(obj_file, translate=[100, 100, 100])
    s = concatenate_scenes([a, b], name="both")
    assert s.n_faces == a.n_faces + b.n_faces and s.name == "both"
    np.testing.assert_array_equal(s.triangles, np.concatenate([a.triangles, b.triangles]))
    for f in ("albedo", "specular", "exponent", "emission"):
        np.testing.assert_array_equal(getattr(s, f), np.concatenate([getattr(a, f), getattr(b, f)]))
    assert s.camera is a.camera
    assert len(s.emitters) == 3
    assert concatenate_scenes([b, a]).camera is a.camera


# Bad input: one line, a LightcutsError naming the key and the file.

def _write(tmp_path, name, content):
    p = tmp_path / name
    p.write_bytes(content if isinstance(content, bytes) else content.encode())
    return p


@pytest.mark.parametrize("name, content, problem", [
    ("missing.obj", None, "no such file"),
    ("mesh.stl", "solid x\nendsolid x\n", "unsupported mesh format"),
    ("noext", "v 0 0 0\n", "unsupported mesh format"),
    ("garbage.ply", b"this is not a ply\x00\x01\x02", "cannot read mesh"),
    ("garbage.glb", b"glTF but not really", "cannot read mesh"),
    ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no triangles"),
    ("empty.obj", "", "no triangles"),
    ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", "NaN or infinite"),
    ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n", "degenerate"),
])
def test_bad_mesh_files(tmp_path, name, content, problem):
    p = tmp_path / name if content is None else _write(tmp_path, name, content)
    with pytest.raises(LightcutsError) as e:
        load_mesh(p, key="scene.meshes.3")
    msg = str(e.value)
    assert problem in msg and str(p) in msg and msg.startswith("scene.meshes.3: ") and "\n" not in msg


def test_degenerate_triangles_dropped_with_warning(tmp_path):
    p = _write(tmp_path, "deg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 3 3 1\n")
    with pytest.warns(UserWarning, match=r"dropped 2 degenerate") as w:
        s = load_mesh(p)
    assert str(p) in str(w[0].message)
    assert s.n_faces == 1 and np.all(s.face_areas > 0)


@pytest.mark.parametrize("kwargs, key", [
    (dict(scale=0.0), "scene.meshes.0.scale"),
    (dict(scale=[1, 0, 1]), "scene.meshes.0.scale"),
    (dict(scale=[1, 2]), "scene.meshes.0.scale"),
    (dict(rotate=[0, float("nan"), 0]), "scene.meshes.0.rotate"),
    (dict(translate=[0, 0, float("inf")]), "scene.meshes.0.translate"),
    (dict(material={"albedo": [1, 1]}), "scene.meshes.0.material.albedo"),
    (dict(material={"exponent": float("nan")}), "scene.meshes.0.material.exponent"),
])
def test_bad_transform_or_material(obj_file, kwargs, key):
    with pytest.raises(LightcutsError, match=key.replace(".", r"\.")):
        load_mesh(obj_file, **kwargs)


def test_bad_mtl_value_names_the_file_and_material(tmp_path):
    (tmp_path / "b.mtl").write_text("newmtl weird\nKd 0.5 0.5 0.5\nKe 1 2 x\n")
    p = _write(tmp_path, "b.obj", "mtllib b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl weird\nf 1 2 3\n")
    with pytest.raises(LightcutsError, match=r"Ke") as e:
        load_mesh(p)
    assert str(p) in str(e.value) and "weird" in str(e.value)


# ---------------------------------------------------------------------------------------------
# Config -> Scene

def _cfg(data, base_dir="."):
    return config_from_dict(data, base_dir=base_dir)


def test_config_builtin_cornell():
    s = scene_from_config(_cfg({"name": "box", "scene": {"builtin": "cornell"}}))
    ref = cornell_box()
    assert s.name == "box"
    np.testing.assert_array_equal(s.triangles, ref.triangles)
    np.testing.assert_array_equal(s.camera.as_array(), ref.camera.as_array())


def test_config_camera_fields_override_builtin_camera():
    s = scene_from_config(_cfg({"scene": {"builtin": "cornell"},
                                "camera": {"resolution": [640, 480], "fov": 50, "up": [0, 1, 0.1]}}))
    cam, ref = s.camera, cornell_box().camera
    assert (cam.width, cam.height, cam.fov) == (640, 480, 50.0)
    np.testing.assert_array_equal(cam.up, [0, 1, 0.1])
    np.testing.assert_array_equal(cam.position, ref.position)
    np.testing.assert_array_equal(cam.look_at, ref.look_at)


def test_config_material_overrides_of_builtin_surfaces():
    s = scene_from_config(_cfg({"scene": {"builtin": "cornell", "materials": {
        "tall_block": {"albedo": [0.5, 0.49, 0.47], "specular": [0.2, 0.2, 0.2], "exponent": 30}}}}))
    tb = _ids("tall_block")
    assert np.all(s.specular[tb] == 0.2) and np.all(s.exponent[tb] == 30) and np.all(s.albedo[tb] == [0.5, 0.49, 0.47])
    assert np.all(s.specular[np.setdiff1d(np.arange(s.n_faces), tb)] == 0)
    with pytest.raises(LightcutsError, match=r"scene\.materials\.sofa"):
        scene_from_config(_cfg({"scene": {"builtin": "cornell", "materials": {"sofa": {}}}}))


def test_config_builtin_plus_meshes(tmp_path, obj_file):
    sphere = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=1, radius=1.0).export(sphere)
    cfg = _cfg({"name": "mix", "scene": {"builtin": "cornell", "meshes": [
        {"file": "mesh.obj", "translate": [100, 0, 100]},
        {"file": "ball.ply", "scale": 50, "translate": [400, 100, 150], "material": {"albedo": [0.9, 0.1, 0.1]}},
    ]}}, base_dir=tmp_path)
    s = scene_from_config(cfg)
    n_obj, n_ball = 5, 80
    assert s.n_faces == 38 + n_obj + n_ball and s.name == "mix"
    ball = np.arange(38 + n_obj, s.n_faces)
    np.testing.assert_allclose(s.vertices[np.unique(s.faces[ball])].mean(axis=0), [400, 100, 150], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(s.vertices[np.unique(s.faces[ball])] - [400, 100, 150], axis=1),
                               50, rtol=1e-7)  # PLY stores float32
    assert np.all(s.albedo[ball] == [0.9, 0.1, 0.1])
    assert len(s.emitters) == 3  # the light quad and the lamp triangle of mesh.obj
    np.testing.assert_array_equal(s.camera.position, [278, 273, -800])


def test_config_meshes_only_default_camera_frames_the_box(tmp_path, obj_file):
    for res in ([512, 512], [800, 300], [300, 800]):
        s = scene_from_config(_cfg({"scene": {"meshes": [{"file": "mesh.obj"}]}, "camera": {"resolution": res}},
                                   base_dir=tmp_path))
        cam = s.camera
        lo, hi = s.bounds
        np.testing.assert_allclose(cam.look_at, 0.5 * (lo + hi))
        assert cam.position[2] > hi[2] and cam.fov == DEFAULT_FOV and [cam.width, cam.height] == res
        np.testing.assert_allclose(cam.position[:2], cam.look_at[:2])
        right, up, fwd = cam.frame()
        tan_v = math.tan(math.radians(cam.fov) / 2)
        tan_h = tan_v * cam.width / cam.height
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        d = corners - cam.position
        assert np.all(d @ fwd > 0)
        assert np.all(np.abs(d @ right) / (d @ fwd) <= tan_h * (1 + 1e-12))
        assert np.all(np.abs(d @ up) / (d @ fwd) <= tan_v * (1 + 1e-12))


def test_framing_camera_is_tight_for_a_cube():
    # Unit-radius bounding sphere: distance = 1 / sin(fov/2) exactly.
    cam = framing_camera(np.array([[-1, -1, -1], [1, 1, 1]]) / math.sqrt(3), fov=60)
    np.testing.assert_allclose(cam.position, [0, 0, 2.0])


def test_config_meshes_only_full_camera(tmp_path, obj_file):
    cam_cfg = {"position": [1, 2, 30], "look_at": [1, 2, 0], "up": [0, 1, 0], "fov": 30, "resolution": [64, 32]}
    s = scene_from_config(_cfg({"scene": {"meshes": [{"file": "mesh.obj"}]}, "camera": cam_cfg}, base_dir=tmp_path))
    np.testing.assert_array_equal(s.camera.as_array(), [1, 2, 30, 1, 2, 0, 0, 1, 0, 30, 64, 32])


@pytest.mark.parametrize("data, key", [
    ({"scene": {"meshes": [{"file": "mesh.obj"}], "materials": {"floor": {}}}}, "scene.materials.floor"),
    ({"scene": {"builtin": "cornell"}, "camera": {"look_at": [278, 273, -800]}}, "camera.look_at"),
    ({"scene": {"builtin": "cornell"}, "camera": {"up": [0, 0, 2]}}, "camera.up"),
])
def test_config_errors(tmp_path, obj_file, data, key):
    with pytest.raises(LightcutsError, match=key.replace(".", r"\.")):
        scene_from_config(_cfg(data, base_dir=tmp_path))


def test_config_bad_mesh_names_its_index_and_file(tmp_path, obj_file):
    bad = _write(tmp_path, "points.obj", "v 0 0 0\n")
    cfg = _cfg({"scene": {"meshes": [{"file": "mesh.obj"}, {"file": "points.obj"}]}}, base_dir=tmp_path)
    with pytest.raises(LightcutsError) as e:
        scene_from_config(cfg)
    assert str(e.value).startswith("scene.meshes.1: ") and str(bad) in str(e.value)


def test_scene_roundtrips_through_npz(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = scene_from_config(_cfg({"name": "rt", "scene": {"builtin": "cornell"}}))
    t = Scene.load(s.save(tmp_path / "s.npz"))
    for f in ("vertices", "faces", "albedo", "specular", "exponent", "emission"):
        np.testing.assert_array_equal(getattr(t, f), getattr(s, f))
    np.testing.assert_array_equal(t.camera.as_array(), s.camera.as_array())
    assert t.name == "rt"


def test_bounds_are_those_of_the_vertices_faces_use():
    """A vertex no face uses (a loader's leftover) stays out of the box; without faces, every vertex."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0], [50, -9, 7], [0, 0, 3]])
    s = Scene(v, [[0, 1, 2], [0, 2, 4]], 0.5, 0.0, 0.0, 0.0)
    np.testing.assert_array_equal(s.bounds, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_array_equal(Scene(v, np.zeros((0, 3)), 0.5, 0.0, 0.0, 0.0).bounds, [[0, -9, 0], [50, 2, 7]])
