"""Scene types through the SCENES registry: ``scene.builtin`` / ``scene.procedural`` resolved in the
plan step (one-line errors naming the key), defaults declared once, the name and ``{type: NAME}``
giving the same scene."""

from __future__ import annotations

import pytest

from lightcuts.config import load_config
from lightcuts.errors import LightcutsError
from lightcuts.scene.build import image_size, scene_from_config
from lightcuts.scene.registry import SCENES, resolve_scene


def write(tmp_path, text, name="run.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, expected", [
    ("scene: {builtin: sphere}\n", "scene.builtin: unknown built-in scene 'sphere'; valid: cornell"),
    ("scene: {builtin: kitchen}\n", "scene.builtin: unknown built-in scene 'kitchen' (scene.procedural names it)"),
    ("scene: {procedural: {type: cornell}}\n", "scene.procedural.type: unknown procedural scene 'cornell'"),
    ("scene: {procedural: {type: attic}}\n", "scene.procedural.type: unknown procedural scene 'attic'"),
    ("scene: {procedural: {type: kitchen, rooms: 2}}\n",
     "scene.procedural.rooms: scene type 'kitchen' has no parameter 'rooms' (it reads: seed, triangles)"),
    ("scene: {procedural: {type: gallery, seed: 1}}\n", "scene.procedural.seed: scene type 'gallery' has no parameter"),
    ("scene: {procedural: {type: kitchen, triangles: 5000}}\n",
     "scene.procedural.triangles: 5000 is below the minimum 10000"),
    ("scene: {procedural: {type: kitchen, triangles: 5000000}}\n",
     "scene.procedural.triangles: 5000000 is above the maximum 4e+06"),
    ("scene: {procedural: {type: rooms, rooms: 17}}\n", "scene.procedural.rooms: 17 is above the maximum 16"),
    ("scene: {procedural: {type: rooms, seed: -1}}\n", "scene.procedural.seed: -1 is below the minimum 0"),
    ("scene: {procedural: {type: kitchen, triangles: 2.5e4}}\n", "scene.procedural.triangles: expected int"),
    ("scene: {procedural: {type: gallery}}\n", "scene.procedural: type gallery needs scene.meshes (the exhibits)"),
    ("scene: {procedural: {type: city, emitters: -1}}\n", "scene.procedural.emitters: -1 is below the minimum 1000"),
    ("scene: {procedural: {type: office, emitters: 999}}\n", "scene.procedural.emitters: 999 is below the minimum 1000"),
    ("scene: {procedural: {type: office, emitters: 4000001}}\n",
     "scene.procedural.emitters: 4000001 is above the maximum 4e+06"),
    ("scene: {procedural: {type: city, emitters: 1.0e4}}\n", "scene.procedural.emitters: expected int"),
    ("scene: {procedural: {type: city, seed: -2}}\n", "scene.procedural.seed: -2 is below the minimum 0"),
    ("scene: {procedural: {type: office, triangles: 20000}}\n",
     "scene.procedural.triangles: scene type 'office' has no parameter 'triangles' (it reads: emitters, seed)"),
])
def test_bad_scene_types_name_the_key(tmp_path, text, expected):
    """The config loads (it has the right shape); the plan's resolution fails with one line."""
    cfg = load_config(write(tmp_path, text))
    with pytest.raises(LightcutsError) as e:
        resolve_scene(cfg.scene)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(expected.split(":")[0] + ":"), msg
    assert expected in msg, msg
    with pytest.raises(LightcutsError, match=expected.split(":")[0]):
        scene_from_config(cfg)  # the API path resolves the same way


@pytest.mark.parametrize("text", ["scene: {procedural: {triangles: 10000}}\n", "scene: {procedural: [kitchen]}\n",
                                  "scene: {procedural: {type: 3}}\n"])
def test_config_checks_the_shape(tmp_path, text):
    p = write(tmp_path, text)
    with pytest.raises(LightcutsError) as e:
        load_config(p)
    assert str(e.value).startswith(f"{p}: scene.procedural:") and "\n" not in str(e.value)


def test_defaults_are_the_declared_ones():
    assert dict(SCENES.resolve("kitchen", "k").params) == {"seed": 0, "triangles": 200_000}
    assert dict(SCENES.resolve("rooms", "r").params) == {"rooms": 4, "seed": 0, "triangles": 100_000}
    assert dict(SCENES.resolve("gallery", "g").params) == {} == dict(SCENES.resolve("cornell", "c").params)
    assert dict(SCENES.resolve("city", "c").params) == {"emitters": 100_000, "seed": 0} \
        == dict(SCENES.resolve("office", "o").params)


def test_name_and_type_mapping_give_the_same_bytes(tmp_path):
    """``procedural: kitchen``, ``{type: kitchen}`` and the declared defaults spelled out: one scene;
    another seed: another scene."""
    def saved(text, name):
        cfg = load_config(write(tmp_path, f"name: k\nscene: {{procedural: {text}}}\n", f"{name}.yaml"))
        return scene_from_config(cfg).save(tmp_path / f"{name}.npz").read_bytes()

    plain = saved("kitchen", "plain")
    assert saved("{type: kitchen}", "mapping") == plain
    assert saved("{type: kitchen, triangles: 200000, seed: 0}", "spelled") == plain
    assert saved("{type: kitchen, seed: 1}", "other") != plain


def test_image_size_from_the_type_trait(tmp_path):
    for text, size in [("scene: {builtin: cornell}\n", (512, 512)),
                       ("scene: {procedural: {type: rooms, rooms: 2}}\n", (512, 384))]:
        cfg = load_config(write(tmp_path, text))
        assert image_size(cfg) == size == tuple(resolve_scene(cfg.scene).trait("resolution"))
