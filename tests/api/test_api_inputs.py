"""Bad arguments to the Python API: lightcuts.load_config / render / compare and the results' save
raise LightcutsError (one line naming the argument) before any work, never another exception; a
save proves it can write its folder before writing any file. Checked case by case and by fuzzing
every argument with values of random types (a tiny scene, so a valid call is cheap too)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import lightcuts
from lightcuts import limits
from lightcuts.config import RunConfig
from lightcuts.errors import LightcutsError

TINY = ("name: tiny\nseed: 3\nscene: {builtin: cornell}\ncamera: {resolution: [4, 4]}\n"
        "lights: {direct: {count: 16}}\n")
UNWRITABLE = ["/proc/lightcuts-out", "/sys/lightcuts-out/deeper"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    path = tmp_path_factory.mktemp("api") / "tiny.yaml"
    path.write_text(TINY)
    return path


def _one_line(exc_info, start: str) -> None:
    msg = str(exc_info.value)
    assert "\n" not in msg and msg.startswith(start), msg


@pytest.mark.parametrize("call, start", [
    (lambda p: lightcuts.render(42), "config 42: expected a RunConfig"),
    (lambda p: lightcuts.render(None), "config None: expected a RunConfig"),
    (lambda p: lightcuts.render(p, reference="yes"), "reference 'yes': expected True or False"),
    (lambda p: lightcuts.render(p, progress=None), "progress None: expected True or False"),
    (lambda p: lightcuts.compare(p, builders=3), "builders 3: expected names"),
    (lambda p: lightcuts.compare(p, builders=["divisive-3d", 4]), "builders ['divisive-3d', 4]: expected names"),
    (lambda p: lightcuts.compare(p, metrics={"walter2008"}), "metrics {'walter2008'}: expected names"),
    (lambda p: lightcuts.compare(p, pixels="16"), "pixels '16': expected an integer"),
    (lambda p: lightcuts.compare(p, pixels=True), "pixels True: expected an integer"),
    (lambda p: lightcuts.compare(p, pixels=2.5), "pixels 2.5: expected an integer"),
    (lambda p: lightcuts.compare(p, pixels=-1), "pixels -1: must be from 0 to 33,554,432"),
    (lambda p: lightcuts.compare(p, pixels=limits.MAX_PIXELS + 1), "pixels 33554433: must be from 0 to 33,554,432"),
    (lambda p: lightcuts.compare(p, store=7), "store 7: expected a path"),
    (lambda p: lightcuts.compare(p, store=p), "store "),  # a file, not a folder
    (lambda p: lightcuts.compare(p, store="/proc/lightcuts-rows"), "store '/proc/lightcuts-rows': cannot write in"),
    (lambda p: lightcuts.compare(p, force="no"), "force 'no': expected True or False"),
    (lambda p: lightcuts.compare(p, mitsuba_spp=0), "mitsuba_spp 0: must be from 1 to 1,048,576"),
    (lambda p: lightcuts.compare(p, mitsuba_spp="64"), "mitsuba_spp '64': expected an integer"),
    (lambda p: lightcuts.render(p, cluster=42), "cluster 42: expected a distributed.Client or a scheduler address"),
    (lambda p: lightcuts.render(p, cluster="my laptop"), "cluster 'my laptop': expected tcp://HOST:PORT"),
    (lambda p: lightcuts.render(p, tile_size=16), "tile_size: only with a cluster"),
    (lambda p: lightcuts.render(p, cluster="tcp://127.0.0.1:1", tile_size=0), "tile_size 0: must be from 1 to 8,192"),
    (lambda p: lightcuts.compare(p, cluster=[1]), "cluster [1]: expected a distributed.Client"),
    (lambda p: lightcuts.load_config(42), "config 42: expected a path"),
    (lambda p: lightcuts.load_config("a\nb.yaml"), "a\\nb.yaml: cannot read config"),  # one line, escaped
    (lambda p: lightcuts.load_config(p, **{"no.such.key": 1}), f"{{p}}: no.such.key: unknown key"),
    (lambda p: lightcuts.load_config(p, render__spp=limits.MAX_SPP + 1), "{p}: render.spp: "),
])
def test_bad_argument_one_line_before_work(tiny, stage_calls, call, start):
    with pytest.raises(LightcutsError) as e:
        call(tiny)
    _one_line(e, start.replace("{p}", str(tiny)))
    assert stage_calls == []


def test_a_config_assigned_after_loading_is_validated_again(tiny, stage_calls):
    cfg = lightcuts.load_config(tiny)
    cfg.render.spp = 10**9  # pydantic does not check an assignment
    with pytest.raises(LightcutsError) as e:
        lightcuts.render(cfg)
    _one_line(e, "config: render.spp: Input should be less than or equal to 16384")
    cfg = lightcuts.load_config(tiny)
    cfg.render = "fast"
    with pytest.raises(LightcutsError) as e:
        lightcuts.compare(cfg)
    _one_line(e, "config: render: ")
    assert stage_calls == []


def test_a_config_validated_again_sets_what_it_set(tiny):
    """The fields a config sets, and those assigned since (in a section left at its default too), are
    set again: a stage that tells a given value from a default sees the same."""
    from lightcuts.api import _config

    def sets(m):
        return {"": m.model_fields_set, **{k: getattr(m, k).model_fields_set for k in ("scene", "camera", "lights",
                                                                                       "render", "tree")},
                "lights.direct": m.lights.direct.model_fields_set, "render.clamp": m.render.clamp.model_fields_set}

    cfg = lightcuts.load_config(tiny)
    assert sets(_config(cfg)[0]) == sets(cfg) and "count" in cfg.lights.direct.model_fields_set
    unset = lightcuts.load_config(tiny, **{"lights.direct": {}})
    assert sets(_config(unset)[0]) == sets(unset) and "count" not in unset.lights.direct.model_fields_set
    cfg.render.clamp.enabled = False  # render is not in the file
    again, _ = _config(cfg)
    assert again == cfg and not again.render.clamp.enabled and again.render.clamp.model_fields_set == {"enabled"}


def test_a_config_object_renders_as_its_file(tmp_path):
    """A material override that sets some fields keeps the surface's own for the others, whether the
    run is given as the file or as its RunConfig (validated again from what it sets, in dicts and
    lists of models too)."""
    path = tmp_path / "glossy.yaml"
    path.write_text(TINY.replace("scene: {builtin: cornell}", "scene: {builtin: cornell, materials: {floor: "
                                                              "{specular: [0.3, 0.3, 0.3], exponent: 60}}}"))
    cfg = lightcuts.load_config(path)
    assert cfg.scene.materials["floor"].model_fields_set == {"specular", "exponent"}
    by_file = lightcuts.render(path, progress=False)
    by_object = lightcuts.render(cfg, progress=False)
    assert np.array_equal(by_file.image, by_object.image) and by_file.image.any()


@pytest.fixture(scope="module")
def results(tiny):
    """A Render and a Comparison of the tiny scene, made once."""
    cfg = lightcuts.load_config(tiny)
    return lightcuts.render(cfg, progress=False), lightcuts.compare(cfg, builders="divisive-3d", pixels=4,
                                                                     progress=False)


@pytest.mark.parametrize("which", [0, 1], ids=["Render", "Comparison"])
@pytest.mark.parametrize("where", UNWRITABLE)
def test_save_where_nothing_can_be_written(results, monkeypatch, which, where):
    """/proc and /sys take no new entry even from root: save refuses before writing a file."""
    import lightcuts.io

    opened = []
    monkeypatch.setattr(lightcuts.io, "output_set", lambda *a, **k: opened.append(a) or pytest.fail("writing"))
    with pytest.raises(LightcutsError) as e:
        results[which].save(where)
    _one_line(e, f"folder '{where}': cannot write in '/")
    assert opened == []


def test_save_writes_a_new_folder_and_nothing_else(results, tmp_path):
    render, comparison = results
    assert render.save(tmp_path / "a" / "render") == tmp_path / "a" / "render"
    assert comparison.save(tmp_path / "a" / "compare") == tmp_path / "a" / "compare"
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["compare", "render"]
    assert not [p for p in tmp_path.rglob(".*")]  # no probe or temporary left


# Fuzzing: random types and values for every argument give a result or a LightcutsError.

#: Texts that name no folder outside the current one (a fuzzed save or store writes where it is told).
_TEXT = st.text(st.characters(blacklist_characters="/\\.~"), max_size=6)
_JUNK = (st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats(allow_nan=True) | _TEXT
         | st.binary(max_size=6) | st.just(object()) | st.just(np.int64(4)) | st.just(np.float32(0.5))
         | st.just(np.bool_(True)) | st.just(np.array([1, 2])) | st.lists(st.integers(-3, 3) | _TEXT, max_size=3)
         | st.dictionaries(_TEXT, st.integers(-3, 3), max_size=2))
#: Config keys whose valid values keep the tiny render cheap, and some that do not exist.
_KEYS = ["render.eps", "render.spp", "render.max_cut", "render.exposure", "render.crop", "render.integrator",
         "render.ray_caster", "render.representatives", "render.compensation", "render.clamp.enabled", "seed",
         "name", "tree.builder", "tree.metric", "tree.c", "camera.fov", "camera.aperture", "lights.sun",
         "render__eps", "no.such.key", "render.eps.x", "", ".", "render..eps", "scene.builtin"]
_FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])


def _ok_or_lightcuts_error(call):
    try:
        return call()
    except LightcutsError as exc:
        assert "\n" not in str(exc)
        return None


@_FUZZ
@given(path=st.sampled_from(["tiny", "missing", "folder"]) | _JUNK,
       overrides=st.dictionaries(st.sampled_from(_KEYS), _JUNK | st.sampled_from([0.01, 2, [0, 0, 2, 2]]),
                                 max_size=3))
def test_fuzz_load_config(tiny, path, overrides):
    where = {"tiny": tiny, "missing": tiny.with_name("missing.yaml"), "folder": tiny.parent}
    path = where.get(path, path) if isinstance(path, str) else path
    cfg = _ok_or_lightcuts_error(lambda: lightcuts.load_config(path, **overrides))
    assert cfg is None or isinstance(cfg, RunConfig)


def _config(tiny, kind, key, value):
    """The config argument: the tiny file, its RunConfig, that RunConfig with ``key`` assigned
    ``value`` after loading (unchecked by pydantic), or ``value`` itself."""
    if kind == "path":
        return tiny
    cfg = lightcuts.load_config(tiny)
    if kind == "assigned":
        section, _, field = key.rpartition(".")
        node = cfg
        for part in filter(None, section.split(".")):
            node = getattr(node, part)
        setattr(node, field, copy.copy(value))
    return value if kind == "junk" else cfg


_ASSIGNABLE = ["render.eps", "render.spp", "render.max_cut", "render.crop", "render.integrator", "seed",
               "camera.fov", "tree.builder", "render"]


@_FUZZ
@given(kind=st.sampled_from(["path", "config", "assigned", "junk"]), key=st.sampled_from(_ASSIGNABLE),
       value=_JUNK, reference=st.booleans() | _JUNK, progress=st.just(False) | _JUNK)
def test_fuzz_render(tiny, kind, key, value, reference, progress):
    config = _config(tiny, kind, key, value)
    r = _ok_or_lightcuts_error(lambda: lightcuts.render(config, reference=reference, progress=progress))
    assert r is None or (r.image.shape[2] == 3 and np.isfinite(r.image).all())


@_FUZZ
@given(kind=st.sampled_from(["path", "config", "assigned", "junk"]), key=st.sampled_from(_ASSIGNABLE),
       value=_JUNK, builders=st.sampled_from(["divisive-3d", ["divisive-6d", "saoh"], "nope", ""]) | _JUNK,
       metrics=st.none() | st.sampled_from(["walter2008", ["surface-area"]]) | _JUNK,
       pixels=st.integers(0, 8) | _JUNK, store=st.sampled_from([None, "rows", "file", "/proc/rows"]) | _JUNK,
       force=st.booleans() | _JUNK, mitsuba_spp=st.none() | st.integers(max_value=0) | _JUNK.filter(
           lambda v: not isinstance(v, (int, np.integer)) or isinstance(v, (bool, np.bool_)) or not 0 < v),
       progress=st.just(False) | _JUNK)
def test_fuzz_compare(tiny, tmp_path, monkeypatch, kind, key, value, builders, metrics, pixels, store, force,
                      mitsuba_spp, progress):
    monkeypatch.chdir(tmp_path)
    config = _config(tiny, kind, key, value)
    (tmp_path / "file").write_text("not a folder")
    if isinstance(store, str) and store in ("rows", "file"):
        store = tmp_path / store
    c = _ok_or_lightcuts_error(lambda: lightcuts.compare(config, builders, metrics, pixels=pixels, store=store,
                                                         force=force, mitsuba_spp=mitsuba_spp, progress=progress))
    assert c is None or (len(c.rows) >= 1 and all(r["cut_mean"] > 0 for r in c.rows))


def test_save_to_unencodable_folder_name_is_one_line(results, tmp_path):
    """A lone surrogate cannot become a file name: one LightcutsError naming the key, nothing written."""
    with pytest.raises(LightcutsError, match="folder .*not a file name this system can encode"):
        results[0].save(str(tmp_path / "a\ud800b"))
    assert list(tmp_path.iterdir()) == []


@_FUZZ
@given(folder=st.sampled_from(["new", "file"] + UNWRITABLE) | _JUNK, which=st.sampled_from([0, 1]))
def test_fuzz_save(results, tmp_path, monkeypatch, folder, which):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file").write_text("not a folder")
    if isinstance(folder, str) and folder in ("new", "file"):
        folder = tmp_path / folder
    out = _ok_or_lightcuts_error(lambda: results[which].save(folder))
    assert out is None or (out.is_dir() and (out / "report.json").is_file())
