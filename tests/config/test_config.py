"""Config validation: every shipped config loads; each kind of bad config fails with one line."""

from pathlib import Path

import pytest

from lightcuts import limits
from lightcuts.config import load_config
from lightcuts.errors import LightcutsError

CONFIGS = sorted((Path(__file__).parents[2] / "configs").glob("*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_shipped_configs_validate(path):
    from lightcuts.pipeline.plan import plan_run

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
    ("scene: {builtin: cornell}\nlights: {environment: {count: 4}}\n",
     "lights.environment: give file or procedural (neither: the environment of a scene.mitsuba file)"),
    ("render: {eps: 0.1}\n", "scene: Field required"),
    ("scene: {}\n", "scene: needs builtin, procedural, mitsuba, meshes or emitters"),
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


# Limits on what sizes a run's work and memory (lightcuts.limits): the limit itself loads, one past it
# is refused with one line naming the key and the limit.

_NO_DIRECT = {"lights.direct.count": 0}
_ENV = {"lights.environment": {"procedural": {}}, "lights.direct.count": 0}
BOUNDS = [  # (key, limit, other values that keep the rest within its limits)
    ("render.spp", limits.MAX_SPP, {}),
    ("render.passes", limits.MAX_PASSES, {}),
    ("render.continuation_rays", limits.MAX_CONTINUATION_RAYS, {}),
    ("render.max_cut", limits.MAX_CUT, {}),
    ("lights.direct.count", limits.MAX_LIGHTS, {}),
    ("lights.indirect.count", limits.MAX_LIGHTS, _NO_DIRECT),
    ("lights.environment.count", limits.MAX_LIGHTS, _ENV),
    ("lights.indirect.max_bounces", limits.MAX_BOUNCES, {}),
]


@pytest.mark.parametrize("key, limit, others", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_work_and_memory_bounds_at_the_limit(tmp_path, key, limit, others):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    cfg = load_config(p, values={**others, key: limit})
    section, _, field = key.rpartition(".")
    node = cfg
    for part in section.split("."):
        node = getattr(node, part)
    assert getattr(node, field) == limit
    with pytest.raises(LightcutsError) as e:
        load_config(p, values={**others, key: limit + 1})
    msg = str(e.value)
    assert "\n" not in msg and f": {key}: " in msg and (str(limit) in msg or f"{limit:,}" in msg), msg


@pytest.mark.parametrize("values, key, limit", [
    # spp x continuation_rays: 256 x 64 is the limit
    ({"render.spp": 256, "render.continuation_rays": 64}, "render.continuation_rays", limits.MAX_SPP),
    # every light count together
    ({"lights.direct.count": limits.MAX_LIGHTS // 2, "lights.indirect.count": limits.MAX_LIGHTS // 2}, "lights",
     limits.MAX_LIGHTS),
    ({"lights.direct.count": limits.MAX_LIGHTS // 2, "lights.indirect.count": limits.MAX_LIGHTS // 4,
      "lights.environment": {"procedural": {}, "count": limits.MAX_LIGHTS // 4}}, "lights", limits.MAX_LIGHTS),
])
def test_products_and_sums_at_the_limit(tmp_path, values, key, limit):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    load_config(p, values=values)
    over = dict(values)
    first = next(iter(values))
    over[first] = values[first] + 1
    with pytest.raises(LightcutsError) as e:
        load_config(p, values=over)
    assert f": {key}: " in str(e.value) and f"{limit:,}" in str(e.value), str(e.value)


def test_emitter_triangles_at_the_limit(tmp_path):
    """A grid of quads making MAX_EMITTER_TRIANGLES triangles loads; one more quad is refused."""
    grid = {"grid": {"lo": [0, 0, 0], "hi": [1, 0, 1], "count": [1000, 1, 1000]}, "normal": [0, -1, 0],
            "size": [0.001, 0.001], "radiance": [1, 1, 1]}
    quad = {"position": [0, 1, 0], "normal": [0, -1, 0], "size": [1, 1], "radiance": [1, 1, 1]}
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    assert limits.MAX_EMITTER_TRIANGLES == 2 * 1000 * 1000 * 2
    cfg = load_config(p, values={"scene.emitters": [grid, grid]})
    assert sum(e.triangles() for e in cfg.scene.emitters) == limits.MAX_EMITTER_TRIANGLES
    with pytest.raises(LightcutsError, match=r": scene.emitters: 4,000,002 triangles in all .* more than 4,000,000"):
        load_config(p, values={"scene.emitters": [grid, grid, quad]})
    disc = {**quad, "shape": "disc", "size": None, "radius": 1.0, "segments": 7}
    assert load_config(p, values={"scene.emitters": [disc]}).scene.emitters[0].triangles() == 7


@pytest.mark.parametrize("values, ok", [
    ({"camera.resolution": [8192, 4096], "render.spp": 2048}, True),  # 2**25 pixels x 2**11 = 2**36
    ({"camera.resolution": [8192, 4096], "render.spp": 2049}, False),
    ({"camera.resolution": [8192, 4096], "render.spp": 1024, "render.passes": 2}, True),
    ({"camera.resolution": [8192, 4096], "render.spp": 1025, "render.passes": 2}, False),
    ({"camera.resolution": [8192, 4096], "render.spp": 1024, "render.compensation": True,
      "render.continuation_rays": 2}, True),
    ({"camera.resolution": [8192, 4096], "render.spp": 1024, "render.compensation": True,
      "render.continuation_rays": 3}, False),
    ({"camera.resolution": [8192, 4096], "render.spp": 4096, "render.crop": [0, 0, 8192, 2048]}, True),
    ({"camera.resolution": [8192, 4096], "render.spp": 4097, "render.crop": [0, 0, 8192, 2048]}, False),
])
def test_eye_rays_of_a_render_at_the_limit(tmp_path, values, ok):
    """pixels (of the crop) x spp x passes (x continuation_rays with compensation) <= MAX_EYE_RAYS,
    checked by the plan of a render."""
    from lightcuts.pipeline.plan import check_work, plan_run

    cfg = load_config(write(tmp_path, "scene: {builtin: cornell}\n"), values=values)
    plan_run(cfg)  # a run that does not render is not bounded by its eye rays
    if ok:
        assert check_work(cfg, None) <= limits.MAX_EYE_RAYS
        plan_run(cfg, render=True)
    else:
        with pytest.raises(LightcutsError, match=r"^render: .* eye rays, more than 68,719,476,736 "):
            plan_run(cfg, render=True)


def test_yaml_error_without_a_line_is_one_clean_line(tmp_path):
    p = tmp_path / "bin.yaml"
    p.write_bytes(b"\x00\x01 binary")
    with pytest.raises(LightcutsError) as e:
        load_config(p)
    assert str(e.value).startswith(f"{p}: invalid YAML (") and "::" not in str(e.value)
    with pytest.raises(LightcutsError, match=r"bad.yaml: line 2: invalid YAML \("):
        load_config(write(tmp_path, "scene: [unclosed\n", "bad.yaml"))


@pytest.mark.parametrize("key", ["no.such.key", "render.epz.x", "scene.materials.floor.albedoo.r"])
def test_unknown_override_is_named_in_full(tmp_path, key):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    for kwargs, where in (({"overrides": [f"{key}=1"]}, "--set"), ({"values": {key: 1}}, f"{p}:")):
        with pytest.raises(LightcutsError) as e:
            load_config(p, **kwargs)
        assert str(e.value).startswith(f"{where} {key}: unknown key (")
    with pytest.raises(LightcutsError, match=r"yaml: render.epz: unknown key \(did you mean render.eps\?\)$"):
        load_config(write(tmp_path, "scene: {builtin: cornell}\nrender: {epz: 1}\n"), ["render.eps=0.1"])


@pytest.mark.parametrize("path", [42, None, b"run.yaml", ["run.yaml"], "", "run\0.yaml"])
def test_config_path_of_a_wrong_type(path):
    with pytest.raises(LightcutsError, match=r"^config .*: expected a path"):
        load_config(path)


def test_readme_table_of_limits_is_lightcuts_limits():
    """Every row of the README's table of limits gives the value of lightcuts.limits, and every
    bound on work or memory has its row."""
    readme = (CONFIGS[0].parents[1] / "README.md").read_text()
    table = readme[readme.index("| What | Limit |"):].split("\n\n")[0].splitlines()[2:]
    rows = {}
    for line in table:
        what, cell = (c.strip() for c in line.strip("|").split("|"))
        first = cell.split()[0].replace(",", "")
        rows[what] = 2 ** int(first[3:]) if first.startswith("2**") else int(first)
    expected = {"pixels (": limits.MAX_PIXELS, "`render.spp` (": limits.MAX_SPP, "`render.spp` x": limits.MAX_SPP,
                "eye rays": limits.MAX_EYE_RAYS, "`render.passes`": limits.MAX_PASSES,
                "`lights.direct.count`": limits.MAX_LIGHTS, "`lights.indirect.max_bounces`": limits.MAX_BOUNCES,
                "triangles made": limits.MAX_EMITTER_TRIANGLES, "`compare --pixels`": limits.MAX_PIXELS,
                "`reference --spp`": limits.MAX_REFERENCE_SPP, "`scaling --repeats`": limits.MAX_REPEATS,
                "entries of": limits.MAX_POINTS}
    assert len(rows) == len(expected)
    for start, value in expected.items():
        assert [v for what, v in rows.items() if what.startswith(start)] == [value], start


@pytest.mark.parametrize("key, hint", [
    ("render.epss", "(did you mean render.eps?)"), ("rendr.eps", "(did you mean render?)"),
    ("camera.resolutoin", "(did you mean camera.resolution?)"),
    ("lights.direct.zzz", "(known: count, source)"),
])
def test_unknown_key_suggests_the_nearest(tmp_path, key, hint):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    with pytest.raises(LightcutsError) as e:
        load_config(p, [f"{key}=1"])
    assert str(e.value) == f"--set {key}: unknown key {hint}"


@pytest.mark.parametrize("assignment, form", [
    ("camera.resolution=160x120", "a list of 2 numbers, e.g. [640, 480]"),
    ("camera.position=1", "a list of 3 numbers, e.g. [0.5, 0.5, 0.5]"),
    ("render.crop=5", "a list of 4 numbers, e.g. [0, 0, 64, 64]"),
])
def test_a_list_of_the_wrong_type_gives_the_form(tmp_path, assignment, form):
    p = write(tmp_path, "scene: {builtin: cornell}\n")
    with pytest.raises(LightcutsError) as e:
        load_config(p, [assignment])
    key = assignment.partition("=")[0]
    assert str(e.value) == f"--set {key}: Input should be a valid list (expected {form})"
    with pytest.raises(LightcutsError) as e:  # the same in the file names the file
        load_config(write(tmp_path, f"scene: {{builtin: cornell}}\ncamera: {{resolution: 7}}\n", "f.yaml"))
    assert str(e.value).startswith(f"{tmp_path / 'f.yaml'}: camera.resolution: Input should be a valid list (expected")
