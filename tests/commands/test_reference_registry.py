"""Reference renderers are plugins (lightcuts.integrators.references.REFERENCES): every entry declares the
traits the command checks, ``--renderer`` takes any registered name (a scratch entry included) and the
checks read traits, not names; ``lightcuts scaling --gather`` picks its integrators by their
``cuts_per`` trait."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lightcuts.cli import main
from lightcuts.config import load_config
from lightcuts.errors import LightcutsError
from lightcuts.registry import declare
from lightcuts.integrators.references import REFERENCES, TRAITS, PathReference, ReferenceRenderer, make_reference

ROOT = Path(__file__).resolve().parents[2]
TINY = ["--set", "lights.indirect.count=200", "--set", "lights.direct.count=16", "--set", "camera.resolution=[12,10]",
        "--no-progress"]


def test_every_entry_declares_its_traits():
    assert {"lightcuts", "mitsuba"} <= set(REFERENCES.names())
    for e in REFERENCES.entries():
        assert issubclass(e.obj, ReferenceRenderer), e.name
        assert set(TRAITS) <= set(e.traits), (e.name, sorted(e.traits))
        assert isinstance(e.trait("exact_materials"), bool) and isinstance(e.trait("lens"), bool)
        assert isinstance(e.trait("max_depth"), bool)
        assert e.trait("light_types") and set(e.trait("light_types")) <= {"emitters", "sun", "environment"}
        assert e.trait("integrators") and set(e.trait("integrators")) <= {"path", "direct"}
        assert isinstance(e.trait("sampler"), str) and e.trait("sampler")
    assert REFERENCES.entry("lightcuts").trait("exact_materials") is True
    assert REFERENCES.entry("mitsuba").trait("exact_materials") is False


def _scratch(lens: bool, light_types=("emitters",)):
    """lightcuts' path tracer again under the name ``scratch-ref`` with other traits and file stem."""

    @REFERENCES.register("scratch-ref")
    @declare(exact_materials=False, light_types=light_types, lens=lens, integrators=("path",), max_depth=False,
             sampler="the path integrator's")
    class Scratch(PathReference):
        """A scratch reference renderer."""

        file = "scratch"

    return Scratch


def test_a_registered_renderer_is_run_by_name(scratch_registries, tmp_path):
    """``--renderer scratch-ref`` renders through the entry: its image files, its name in report.json,
    and ``phong_approximated`` from its ``exact_materials`` trait (the glossy box has Phong lobes)."""
    _scratch(lens=False)
    out = tmp_path / "ref"
    assert main(["reference", str(ROOT / "configs/cornell-glossy.yaml"), "--renderer", "scratch-ref", "--spp", "2",
                 "--out", str(out), *TINY]) == 0
    r = json.loads((out / "report.json").read_text())
    assert r["path_tracer"]["renderer"] == "scratch-ref" and r["phong_approximated"] is True
    assert sorted(p.name for p in out.iterdir()) == ["lightcuts.exr", "lightcuts.png", "report.html", "report.json",
                                                      "scratch.exr", "scratch.png"]


def test_an_unknown_renderer_is_one_line_listing_the_registry(scratch_registries, tmp_path, capsys):
    _scratch(lens=False)
    assert main(["reference", str(ROOT / "configs/cornell.yaml"), "--renderer", "nosuch", "--out",
                 str(tmp_path / "ref")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--renderer" in err[0] and "nosuch" in err[0], err
    assert all(n in err[0] for n in ("lightcuts", "mitsuba", "scratch-ref")), err
    assert not (tmp_path / "ref").exists()


def test_the_check_reads_traits(scratch_registries):
    """A lens and a sun are accepted or refused by the ``lens`` and ``light_types`` traits, and the
    refusal names every renderer whose traits allow the run."""
    lens = load_config(ROOT / "configs/cornell.yaml", ["camera.aperture=0.05"])
    sun = load_config(ROOT / "configs/sun-env.yaml")
    with pytest.raises(LightcutsError, match=r"camera.aperture needs --renderer mitsuba$"):
        make_reference("lightcuts").check(lens)
    _scratch(lens=True, light_types=("emitters", "sun", "environment"))
    make_reference("scratch-ref").check(lens)
    make_reference("scratch-ref").check(sun)
    with pytest.raises(LightcutsError, match=r"lights.sun needs --renderer mitsuba or scratch-ref$"):
        make_reference("lightcuts").check(sun)
    with pytest.raises(LightcutsError, match=r"--integrator direct needs --renderer mitsuba$"):
        make_reference("scratch-ref").check(lens, "direct")


def test_gather_scaling_compares_the_integrators_declaring_cuts_per(scratch_registries):
    from lightcuts.commands.scaling_gather import compared
    from lightcuts.integrators.registry import INTEGRATORS

    assert [e.name for e in compared()] == ["lightcuts", "multidimensional"]
    INTEGRATORS.register("a-per-pixel", INTEGRATORS.get("multidimensional"),
                         **{**INTEGRATORS.entry("multidimensional").traits})
    INTEGRATORS.register("z-per-eye-ray", INTEGRATORS.get("lightcuts"), **INTEGRATORS.entry("lightcuts").traits)
    INTEGRATORS.register("path-again", INTEGRATORS.get("path"), **INTEGRATORS.entry("path").traits)
    assert [e.name for e in compared()] == ["lightcuts", "z-per-eye-ray", "a-per-pixel", "multidimensional"]


def test_lightcuts_reference_draws_as_the_configs_path_integrator():
    """The `lightcuts` reference's next-event estimation follows the config's own `path` integrator
    (a light tree when it says so) and draws by power otherwise."""
    import numpy as np

    from lightcuts.accel import make_caster
    from lightcuts.api import load_config as api_config
    from lightcuts.integrators.path import path_trace
    from lightcuts.scene.build import scene_from_config

    tree = api_config(ROOT / "configs" / "cornell.yaml", **{"camera.resolution": [16, 16],
                                                           "render.integrator": {"type": "path", "light_sampler": "tree"}})
    power = api_config(ROOT / "configs" / "cornell.yaml", **{"camera.resolution": [16, 16]})
    scene = scene_from_config(power)
    caster = make_caster(scene)
    ref = make_reference("lightcuts")
    a, _ = ref.render(tree, scene, None, 2, 3)
    b, _ = ref.render(power, scene, None, 2, 3)
    np.testing.assert_array_equal(a, path_trace(scene, caster, spp=2, seed=3, light_sampler="tree")[0])
    np.testing.assert_array_equal(b, path_trace(scene, caster, spp=2, seed=3)[0])
    assert not np.array_equal(a, b)
