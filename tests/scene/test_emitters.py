"""Area lights placed by the config (``scene.emitters``) and meshes without emitters: the shapes and
their winding, a grid's centres, the same light as an emissive mesh file, and no lights.direct error
for an unlit mesh that the user lit otherwise."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

import lightcuts
from lightcuts.errors import LightcutsError
from lightcuts.lights.lightset import LUMINANCE
from lightcuts.scene.emitters import emitter_scene
from lightcuts.config.schema import AreaLight


def entry(**kw):
    return AreaLight.model_validate({"normal": [0, -1, 0], "radiance": [2, 3, 4], **kw})


def test_a_quad_faces_its_normal_with_its_size():
    s = emitter_scene(entry(position=[1, 2, 3], size=[0.4, 0.2]))
    assert s.n_faces == 2 and np.allclose(s.face_normals, [0, -1, 0])
    assert s.face_areas.sum() == pytest.approx(0.08)
    assert np.allclose(s.vertices.mean(axis=0), [1, 2, 3]) and np.allclose(s.emission, [2, 3, 4])
    assert np.allclose(s.albedo, 0.0)
    lo, hi = s.bounds
    assert sorted(np.round(hi - lo, 9)) == [0.0, 0.2, 0.4]


def test_a_disc_is_a_fan_facing_its_normal():
    s = emitter_scene(entry(shape="disc", position=[0, 1, 0], radius=0.5, segments=64, normal=[1, 1, 0]))
    n = np.array([1, 1, 0]) / np.sqrt(2)
    assert s.n_faces == 64 and np.allclose(s.face_normals, n)
    assert s.face_areas.sum() == pytest.approx(0.5 * 64 * 0.25 * np.sin(2 * np.pi / 64))


def test_a_grid_puts_one_at_every_cell_centre():
    s = emitter_scene(entry(grid={"lo": [0, 2.5, 0], "hi": [4, 2.5, 2], "count": [4, 1, 2]}, size=[0.1, 0.1]))
    assert s.n_faces == 16
    centres = s.triangles.reshape(8, 2, 3, 3)[:, 0, [0, 2]].mean(axis=1)  # a quad's diagonal midpoint
    expected = [[x, 2.5, z] for z in (0.5, 1.5) for x in (0.5, 1.5, 2.5, 3.5)]
    assert np.allclose(centres, expected)


def _room(tmp_path):
    """An open box (floor and four walls, no ceiling) as OBJ, without emitters."""
    box = trimesh.creation.box(extents=[4, 3, 4])
    box.apply_translation([0, 1.5, 0])
    keep = box.face_normals[:, 1] < 0.5  # drop the two ceiling triangles
    room = trimesh.Trimesh(box.vertices, box.faces[keep][:, ::-1], process=False)  # inward
    room.export(tmp_path / "room.obj")


def _config(tmp_path, text, **values):
    (tmp_path / "run.yaml").write_text(text)
    base = {"camera.position": [0, 1.5, 1.9], "camera.look_at": [0, 0.5, 0], "camera.resolution": [24, 24],
            "camera.fov": 80, "lights.direct.count": 2048, "render.eps": 0.01}
    return lightcuts.load_config(tmp_path / "run.yaml", **{**base, **values})


def test_placed_quads_light_like_the_same_quads_as_an_emissive_mesh(tmp_path):
    _room(tmp_path)
    lamp = {"normal": [0, -1, 0], "radiance": [5, 5, 5], "size": [0.5, 0.5]}
    grid = {"lo": [-1, 2.8, -1], "hi": [1, 2.8, 1], "count": [2, 1, 2]}
    placed = _config(tmp_path, "scene: {meshes: [{file: room.obj}]}\n",
                     **{"scene.emitters": [{**lamp, "grid": grid}]})
    quads = emitter_scene(placed.scene.emitters[0])
    trimesh.Trimesh(quads.vertices, quads.faces, process=False).export(tmp_path / "lamps.obj")
    as_mesh = _config(tmp_path, "scene: {meshes: [{file: room.obj}, {file: lamps.obj, material: "
                                "{albedo: [0, 0, 0], emission: [5, 5, 5]}}]}\n")
    a = lightcuts.render(placed, progress=False)
    b = lightcuts.render(as_mesh, progress=False)
    la, lb = (float((r.image.astype(np.float64) @ LUMINANCE).mean()) for r in (a, b))
    assert la > 0.01 and la == pytest.approx(lb, rel=1e-6)
    assert a.report["lights"]["oriented"] == b.report["lights"]["oriented"] == 2048


def test_an_unlit_mesh_needs_no_lights_direct_setting(tmp_path):
    """Lit by a sun, a mesh without emitters renders without touching lights.direct; asking for
    direct lights there is a one-line error that says what to do."""
    _room(tmp_path)
    text = "scene: {meshes: [{file: room.obj}]}\nlights: {sun: {direction: [0.3, 1, 0.2], irradiance: [3, 3, 3]}}\n"
    (tmp_path / "sun.yaml").write_text(text)
    r = lightcuts.render(lightcuts.load_config(tmp_path / "sun.yaml", **{"camera.resolution": [16, 16]}),
                         progress=False)
    assert "oriented" not in r.report["lights"] and r.image.max() > 0
    with pytest.raises(LightcutsError, match="lights.direct: the scene has no emissive triangles"):
        lightcuts.render(lightcuts.load_config(tmp_path / "sun.yaml", **{"lights.direct.count": 64}), progress=False)


@pytest.mark.parametrize("bad, message", [
    ({"position": [0, 0, 0]}, "a quad takes size"),
    ({"position": [0, 0, 0], "shape": "disc", "size": [1, 1]}, "a disc takes radius"),
    ({"size": [1, 1]}, "give exactly one of position and grid"),
    ({"position": [0, 0, 0], "size": [1, 1], "radiance": [0, 0, 0]}, "radiance: must not be all zero"),
    ({"position": [0, 0, 0], "size": [1, 1], "normal": [0, 0, 0]}, "normal: must not be zero"),
    ({"grid": {"lo": [0, 0, 0], "hi": [1, -1, 1], "count": [1, 1, 1]}, "size": [1, 1]}, "must be >= lo"),
    ({"position": [0, 0, 0], "size": [1, 1], "up": [0, 3, 0]}, "up: zero or parallel to the normal"),
])
def test_bad_emitters_are_one_line_config_errors(tmp_path, bad, message):
    (tmp_path / "run.yaml").write_text("scene: {builtin: cornell}\n")
    with pytest.raises(LightcutsError, match=message) as e:
        lightcuts.load_config(tmp_path / "run.yaml",
                              **{"scene.emitters": [{"normal": [0, -1, 0], "radiance": [1, 1, 1], **bad}]})
    assert "scene.emitters.0" in str(e.value) and "\n" not in str(e.value)


def test_an_up_parallel_to_the_normal_is_refused_by_the_mesh_builder_too():
    e = AreaLight.model_construct(**{**entry(position=[0, 0, 0], size=[1, 1]).model_dump(), "up": [0, 2, 0]})
    with pytest.raises(LightcutsError, match="scene.emitters.3.up: zero or parallel"):
        emitter_scene(e, key="scene.emitters.3")


# Emission against the light limits, checked on the scene (lightcuts.limits).

def _triangle(emission, size=1.0):
    from lightcuts.scene.scene import Scene

    return Scene([[0, 0, 0], [size, 0, 0], [0, size, 0]], [[0, 1, 2]], 0.5, 0.0, 0.0, emission)


@pytest.mark.parametrize("emission, size, problem", [
    ([np.nan, 1, 1], 1.0, "1 triangles emit NaN or infinite radiance"),
    ([np.inf, 0, 0], 1.0, "NaN or infinite radiance"),
    ([-1, 0, 0], 1.0, "negative radiance"),
    ([1.01e30, 0, 0], 1.0, "radiance above 1e+30"),
    ([1e30, 0, 0], 2e15, "emitted power 2e+60 W/sr"),  # area 2e30
])
def test_emission_beyond_the_light_limits_is_refused_naming_the_source(emission, size, problem, monkeypatch):
    import lightcuts.scene.scene as scene_module

    if "power" in problem:
        monkeypatch.setattr(scene_module, "MAX_EMITTED_POWER", 1.99e60)
    with pytest.raises(LightcutsError, match="^a source: .*" + re.escape(problem)):
        _triangle(emission, size).check_emission("a source")
    if "power" in problem:
        monkeypatch.setattr(scene_module, "MAX_EMITTED_POWER", 2e60)
        _triangle(emission, size).check_emission("a source")


def test_the_limits_hold_what_the_config_can_place_once():
    """One quad of the largest size and radiance a config takes (1e30 each) is within the limits;
    two of them are not."""
    _triangle([1e30, 1e30, 1e30], 1e30 * 2 ** 0.5).check_emission("x")
    with pytest.raises(LightcutsError, match=r"^scene.emitters.3: emitted power 2e\+90"):
        emitter_scene(entry(grid={"lo": [0, 0, 0], "hi": [1, 0, 0], "count": [2, 1, 1]}, size=[1e30, 1e30],
                            radiance=[1e30, 1e30, 1e30]), key="scene.emitters.3")


def test_a_mesh_beyond_the_power_limit_is_named_by_its_key(tmp_path):
    """A mesh scaled by 1e30 whose config material emits 1e30: 4e90 W/sr from the mesh alone."""
    from lightcuts.scene.loaders import load_mesh

    (tmp_path / "q.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    with pytest.raises(LightcutsError, match=r"^scene.meshes.4: .*q.obj: emitted power 4e\+90 W/sr"):
        load_mesh(tmp_path / "q.obj", scale=1e30, material={"emission": [1e30] * 3}, key="scene.meshes.4")
    assert load_mesh(tmp_path / "q.obj", scale=1e29, material={"emission": [1e30] * 3}).emission.max() == 1e30


def test_nan_emission_is_not_taken_for_no_emission():
    """Lights made from a scene with NaN emission (which no loader lets in, but a Scene made by
    hand can hold): the NaN is named, not 'no emissive triangles'."""
    from lightcuts.config.schema import config_from_dict
    from lightcuts.lights.generate import lights_from_config

    cfg = config_from_dict({"scene": {"builtin": "cornell"}, "lights": {"direct": {"count": 4}}}, "x.yaml", ".")
    with pytest.raises(LightcutsError, match="^scene 'scene': 1 triangles emit NaN or infinite radiance"):
        lights_from_config(cfg, _triangle([np.nan, 1, 1]))


def test_mtl_emission_above_the_radiance_limit_names_the_line(tmp_path):
    from lightcuts.scene.loaders import load_mesh

    (tmp_path / "k.obj").write_text("mtllib k.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n")
    (tmp_path / "k.mtl").write_text("newmtl lamp\nKe 1e30 2 3\n")
    assert load_mesh(tmp_path / "k.obj").emission.max() == 1e30
    (tmp_path / "k.mtl").write_text("newmtl lamp\nKe 2e30 2 3\n")
    with pytest.raises(LightcutsError, match=r"k.mtl:2: material 'lamp': Ke 2e30 2 3: emitted radiance above 1e\+30"):
        load_mesh(tmp_path / "k.obj")
