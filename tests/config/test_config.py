"""Config validation: every shipped config loads; each kind of bad config fails with one line."""

from pathlib import Path

import pytest

from lightcuts.config import load_config
from lightcuts.errors import LightcutsError

CONFIGS = sorted((Path(__file__).parents[2] / "configs").glob("*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_shipped_configs_validate(path):
    from lightcuts.commands.plan import plan_run

    cfg = load_config(path)
    assert cfg.name == path.stem
    plan_run(cfg, render=True)  # every plugin resolves; an aperture only with an integrator that renders a lens


@pytest.mark.parametrize("name, base", [("kitchen-fig8", "kitchen"), ("rooms-fig8", "rooms")])
def test_fig8_configs_are_the_papers_setting_on_our_scenes(name, base):
    """640 x 480, 16 gather points, 200,000 indirect VPLs, multidimensional lightcuts with multiple
    representatives and clamping; the scene and the rest as the scene's own config."""
    root = CONFIGS[0].parent
    cfg, own = load_config(root / f"{name}.yaml"), load_config(root / f"{base}.yaml")
    assert cfg.camera.resolution == [640, 480] and cfg.render.spp == 16 and cfg.lights.indirect.count == 200_000
    assert cfg.render.integrator == {"type": "multidimensional", "representatives": 4}
    assert cfg.render.clamp.enabled and cfg.camera.aperture == 0
    assert cfg.scene == own.scene and cfg.seed == own.seed and cfg.tree == own.tree
    assert cfg.lights.direct == own.lights.direct and cfg.render.eps == own.render.eps


def test_dof_config_focuses_on_the_table():
    """The kitchen's camera focused at the table's distance along the view axis, 64 gather points."""
    import numpy as np

    from lightcuts.scene import kitchen

    cfg = load_config(CONFIGS[0].parent / "kitchen-dof.yaml")
    cam = kitchen.camera()
    forward = np.subtract(cam.look_at, cam.position)
    forward /= np.linalg.norm(forward)
    table = np.array([kitchen.TABLE_CENTRE[0], kitchen.TABLE_H, kitchen.TABLE_CENTRE[1]])
    assert cfg.camera.focus_distance == pytest.approx(np.dot(table - cam.position, forward), abs=0.02)
    assert 0 < cfg.camera.aperture < 0.1 and cfg.render.spp == 64
    assert cfg.render.integrator["type"] == "multidimensional"


def write(tmp_path, text, name="run.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, expected", [
    ("scene: {builtin: cornell}\nrender: {epss: 0.1}\n", "render.epss: unknown key"),
    ("scene: {builtin: cornell}\nrender: {eps: fast}\n", "render.eps:"),
    ("scene: {builtin: cornell}\nrender: {eps: -1}\n", "render.eps:"),
    ("scene: {builtin: cornell}\nlights: {direct: {count: 1.5}}\n", "lights.direct.count:"),
    ("scene: {meshes: [{file: nothere.obj}]}\n", "scene.meshes.0.file: no such file"),
    ("scene: {builtin: cornell}\nlights: {environment: {file: sky.exr}}\n", "lights.environment.file: no such file"),
    ("scene: {builtin: cornell}\nlights: {environment: {count: 4}}\n", "lights.environment: give exactly one"),
    ("render: {eps: 0.1}\n", "scene: Field required"),
    ("scene: {}\n", "scene: needs builtin, procedural, meshes or emitters"),
    ("scene: [1, 2\n", "invalid YAML"),
    ("- 1\n- 2\n", "expected a mapping"),
    ("scene: {builtin: cornell}\ncamera: {resolution: [0, 10]}\n", "camera.resolution.0:"),
    ("scene: {builtin: cornell}\nrender: {eps: .nan}\n", "render.eps:"),
    ("scene: {builtin: cornell}\nrender: {max_cut: 2000000}\n", "render.max_cut:"),
    ("scene: {builtin: cornell}\nlights: {sun: {direction: [0, .inf, 0], irradiance: [1, 1, 1]}}\n",
     "lights.sun.direction.1:"),
])
def test_bad_configs_name_the_key(tmp_path, text, expected):
    p = write(tmp_path, text)
    with pytest.raises(LightcutsError) as e:
        load_config(p)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(str(p)), msg
    assert expected in msg, msg


def test_missing_config_file(tmp_path):
    with pytest.raises(LightcutsError, match="cannot read config"):
        load_config(tmp_path / "none.yaml")


def test_overrides_apply_and_validate(tmp_path):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    cfg = load_config(p, ["render.eps=0.005", "lights.indirect.count=2000", "tree.builder=divisive-6d"])
    assert cfg.render.eps == 0.005 and cfg.lights.indirect.count == 2000 and cfg.tree.builder == "divisive-6d"
    with pytest.raises(LightcutsError, match="render.nope: unknown key"):
        load_config(p, ["render.nope=1"])
    with pytest.raises(LightcutsError, match="expected key=value"):
        load_config(p, ["render.eps"])


def test_paths_resolve_against_config_folder(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    p = write(tmp_path / "sub", "scene: {meshes: [{file: m.obj}]}\n")
    cfg = load_config(p)
    assert cfg.resolve(cfg.scene.meshes[0].file) == (tmp_path / "sub" / "m.obj").resolve()
