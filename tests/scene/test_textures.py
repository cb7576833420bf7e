"""Albedo textures: the uv maps and the bilinear sRGB lookup, MTL ``map_Kd`` and glTF textures read
into the Scene, a textured checkerboard rendered at the right pixels with the right values, and a
glTF scene rendering as its OBJ+MTL equivalent."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from PIL import Image

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.scene.loaders import concatenate_scenes, load_mesh
from lightcuts.scene.materials import pbr_to_phong
from lightcuts.scene.scene import Scene
from lightcuts.scene.textures import (TextureSet, albedo_at, face_texture_means, image_to_linear, srgb_to_linear,
                                      texture_lookup, uv_maps)
from scene_files import BLUE, RED, checkerboard, edit_glb, quad_obj


def test_srgb_decoding_is_the_standard_curve():
    assert srgb_to_linear(0.0) == 0.0 and srgb_to_linear(1.0) == pytest.approx(1.0)
    assert float(srgb_to_linear(128 / 255)) == pytest.approx(0.2158605, abs=1e-6)
    assert float(srgb_to_linear(10 / 255)) == pytest.approx(10 / 255 / 12.92)
    assert image_to_linear(np.array([[[255, 128, 0]]], np.uint8))[0, 0] == pytest.approx([1.0, 0.2158605, 0.0],
                                                                                          abs=1e-6)


def test_uv_maps_give_every_point_its_interpolated_coordinates():
    """To whole periods of the repeat, which the maps take off corner 0 (its u, v in [0, 1))."""
    rng = np.random.default_rng(3)
    tri = rng.normal(size=(50, 3, 3))
    uv = rng.uniform(-2, 3, size=(50, 3, 2))
    maps = uv_maps(tri.reshape(-1, 3), np.arange(150).reshape(50, 3), uv)
    b = rng.dirichlet([1, 1, 1], size=50)
    x = np.einsum("fk,fkc->fc", b, tri)
    expected = np.einsum("fk,fkc->fc", b, uv)
    got_u = maps[:, 9] + np.einsum("fc,fc->f", x - maps[:, 0:3], maps[:, 3:6])
    got_v = maps[:, 10] + np.einsum("fc,fc->f", x - maps[:, 0:3], maps[:, 6:9])
    off = np.stack([got_u, got_v], 1) - expected
    np.testing.assert_allclose(off, np.round(off), atol=1e-9)
    np.testing.assert_array_equal(np.round(off), -np.floor(uv[:, 0]))
    assert np.all((maps[:, 9:11] >= 0) & (maps[:, 9:11] < 1))


def test_the_lookup_is_bilinear_between_texel_centres_and_repeats():
    img = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)  # 2 rows, 3 columns
    ts = TextureSet()
    ts.add(img, "ramp")
    look = lambda u, v: np.array(texture_lookup(ts.texels, ts.table, 0, u, v))  # noqa: E731
    # texel centres: column j at u = (j + 0.5) / 3; row 0 (the top) at v = 1 - 0.5 / 2
    for j in range(3):
        np.testing.assert_allclose(look((j + 0.5) / 3, 0.75), img[0, j], atol=1e-5)
        np.testing.assert_allclose(look((j + 0.5) / 3, 0.25), img[1, j], atol=1e-5)
    np.testing.assert_allclose(look(1.0 / 3, 0.75), 0.5 * (img[0, 0] + img[0, 1]), atol=1e-5)
    np.testing.assert_allclose(look(0.5 / 3, 0.5), 0.5 * (img[0, 0] + img[1, 0]), atol=1e-5)
    # repeat: between the last and the first column, and whole periods away
    np.testing.assert_allclose(look(1.0, 0.75), 0.5 * (img[0, 2] + img[0, 0]), atol=1e-5)
    np.testing.assert_allclose(look(0.3 + 7, 0.6 - 3), look(0.3, 0.6), atol=1e-5)
    np.testing.assert_allclose(look(0.3 - 1e9, 0.6), look(0.3, 0.6), atol=1e-3)
    assert np.all(np.isfinite(look(np.nan, np.inf)))


def test_albedo_at_multiplies_the_triangle_colour_and_skips_untextured_triangles():
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], np.float64)
    ts = TextureSet()
    ts.add(np.full((2, 2, 3), [0.5, 0.25, 1.0], np.float32), "flat")
    s = Scene(tri, [[0, 1, 2], [3, 4, 5]], [[0.8, 0.8, 0.8], [0.3, 0.2, 0.1]], 0.0, 0.0, 0.0,
              uv=np.zeros((2, 3, 2)), texture=[0, -1], textures=ts)
    tex = s.texture_data()
    assert albedo_at(s.albedo, tex, 0, 0.2, 0.2, 0.0) == pytest.approx((0.4, 0.2, 0.8))
    assert albedo_at(s.albedo, tex, 1, 5.2, 0.2, 0.0) == pytest.approx((0.3, 0.2, 0.1))
    plain = Scene(tri, [[0, 1, 2], [3, 4, 5]], 0.7, 0.0, 0.0, 0.0)
    assert not plain.textured and all(len(a) == 0 for a in plain.texture_data())
    assert albedo_at(plain.albedo, plain.texture_data(), 0, 0.2, 0.2, 0.0) == pytest.approx((0.7, 0.7, 0.7))


def test_textured_scenes_concatenate_save_and_load(tmp_path):
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    a_set, b_set = TextureSet(), TextureSet()
    a_set.add(np.zeros((1, 1, 3)), "a")
    b_set.add(np.ones((2, 1, 3)), "b")
    a = Scene(tri, [[0, 1, 2]], 0.5, 0, 0, 0, uv=np.zeros((1, 3, 2)), texture=[0], textures=a_set)
    plain = Scene(tri, [[0, 1, 2]], 0.5, 0, 0, 0)
    b = Scene(tri, [[0, 1, 2]], 0.5, 0, 0, 0, uv=np.ones((1, 3, 2)), texture=[0], textures=b_set)
    s = concatenate_scenes([a, plain, b])
    assert list(s.texture) == [0, -1, 1] and s.textures.names == ["a", "b"]
    assert np.all(s.textures.image(1) == 1) and s.uv[2].min() == 1
    s.save(tmp_path / "s.npz")
    t = Scene.load(tmp_path / "s.npz")
    assert list(t.texture) == [0, -1, 1] and np.array_equal(t.uv, s.uv)
    assert np.array_equal(t.textures.texels, s.textures.texels) and t.textures.names == ["a", "b"]
    assert not concatenate_scenes([plain, plain]).textured


def test_map_kd_is_read_with_its_options_and_relative_path(tmp_path):
    (tmp_path / "maps").mkdir()
    Image.fromarray(checkerboard()).save(tmp_path / "maps" / "c.png")
    quad_obj(tmp_path, "newmtl m\nKd 0.5 0.5 0.5\nmap_Kd -blendu on -s 2 3 1 -o 0.25 0.5 maps/c.png\n")
    s = load_mesh(tmp_path / "quad.obj")
    assert s.textured and list(s.texture) == [0, 0] and s.textures.names[0].endswith("c.png")
    np.testing.assert_allclose(s.uv[0], [[0.25, 0.5], [2.25, 0.5], [2.25, 3.5]])
    np.testing.assert_allclose(s.textures.image(0)[0, 0], srgb_to_linear(np.array(RED) / 255), rtol=1e-6)
    np.testing.assert_allclose(s.albedo, 0.5)
    # overriding the material drops the texture
    assert not load_mesh(tmp_path / "quad.obj", material={"albedo": [0.2, 0.2, 0.2]}).textured


def test_a_missing_or_broken_texture_is_one_line_naming_the_material(tmp_path):
    quad_obj(tmp_path, "newmtl m\nKd 1 1 1\nmap_Kd nowhere.png\n")
    with pytest.raises(LightcutsError, match=r"scene.meshes.0: .*material 'm': texture .*nowhere.png: no such file"):
        load_mesh(tmp_path / "quad.obj")
    (tmp_path / "bad.png").write_bytes(b"not an image")
    quad_obj(tmp_path, "newmtl m\nKd 1 1 1\nmap_Kd bad.png\n")
    with pytest.raises(LightcutsError, match="cannot read image") as e:
        load_mesh(tmp_path / "quad.obj")
    assert "\n" not in str(e.value)
    quad_obj(tmp_path, "newmtl m\nmap_Kd -s\n")
    with pytest.raises(LightcutsError, match="map_Kd -s needs a value"):
        load_mesh(tmp_path / "quad.obj")


def test_a_textured_material_without_texture_coordinates_is_refused(tmp_path):
    Image.fromarray(checkerboard()).save(tmp_path / "tex.png")
    (tmp_path / "q.obj").write_text("mtllib q.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    (tmp_path / "q.mtl").write_text("newmtl m\nmap_Kd tex.png\n")
    with pytest.raises(LightcutsError, match="without texture coordinates"):
        load_mesh(tmp_path / "q.obj")


def _pixel_uv(cfg, w, h):
    """uv of every pixel's centre on the quad (the camera at (0, 0, 3) looking down -z, up +y)."""
    t = math.tan(math.radians(cfg.camera.fov) / 2)
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * t * w / h
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * t
    x, y = np.meshgrid(3 * xs, 3 * ys)
    return (x + 1) / 2, (y + 1) / 2


def test_a_textured_checkerboard_renders_each_square_at_its_pixels(tmp_path):
    """A sun straight above the quad (irradiance pi) makes the radiance the albedo: each square of
    the 4 x 4 checkerboard, seen through the pixels wholly inside it, has mean Kd * decoded colour
    within 2%; the squares alternate in the image as in the texture (row 0 at the top)."""
    quad_obj(tmp_path, "newmtl m\nKd 0.8 0.9 1.0\nmap_Kd tex.png\n", checkerboard())
    (tmp_path / "run.yaml").write_text(
        "scene: {meshes: [{file: quad.obj}]}\n"
        "camera: {position: [0, 0, 3], look_at: [0, 0, 0], up: [0, 1, 0], fov: 30, resolution: [64, 64]}\n"
        f"lights: {{sun: {{direction: [0, 0, 1], irradiance: [{math.pi}, {math.pi}, {math.pi}]}}}}\n")
    cfg = lightcuts.load_config(tmp_path / "run.yaml")
    img = lightcuts.render(cfg, progress=False).image.astype(np.float64)
    u, v = _pixel_uv(cfg, 64, 64)
    half = 0.5 * 2 * 3 * math.tan(math.radians(15)) / 64 / 2  # half a pixel, in uv
    margin = half + 1.0 / 32  # and one texel for the filter
    kd = np.array([0.8, 0.9, 1.0])
    seen = 0
    for row in range(4):
        for col in range(4):
            lo_u, lo_v = col / 4, (3 - row) / 4  # texture row 0 (top) is v in [0.75, 1]
            inside = (u > lo_u + margin) & (u < lo_u + 0.25 - margin) & (v > lo_v + margin) & (v < lo_v + 0.25 - margin)
            assert inside.sum() >= 4
            colour = RED if (row + col) % 2 == 0 else BLUE
            expected = kd * srgb_to_linear(np.array(colour) / 255)
            np.testing.assert_allclose(img[inside].mean(axis=0), expected, rtol=0.02)
            seen += 1
    assert seen == 16


def test_emissive_texture_means_are_per_triangle_averages():
    ts = TextureSet()
    ts.add(image_to_linear(checkerboard(2, 64)), "c")  # 2 x 2 squares of 64 x 64 texels
    uv = np.array([[[0, 0.5], [0.5, 0.5], [0, 1]],  # top-left square: RED
                   [[0, 0], [1, 0], [0, 1]]])  # half the image: the mean of both colours' share
    m = face_texture_means(ts, np.array([0, 0]), uv)
    np.testing.assert_allclose(m[0], srgb_to_linear(np.array(RED) / 255), rtol=0.02)
    assert np.all(m[1] > 0.1)
    assert np.all(face_texture_means(ts, np.array([-1]), uv[:1]) == 1)


def test_pbr_mapping():
    rd, rs, n = pbr_to_phong([0.5, 0.6, 0.7], 0.0, 1.0)
    np.testing.assert_allclose(rd, [0.48, 0.576, 0.672]) and np.testing.assert_allclose(rs, 0.04)
    assert n == 0.0
    rd, rs, n = pbr_to_phong([0.5, 0.6, 0.7], 1.0, 0.5)
    np.testing.assert_allclose(rd, 0) and np.testing.assert_allclose(rs, [0.5, 0.6, 0.7])
    assert n == pytest.approx(2 / 0.25 ** 2 - 2)
    assert pbr_to_phong([1, 1, 1], 0.3, 0.0)[2] == 1e4
    rd, rs, _ = pbr_to_phong([1, 1, 1], 0.0, 0.7)
    assert np.all(rd + rs <= 1.0 + 1e-12)


def _room_parts():
    """An open box of two PBR materials (one textured) and an emissive quad above it."""
    box = trimesh.creation.box(extents=[4, 3, 4])
    box.apply_translation([0, 1.5, 0])
    keep = box.face_normals[:, 1] < 0.5
    floor = box.face_normals[:, 1] < -0.5
    walls = trimesh.Trimesh(box.vertices, box.faces[keep & ~floor][:, ::-1], process=False)
    fl = trimesh.Trimesh(box.vertices, box.faces[floor][:, ::-1], process=False)
    fl = fl.unmerge_vertices() or fl
    lamp = trimesh.Trimesh([[-0.5, 2.9, -0.5], [0.5, 2.9, -0.5], [0.5, 2.9, 0.5], [-0.5, 2.9, 0.5]],
                           [[0, 1, 2], [0, 2, 3]], process=False)  # facing down
    return walls, fl, lamp


def _emissive_strength(doc):
    """Each emissiveFactor above 1 as its largest value times a factor of at most 1, the largest
    value given by KHR_materials_emissive_strength (what trimesh's exporter does not write)."""
    for m in doc["materials"]:
        top = max(m.get("emissiveFactor", [0]))
        if top > 1:
            m["emissiveFactor"] = [x / top for x in m["emissiveFactor"]]
            m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": top}}
            doc["extensionsUsed"] = ["KHR_materials_emissive_strength"]


def test_a_gltf_renders_like_its_obj_mtl_equivalent(tmp_path):
    from trimesh.visual.material import PBRMaterial

    walls, floor, lamp = _room_parts()
    uv = floor.vertices[:, [0, 2]] / 4 + 0.5  # the floor's texture spans it once
    tex = checkerboard(4, 8)
    base, metallic, rough = np.array([153, 204, 102]) / 255, 0.0, 0.6
    emissive = [4.0, 3.5, 3.0]
    walls.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(
        name="walls", baseColorFactor=[*base, 1.0], metallicFactor=metallic, roughnessFactor=rough))
    floor.visual = trimesh.visual.TextureVisuals(uv=uv, material=PBRMaterial(
        name="floor", baseColorFactor=[1.0, 1.0, 1.0, 1.0], baseColorTexture=Image.fromarray(tex),
        metallicFactor=0.0, roughnessFactor=1.0))
    lamp.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(
        name="lamp", baseColorFactor=[0, 0, 0, 1], metallicFactor=0.0, emissiveFactor=emissive))
    sc = trimesh.Scene()
    for name, m in (("a_walls", walls), ("b_floor", floor), ("c_lamp", lamp)):
        sc.add_geometry(m, node_name=name, geom_name=name)
    sc.export(tmp_path / "room.glb")
    edit_glb(tmp_path / "room.glb", _emissive_strength)  # glTF's emissiveFactor is at most 1

    (rd, rs, n), (frd, frs, fn) = ((r.tolist(), s.tolist(), n) for r, s, n in (
        pbr_to_phong(base, metallic, rough), pbr_to_phong([1, 1, 1], 0.0, 1.0)))
    Image.fromarray(tex).save(tmp_path / "floor.png")
    mtl = (f"newmtl walls\nKd {rd[0]!r} {rd[1]!r} {rd[2]!r}\nKs {rs[0]!r} {rs[1]!r} {rs[2]!r}\nNs {n!r}\n"
           f"newmtl floor\nKd {frd[0]!r} {frd[1]!r} {frd[2]!r}\nKs {frs[0]!r} {frs[1]!r} {frs[2]!r}\nNs {fn!r}\n"
           "map_Kd floor.png\n"
           f"newmtl lamp\nKd 0 0 0\nKs 0 0 0\nKe {emissive[0]} {emissive[1]} {emissive[2]}\n")
    (tmp_path / "room.mtl").write_text(mtl)
    lines, base_v, base_t = ["mtllib room.mtl"], 1, 1
    for name, m in (("walls", walls), ("floor", floor), ("lamp", lamp)):
        lines += [f"o {name}", *(f"v {x!r} {y!r} {z!r}" for x, y, z in m.vertices.tolist())]
        if name == "floor":
            lines += [f"vt {a!r} {b!r}" for a, b in uv.tolist()]
        lines.append(f"usemtl {name}")
        for f in (m.faces + base_v).tolist():
            lines.append("f " + " ".join(f"{i}/{i - base_v + base_t}" if name == "floor" else str(i) for i in f))
        base_v += len(m.vertices)
    (tmp_path / "room.obj").write_text("\n".join(lines) + "\n")

    g, o = load_mesh(tmp_path / "room.glb"), load_mesh(tmp_path / "room.obj")
    assert g.textured and o.textured
    np.testing.assert_allclose(g.textures.texels, o.textures.texels)
    images = []
    for path in ("room.glb", "room.obj"):
        (tmp_path / "run.yaml").write_text(f"scene: {{meshes: [{{file: {path}}}]}}\n")
        cfg = lightcuts.load_config(tmp_path / "run.yaml", **{
            "camera.position": [0, 2.6, 1.9], "camera.look_at": [0, 0, 0], "camera.resolution": [32, 32],
            "camera.fov": 80, "lights.direct.count": 1024, "lights.indirect.count": 2000, "render.eps": 0.01})
        images.append(lightcuts.render(cfg, progress=False).image.astype(np.float64))
    a, b = images
    assert a.mean() > 0.01
    # the same triangles in the same order, so the same lights and trees: equal but for float rounding
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)


@pytest.mark.parametrize("render", [{"render.compensation": True, "render.clamp.enabled": True,
                                     "render.clamp.min_distance": 0.3}, {"render.integrator": "multidimensional"},
                                    {"render.integrator": "stochastic-lightcuts", "render.spp": 2},
                                    {"render.integrator": "stochastic-lightcuts", "lights.direct.source": "triangles"},
                                    "path_trace"])
def test_a_one_colour_texture_is_the_same_as_that_albedo_everywhere(tmp_path, render):
    """Every kernel that reads an albedo (eye hits, VPL colours in the particle tracer, continuation
    hits, gather points, the path tracer) reads the texture: a floor textured in one colour c with
    Kd 1 renders as the floor of albedo c, to float rounding."""
    from lightcuts.accel import make_caster
    from lightcuts.integrators.path import path_trace
    from lightcuts.scene.build import scene_from_config

    walls, floor, lamp = _room_parts()
    c = image_to_linear(np.array([[[180, 90, 40]]], np.uint8))[0, 0].astype(np.float64).tolist()
    for name, m in (("walls", walls), ("lamp", lamp)):
        m.export(tmp_path / f"{name}.obj")
    (tmp_path / "floor.obj").write_text(
        "mtllib floor.mtl\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in floor.vertices.tolist())
        + "vt 0.3 0.7\n" + "usemtl m\n" + "".join(f"f {a}/1 {b}/1 {d}/1\n" for a, b, d in (floor.faces + 1).tolist()))
    Image.fromarray(np.full((2, 2, 3), [180, 90, 40], np.uint8)).save(tmp_path / "flat.png")
    (tmp_path / "floor.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd flat.png\n")
    (tmp_path / "plain.mtl").write_text(f"newmtl m\nKd {c[0]!r} {c[1]!r} {c[2]!r}\n")
    (tmp_path / "plain.obj").write_text((tmp_path / "floor.obj").read_text().replace("floor.mtl", "plain.mtl"))
    lamp_entry = "{file: lamp.obj, material: {albedo: [0, 0, 0], emission: [4, 4, 4]}}"
    wall_entry = "{file: walls.obj, material: {albedo: [0.6, 0.6, 0.6], specular: [0.2, 0.2, 0.2], exponent: 20}}"
    images = []
    for floor_file in ("floor.obj", "plain.obj"):
        (tmp_path / "run.yaml").write_text(
            f"scene: {{meshes: [{wall_entry}, {{file: {floor_file}}}, {lamp_entry}]}}\n")
        cfg = lightcuts.load_config(tmp_path / "run.yaml", **{
            "camera.position": [0, 2.6, 1.9], "camera.look_at": [0, 0, 0], "camera.resolution": [16, 16],
            "camera.fov": 80, "lights.direct.count": 256, "lights.indirect.count": 1000, "render.eps": 0.01,
            **(render if isinstance(render, dict) else {})})
        if render == "path_trace":
            scene = scene_from_config(cfg)
            with make_caster(scene, "embree") as caster:
                images.append(path_trace(scene, caster, spp=8, seed=1)[0].astype(np.float64))
        else:
            images.append(lightcuts.render(cfg, progress=False).image.astype(np.float64))
    a, b = images
    assert a[10:].mean() > 0.01  # the floor, seen in the lower rows
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)
